// PointCloud2 decoding with layout validation (see cloud_conversion.h).
#include "dimr/ros/cloud_conversion.h"

#include <sensor_msgs/PointField.h>

#include <cmath>
#include <cstring>

namespace dimr::ros1 {
namespace {

using sensor_msgs::PointField;

int DatatypeSize(std::uint8_t t) {
  switch (t) {
    case PointField::INT8:
    case PointField::UINT8:
      return 1;
    case PointField::INT16:
    case PointField::UINT16:
      return 2;
    case PointField::INT32:
    case PointField::UINT32:
    case PointField::FLOAT32:
      return 4;
    case PointField::FLOAT64:
      return 8;
    default:
      return 0;
  }
}

const PointField* FindField(const sensor_msgs::PointCloud2& msg, const std::string& name) {
  for (const PointField& f : msg.fields)
    if (f.name == name) return &f;
  return nullptr;
}

std::string Where(const sensor_msgs::PointCloud2& msg) {
  return " (frame '" + msg.header.frame_id + "', stamp " + std::to_string(msg.header.stamp.sec) +
         "." + std::to_string(msg.header.stamp.nsec / 1000000) + ")";
}

// Checks one field of a float coordinate triple; returns its datatype size.
int CheckFloatField(const sensor_msgs::PointCloud2& msg, const PointField* f,
                    const std::string& name, bool required) {
  if (!f) {
    if (!required) return 0;
    std::string have;
    for (const PointField& g : msg.fields) have += (have.empty() ? "" : ", ") + g.name;
    throw CloudError(
        CloudIssue::kMissingField,
        "no field '" + name + "' (fields: " + (have.empty() ? "none" : have) + ")" + Where(msg));
  }
  const int size = DatatypeSize(f->datatype);
  if (size == 0)
    throw CloudError(CloudIssue::kBadFieldType, "field '" + name + "' has unknown datatype " +
                                                    std::to_string(f->datatype) + Where(msg));
  if (f->datatype != PointField::FLOAT32 && f->datatype != PointField::FLOAT64)
    throw CloudError(CloudIssue::kBadFieldType, "field '" + name +
                                                    "' must be FLOAT32 or FLOAT64, has datatype " +
                                                    std::to_string(f->datatype) + Where(msg));
  if (f->count < 1)
    throw CloudError(CloudIssue::kBadFieldType, "field '" + name + "' has count 0" + Where(msg));
  if (static_cast<std::uint64_t>(f->offset) + size > msg.point_step)
    throw CloudError(CloudIssue::kFieldOutOfBounds,
                     "field '" + name + "' at offset " + std::to_string(f->offset) + " (+" +
                         std::to_string(size) + " bytes) lies beyond point_step " +
                         std::to_string(msg.point_step) + Where(msg));
  return size;
}

inline double ReadFloat(const std::uint8_t* p, int size) {
  if (size == 4) {
    float v;
    std::memcpy(&v, p, 4);
    return v;
  }
  double v;
  std::memcpy(&v, p, 8);
  return v;
}

}  // namespace

const char* CloudIssueName(CloudIssue issue) {
  switch (issue) {
    case CloudIssue::kEmpty:
      return "empty_cloud";
    case CloudIssue::kBigEndian:
      return "big_endian";
    case CloudIssue::kMissingField:
      return "missing_field";
    case CloudIssue::kBadFieldType:
      return "bad_field_type";
    case CloudIssue::kFieldOutOfBounds:
      return "field_out_of_bounds";
    case CloudIssue::kSizeMismatch:
      return "size_mismatch";
    case CloudIssue::kTooLarge:
      return "too_large";
    case CloudIssue::kNoValidPoints:
      return "no_valid_points";
  }
  return "unknown";
}

DecodedCloud DecodeCloud(const sensor_msgs::PointCloud2& msg, const Eigen::Isometry3d& to_target,
                         const DecodeOptions& opt) {
  const std::uint64_t n = static_cast<std::uint64_t>(msg.width) * msg.height;
  if (n == 0 || msg.data.empty())
    throw CloudError(CloudIssue::kEmpty, "width " + std::to_string(msg.width) + " x height " +
                                             std::to_string(msg.height) + ", " +
                                             std::to_string(msg.data.size()) + " data bytes" +
                                             Where(msg));
  if (msg.is_bigendian)
    throw CloudError(CloudIssue::kBigEndian,
                     "big-endian clouds are not supported (convert on the sender)" + Where(msg));
  if (n > opt.max_message_points)
    throw CloudError(CloudIssue::kTooLarge, std::to_string(n) + " points exceed the limit of " +
                                                std::to_string(opt.max_message_points) +
                                                Where(msg));
  if (msg.point_step == 0)
    throw CloudError(CloudIssue::kSizeMismatch, "point_step is 0" + Where(msg));
  if (static_cast<std::uint64_t>(msg.width) * msg.point_step > msg.row_step)
    throw CloudError(CloudIssue::kSizeMismatch, "row_step " + std::to_string(msg.row_step) +
                                                    " < width " + std::to_string(msg.width) +
                                                    " x point_step " +
                                                    std::to_string(msg.point_step) + Where(msg));
  if (static_cast<std::uint64_t>(msg.row_step) * msg.height != msg.data.size())
    throw CloudError(
        CloudIssue::kSizeMismatch,
        "data has " + std::to_string(msg.data.size()) + " bytes, row_step " +
            std::to_string(msg.row_step) + " x height " + std::to_string(msg.height) + " = " +
            std::to_string(static_cast<std::uint64_t>(msg.row_step) * msg.height) + Where(msg));

  const PointField* fx = FindField(msg, "x");
  const PointField* fy = FindField(msg, "y");
  const PointField* fz = FindField(msg, "z");
  const int sx = CheckFloatField(msg, fx, "x", true);
  const int sy = CheckFloatField(msg, fy, "y", true);
  const int sz = CheckFloatField(msg, fz, "z", true);

  DecodedCloud out;
  out.message_points = n;

  // Optional normals: all three or none.
  const PointField* fnx = FindField(msg, "normal_x");
  const PointField* fny = FindField(msg, "normal_y");
  const PointField* fnz = FindField(msg, "normal_z");
  int snx = 0, sny = 0, snz = 0;
  if (fnx && fny && fnz) {
    try {
      snx = CheckFloatField(msg, fnx, "normal_x", true);
      sny = CheckFloatField(msg, fny, "normal_y", true);
      snz = CheckFloatField(msg, fnz, "normal_z", true);
    } catch (const CloudError& e) {
      out.warnings.push_back(std::string("normals ignored: ") + e.what());
      snx = sny = snz = 0;
    }
  } else if (fnx || fny || fnz) {
    out.warnings.push_back("normals ignored: normal_x/normal_y/normal_z are not all present");
  }

  // Optional colour: packed rgb / rgba (FLOAT32 or UINT32, 0x00RRGGBB little-endian).
  const PointField* fc = FindField(msg, "rgb");
  if (!fc) fc = FindField(msg, "rgba");
  bool has_color = false;
  if (fc) {
    const int s = DatatypeSize(fc->datatype);
    if (s != 4 || (fc->datatype != PointField::FLOAT32 && fc->datatype != PointField::UINT32 &&
                   fc->datatype != PointField::INT32))
      out.warnings.push_back("colour ignored: field '" + fc->name +
                             "' is not a packed 4-byte FLOAT32/UINT32");
    else if (static_cast<std::uint64_t>(fc->offset) + 4 > msg.point_step)
      out.warnings.push_back("colour ignored: field '" + fc->name + "' lies beyond point_step");
    else
      has_color = true;
  }

  const std::size_t max_points = std::max<std::size_t>(1, opt.max_points);
  out.stride = static_cast<std::size_t>((n + max_points - 1) / max_points);
  const std::size_t visit = static_cast<std::size_t>((n + out.stride - 1) / out.stride);
  out.points.reserve(visit);
  if (has_color) out.colors.reserve(visit);
  if (snx) out.normals.reserve(visit);

  const Eigen::Matrix3d rot = to_target.linear();
  const Eigen::Vector3d lo(opt.crop_min[0], opt.crop_min[1], opt.crop_min[2]);
  const Eigen::Vector3d hi(opt.crop_max[0], opt.crop_max[1], opt.crop_max[2]);
  const std::uint8_t* base = msg.data.data();
  for (std::uint64_t k = 0; k < n; k += out.stride) {
    const std::uint64_t row = k / msg.width, col = k % msg.width;
    const std::uint8_t* p = base + row * msg.row_step + col * msg.point_step;
    const Eigen::Vector3d local(ReadFloat(p + fx->offset, sx), ReadFloat(p + fy->offset, sy),
                                ReadFloat(p + fz->offset, sz));
    if (!local.allFinite()) {
      ++out.non_finite;
      continue;
    }
    const Eigen::Vector3d q = to_target * local;
    if ((q.array() < lo.array()).any() || (q.array() > hi.array()).any()) {
      ++out.cropped;
      continue;
    }
    out.points.push_back(q.cast<float>());
    if (has_color) {
      std::uint32_t packed;
      std::memcpy(&packed, p + fc->offset, 4);
      out.colors.emplace_back(((packed >> 16) & 0xff) / 255.0f, ((packed >> 8) & 0xff) / 255.0f,
                              (packed & 0xff) / 255.0f);
    }
    if (snx) {
      Eigen::Vector3d nrm(ReadFloat(p + fnx->offset, snx), ReadFloat(p + fny->offset, sny),
                          ReadFloat(p + fnz->offset, snz));
      if (!nrm.allFinite()) nrm.setZero();
      out.normals.push_back((rot * nrm).cast<float>());
    }
  }
  if (out.points.empty())
    throw CloudError(CloudIssue::kNoValidPoints,
                     "no usable point: " + std::to_string(out.non_finite) + " NaN/Inf, " +
                         std::to_string(out.cropped) + " outside the crop box, of " +
                         std::to_string(visit) + " visited" + Where(msg));
  return out;
}

}  // namespace dimr::ros1
