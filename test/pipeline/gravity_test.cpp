#include "dimr/pipeline/gravity.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "dimr/core/error.h"

namespace dimr::pipeline {
namespace {

TEST(UpAxisRotation, MapsTheNamedAxisToZWithAProperRotation) {
  const std::pair<std::string, Eigen::Vector3f> cases[] = {
      {"z", {0, 0, 1}},   {"+z", {0, 0, 1}}, {"-z", {0, 0, -1}}, {"y", {0, 1, 0}},
      {"-y", {0, -1, 0}}, {"x", {1, 0, 0}},  {"-x", {-1, 0, 0}}};
  for (const auto& [name, axis] : cases) {
    const Eigen::Matrix3f r = UpAxisRotation(name);
    EXPECT_TRUE((r * axis).isApprox(Eigen::Vector3f(0, 0, 1))) << name;
    EXPECT_NEAR(r.determinant(), 1.0f, 1e-6f) << name;
    EXPECT_TRUE((r * r.transpose()).isIdentity(1e-6f)) << name;
  }
  // A camera's optical frame (x right, y down, z forward): a point 1 m below the camera and 2 m
  // ahead ends 1 m below it (z = -1), 2 m ahead along y.
  EXPECT_TRUE(
      (UpAxisRotation("-y") * Eigen::Vector3f(0, 1, 2)).isApprox(Eigen::Vector3f(0, 2, -1)));
  EXPECT_THROW(UpAxisRotation("up"), InvalidArgument);
  EXPECT_THROW(UpAxisRotation(""), InvalidArgument);
}

// A 4 x 3 m room: floor, two walls up to 2.5 m, a 0.8 m table top; ~3 cm spacing.
PointCloudInput Room() {
  PointCloudInput c;
  c.name = "room";
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.f, 0.003f);
  auto add = [&](float x, float y, float z) {
    c.points.emplace_back(x + noise(rng), y + noise(rng), z + noise(rng));
  };
  for (float x = 0; x <= 4; x += 0.03f)
    for (float y = 0; y <= 3; y += 0.03f) add(x, y, 0);
  for (float z = 0; z <= 2.5f; z += 0.03f) {
    for (float x = 0; x <= 4; x += 0.03f) add(x, 0, z);
    for (float y = 0; y <= 3; y += 0.03f) add(0, y, z);
  }
  for (float x = 1; x <= 2.2f; x += 0.03f)
    for (float y = 1; y <= 1.8f; y += 0.03f) add(x, y, 0.8f);
  return c;
}

TEST(CheckFloor, ARoomHasItsFloorAtTheBottomAndACameraFrameDoesNot) {
  const PointCloudInput room = Room();
  const FloorCheck ok = CheckFloor(room);
  EXPECT_TRUE(ok.found);
  EXPECT_GT(ok.area_fraction, 0.8);
  EXPECT_NEAR(ok.floor_z, 0.0, 0.01);
  // The room seen by a depth camera at (2, 0.5, 1.3) looking along +y, in its optical frame
  // (x right, y down, z forward: the inverse of --up -y); only what lies ahead of it.
  const Eigen::Matrix3f to_camera = UpAxisRotation("-y").transpose();
  const Eigen::Vector3f eye(2, 0.5f, 1.3f);
  PointCloudInput camera;
  for (const auto& p : room.points) {
    if (p.y() > eye.y() + 0.4f) camera.points.push_back(to_camera * (p - eye));
  }
  const FloorCheck bad = CheckFloor(camera);
  EXPECT_FALSE(bad.found);
  EXPECT_LT(bad.area_fraction, 0.3);
  // --up -y brings it back.
  for (auto& p : camera.points) p = UpAxisRotation("-y") * p;
  EXPECT_TRUE(CheckFloor(camera).found);
  // A room without its floor (a map of walls and a table) is flagged too.
  PointCloudInput no_floor;
  for (const auto& p : room.points) {
    if (p.z() > 0.05f) no_floor.points.push_back(p);
  }
  EXPECT_FALSE(CheckFloor(no_floor).found);
  EXPECT_THROW(CheckFloor(PointCloudInput()), InvalidArgument);
  PointCloudInput nan = room;
  nan.points[4].z() = NAN;
  EXPECT_THROW(CheckFloor(nan), InvalidArgument);
  FloorCheckConfig bad_config;
  bad_config.cell = 0;
  EXPECT_THROW(CheckFloor(room, bad_config), InvalidArgument);
}

TEST(FindFloorPlane, LevelsATiltedRoomAndFindsNoFloorWhereThereIsNone) {
  const PointCloudInput room = Room();
  const FloorPlane level = FindFloorPlane(room);
  ASSERT_TRUE(level.found);
  EXPECT_LT(level.tilt_deg, 1.0);
  EXPECT_GT(level.inliers, 0.3);
  // Pitched by 20 degrees about x and rolled by 7 about y (a camera looking down at the room).
  const Eigen::Matrix3f tilt = (Eigen::AngleAxisf(0.349f, Eigen::Vector3f::UnitX()) *
                                Eigen::AngleAxisf(0.122f, Eigen::Vector3f::UnitY()))
                                   .toRotationMatrix();
  PointCloudInput tilted = room;
  tilted.Rotate(tilt);
  const FloorPlane f = FindFloorPlane(tilted);
  ASSERT_TRUE(f.found);
  EXPECT_NEAR(f.tilt_deg, std::acos((tilt * Eigen::Vector3f::UnitZ()).z()) * 180.0 / 3.14159265,
              0.5);
  EXPECT_GT(f.normal.dot(tilt * Eigen::Vector3f::UnitZ()), 0.9995f);
  // Levelled: the floor points lie flat again (z spread of the original floor, < 2 cm).
  const Eigen::Matrix3f r = LevellingRotation(f.normal);
  EXPECT_NEAR(r.determinant(), 1.0f, 1e-5f);
  float lo = 1e9f, hi = -1e9f;
  for (std::size_t i = 0; i < room.size(); ++i) {
    if (std::abs(room.points[i].z()) > 0.02f) continue;  // floor points of the original
    const float z = (r * tilted.points[i]).z();
    lo = std::min(lo, z);
    hi = std::max(hi, z);
  }
  EXPECT_LT(hi - lo, 0.03f);
  // PointCloudInput::Rotate turns points and normals, not colours.
  PointCloudInput one;
  one.points = {Eigen::Vector3f(0, 1, 0)};
  one.normals = {Eigen::Vector3f(0, 0, 1)};
  one.colors = {Eigen::Vector3f(0.1f, 0.2f, 0.3f)};
  one.Rotate(r);
  EXPECT_TRUE(one.points[0].isApprox(r * Eigen::Vector3f(0, 1, 0)));
  EXPECT_TRUE(one.normals[0].isApprox(r.col(2)));
  EXPECT_EQ(one.colors[0], Eigen::Vector3f(0.1f, 0.2f, 0.3f));
  // Deterministic.
  const FloorPlane again = FindFloorPlane(tilted);
  EXPECT_EQ(again.normal, f.normal);
  // Without a floor: walls are too steep, the table top has the walls' lower parts below it.
  PointCloudInput no_floor;
  for (const auto& p : room.points) {
    if (p.z() > 0.05f) no_floor.points.push_back(p);
  }
  EXPECT_FALSE(FindFloorPlane(no_floor).found);
  EXPECT_THROW(FindFloorPlane(PointCloudInput()), InvalidArgument);
  LevelConfig bad;
  bad.max_tilt_deg = 95;
  EXPECT_THROW(FindFloorPlane(room, bad), InvalidArgument);
  EXPECT_THROW(LevellingRotation(Eigen::Vector3f::Zero()), InvalidArgument);
  EXPECT_TRUE(LevellingRotation(Eigen::Vector3f(0, 0, 2)).isIdentity(1e-6f));
}

}  // namespace
}  // namespace dimr::pipeline
