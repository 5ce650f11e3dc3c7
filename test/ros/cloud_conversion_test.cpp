// PointCloud2 decoding: layouts that must work and malformed / hostile messages that must give
// a named CloudError (never a crash or an out-of-bounds read).
#include "dimr/ros/cloud_conversion.h"

#include <gtest/gtest.h>
#include <sensor_msgs/point_cloud2_iterator.h>

#include <cmath>
#include <limits>

namespace dimr::ros1 {
namespace {

sensor_msgs::PointCloud2 XyzRgb(int n, bool rgb = true) {
  sensor_msgs::PointCloud2 msg;
  msg.header.frame_id = "camera";
  msg.header.stamp.sec = 1000;
  sensor_msgs::PointCloud2Modifier mod(msg);
  if (rgb)
    mod.setPointCloud2FieldsByString(2, "xyz", "rgb");
  else
    mod.setPointCloud2FieldsByString(1, "xyz");
  mod.resize(n);
  sensor_msgs::PointCloud2Iterator<float> x(msg, "x"), y(msg, "y"), z(msg, "z");
  for (int i = 0; i < n; ++i, ++x, ++y, ++z) {
    *x = 0.01f * i;
    *y = 1.0f;
    *z = 2.0f;
  }
  if (rgb) {
    sensor_msgs::PointCloud2Iterator<std::uint8_t> r(msg, "r"), g(msg, "g"), b(msg, "b");
    for (int i = 0; i < n; ++i, ++r, ++g, ++b) {
      *r = 255;
      *g = 0;
      *b = 51;
    }
  }
  return msg;
}

CloudIssue IssueOf(const sensor_msgs::PointCloud2& msg, const DecodeOptions& o = {}) {
  try {
    DecodeCloud(msg, Eigen::Isometry3d::Identity(), o);
  } catch (const CloudError& e) {
    EXPECT_NE(std::string(e.what()).find(CloudIssueName(e.issue())), std::string::npos);
    return e.issue();
  }
  ADD_FAILURE() << "no CloudError";
  return CloudIssue::kEmpty;
}

TEST(CloudConversion, XyzRgbTransformedIntoTarget) {
  const auto msg = XyzRgb(100);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(1, 2, 3);
  const DecodedCloud c = DecodeCloud(msg, T);
  ASSERT_EQ(c.points.size(), 100u);
  ASSERT_EQ(c.colors.size(), 100u);
  EXPECT_TRUE(c.normals.empty());
  // (0.5, 1, 2) rotated by 90 deg about z -> (-1, 0.5, 2), + (1, 2, 3).
  EXPECT_NEAR(c.points[50].x(), 0.0, 1e-5);
  EXPECT_NEAR(c.points[50].y(), 2.5, 1e-5);
  EXPECT_NEAR(c.points[50].z(), 5.0, 1e-5);
  EXPECT_NEAR(c.colors[7].x(), 1.0, 1e-6);
  EXPECT_NEAR(c.colors[7].y(), 0.0, 1e-6);
  EXPECT_NEAR(c.colors[7].z(), 0.2, 1e-6);
}

TEST(CloudConversion, Float64FieldsAndNormalsAndOrganisedRowPadding) {
  // Organised 3 x 4 cloud, x/y/z float64 + normals float32, rows padded by 8 bytes.
  sensor_msgs::PointCloud2 msg;
  msg.height = 3;
  msg.width = 4;
  auto field = [&](const char* name, std::uint32_t off, std::uint8_t type) {
    sensor_msgs::PointField f;
    f.name = name;
    f.offset = off;
    f.datatype = type;
    f.count = 1;
    msg.fields.push_back(f);
  };
  using sensor_msgs::PointField;
  field("x", 0, PointField::FLOAT64);
  field("y", 8, PointField::FLOAT64);
  field("z", 16, PointField::FLOAT64);
  field("normal_x", 24, PointField::FLOAT32);
  field("normal_y", 28, PointField::FLOAT32);
  field("normal_z", 32, PointField::FLOAT32);
  msg.point_step = 36;
  msg.row_step = 4 * 36 + 8;
  msg.data.assign(msg.row_step * 3, 0);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) {
      std::uint8_t* p = msg.data.data() + r * msg.row_step + c * msg.point_step;
      const double xyz[3] = {double(c), double(r), 0.5};
      const float n[3] = {0, 0, 1};
      std::memcpy(p, xyz, 24);
      std::memcpy(p + 24, n, 12);
    }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const DecodedCloud out = DecodeCloud(msg, T);
  ASSERT_EQ(out.points.size(), 12u);
  ASSERT_EQ(out.normals.size(), 12u);
  EXPECT_TRUE(out.colors.empty());
  EXPECT_NEAR(out.points[11].x(), 3.0, 1e-6);   // row 2, col 3
  EXPECT_NEAR(out.points[11].y(), -2.0, 1e-6);  // flipped by the rotation
  EXPECT_NEAR(out.points[11].z(), -0.5, 1e-6);
  EXPECT_NEAR(out.normals[0].z(), -1.0, 1e-6);
}

TEST(CloudConversion, NanInfDroppedAndCounted) {
  auto msg = XyzRgb(10);
  sensor_msgs::PointCloud2Iterator<float> x(msg, "x");
  *(x + 2) = std::numeric_limits<float>::quiet_NaN();  // it + i: point i (it[i]: field i)
  *(x + 5) = std::numeric_limits<float>::infinity();
  sensor_msgs::PointCloud2Iterator<float> z(msg, "z");
  *(z + 9) = -std::numeric_limits<float>::infinity();
  const DecodedCloud c = DecodeCloud(msg, Eigen::Isometry3d::Identity());
  EXPECT_EQ(c.points.size(), 7u);
  EXPECT_EQ(c.colors.size(), 7u);
  EXPECT_EQ(c.non_finite, 3u);
}

TEST(CloudConversion, AllNonFiniteOrCroppedIsNoValidPoints) {
  auto msg = XyzRgb(4);
  sensor_msgs::PointCloud2Iterator<float> y(msg, "y");
  for (int i = 0; i < 4; ++i) *(y + i) = std::nanf("");
  EXPECT_EQ(IssueOf(msg), CloudIssue::kNoValidPoints);
  DecodeOptions o;
  o.crop_max = {10, 10, 1.5};  // every point has z = 2
  EXPECT_EQ(IssueOf(XyzRgb(4), o), CloudIssue::kNoValidPoints);
}

TEST(CloudConversion, CropBoxInTargetFrame) {
  DecodeOptions o;
  o.crop_min = {0.195, -10, -10};
  o.crop_max = {0.505, 10, 10};
  const DecodedCloud c = DecodeCloud(XyzRgb(100), Eigen::Isometry3d::Identity(), o);
  EXPECT_EQ(c.points.size(), 31u);  // x = 0.20 .. 0.50
  EXPECT_EQ(c.cropped, 69u);
}

TEST(CloudConversion, EmptyCloud) {
  EXPECT_EQ(IssueOf(XyzRgb(0)), CloudIssue::kEmpty);
  sensor_msgs::PointCloud2 none;
  EXPECT_EQ(IssueOf(none), CloudIssue::kEmpty);
}

TEST(CloudConversion, MissingFields) {
  for (const char* drop : {"x", "y", "z"}) {
    auto msg = XyzRgb(5);
    for (auto& f : msg.fields)
      if (f.name == drop) f.name = "intensity";
    EXPECT_EQ(IssueOf(msg), CloudIssue::kMissingField) << drop;
  }
}

TEST(CloudConversion, WrongFieldTypes) {
  using sensor_msgs::PointField;
  const std::uint8_t types[] = {PointField::INT32, PointField::UINT8, 0, 42};
  for (std::uint8_t t : types) {
    auto msg = XyzRgb(5);
    msg.fields[1].datatype = t;
    EXPECT_EQ(IssueOf(msg), CloudIssue::kBadFieldType) << int(t);
  }
  auto msg = XyzRgb(5);
  msg.fields[2].count = 0;
  EXPECT_EQ(IssueOf(msg), CloudIssue::kBadFieldType);
}

TEST(CloudConversion, FieldOffsetsBeyondPointStep) {
  auto msg = XyzRgb(5);
  msg.fields[2].offset = msg.point_step - 2;
  EXPECT_EQ(IssueOf(msg), CloudIssue::kFieldOutOfBounds);
  auto huge = XyzRgb(5);
  huge.fields[0].offset = 0xffffffffu;  // would overflow a 32-bit offset + size
  EXPECT_EQ(IssueOf(huge), CloudIssue::kFieldOutOfBounds);
}

TEST(CloudConversion, SizeMismatches) {
  auto short_data = XyzRgb(10);
  short_data.data.resize(short_data.data.size() - 1);
  EXPECT_EQ(IssueOf(short_data), CloudIssue::kSizeMismatch);
  auto long_data = XyzRgb(10);
  long_data.data.resize(long_data.data.size() + 16);
  EXPECT_EQ(IssueOf(long_data), CloudIssue::kSizeMismatch);
  auto bad_row = XyzRgb(10);
  bad_row.row_step -= 1;
  EXPECT_EQ(IssueOf(bad_row), CloudIssue::kSizeMismatch);
  auto lying_width = XyzRgb(10);
  lying_width.width = 1000000;  // claims far more points than the data holds
  EXPECT_EQ(IssueOf(lying_width), CloudIssue::kSizeMismatch);
  auto zero_step = XyzRgb(10);
  zero_step.point_step = 0;
  EXPECT_EQ(IssueOf(zero_step), CloudIssue::kSizeMismatch);
  auto overflow = XyzRgb(10);
  overflow.height = 0x10000;
  overflow.row_step = 0x10000;  // row_step x height = 2^32: must not wrap to 0
  overflow.width = 1;
  EXPECT_EQ(IssueOf(overflow), CloudIssue::kSizeMismatch);
}

TEST(CloudConversion, BigEndianRejected) {
  auto msg = XyzRgb(5);
  msg.is_bigendian = true;
  EXPECT_EQ(IssueOf(msg), CloudIssue::kBigEndian);
}

TEST(CloudConversion, TooLargeRejectedBeforeReading) {
  DecodeOptions o;
  o.max_message_points = 50;
  EXPECT_EQ(IssueOf(XyzRgb(51), o), CloudIssue::kTooLarge);
}

TEST(CloudConversion, TenMillionPointsSubsampledToTheCap) {
  const auto msg = XyzRgb(10000000, /*rgb=*/false);
  DecodeOptions o;
  o.max_points = 2000000;
  const DecodedCloud c = DecodeCloud(msg, Eigen::Isometry3d::Identity(), o);
  EXPECT_EQ(c.stride, 5u);
  EXPECT_EQ(c.points.size(), 2000000u);
  EXPECT_EQ(c.message_points, 10000000u);
  EXPECT_NEAR(c.points[1].x(), 0.05f, 1e-5);  // every 5th point
}

TEST(CloudConversion, UnusableColourAndPartialNormalsAreWarningsOnly) {
  auto msg = XyzRgb(5);
  for (auto& f : msg.fields)
    if (f.name == "rgb") f.datatype = sensor_msgs::PointField::FLOAT64;
  DecodedCloud c = DecodeCloud(msg, Eigen::Isometry3d::Identity());
  EXPECT_EQ(c.points.size(), 5u);
  EXPECT_TRUE(c.colors.empty());
  ASSERT_EQ(c.warnings.size(), 1u);
  EXPECT_NE(c.warnings[0].find("colour ignored"), std::string::npos);

  auto partial = XyzRgb(5);
  sensor_msgs::PointField nx;
  nx.name = "normal_x";
  nx.offset = 0;
  nx.datatype = sensor_msgs::PointField::FLOAT32;
  nx.count = 1;
  partial.fields.push_back(nx);
  c = DecodeCloud(partial, Eigen::Isometry3d::Identity());
  EXPECT_TRUE(c.normals.empty());
  ASSERT_EQ(c.warnings.size(), 1u);
  EXPECT_NE(c.warnings[0].find("normals ignored"), std::string::npos);
}

TEST(CloudConversion, MessagesNameFrameAndStamp) {
  auto msg = XyzRgb(5);
  msg.fields.erase(msg.fields.begin());
  try {
    DecodeCloud(msg, Eigen::Isometry3d::Identity());
    FAIL();
  } catch (const CloudError& e) {
    const std::string w = e.what();
    EXPECT_NE(w.find("missing_field"), std::string::npos) << w;
    EXPECT_NE(w.find("'x'"), std::string::npos) << w;
    EXPECT_NE(w.find("'camera'"), std::string::npos) << w;
    EXPECT_NE(w.find("1000."), std::string::npos) << w;
  }
}

}  // namespace
}  // namespace dimr::ros1
