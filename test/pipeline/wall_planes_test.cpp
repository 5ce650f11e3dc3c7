#include "dimr/pipeline/wall_planes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "dimr/core/error.h"
#include "dimr/core/labels.h"

namespace dimr::pipeline {
namespace {

using V = Eigen::Vector3f;

// A 4 x 5 m room (2 cm grid, 4 mm noise): floor, four walls to 2.4 m, a free-standing
// wardrobe-like panel 1.5 x 1.8 m at 0.6 m in front of the x = 0 wall, and a chair-like box in
// the middle. Labels as a confused stage 1 gives them: a stretch of the y = 0 wall as curtain,
// another as chair, a door in the x = 4 wall, the panel as bed, the box as chair.
struct Scene {
  std::vector<V> points;
  std::vector<int> label;
  std::vector<int> truth;  // what each point is: wall, floor, door, bed (panel), chair
};

Scene MakeScene() {
  using namespace labels;
  Scene s;
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.f, 0.004f);
  auto add = [&](float x, float y, float z, int label, int truth) {
    s.points.emplace_back(x + noise(rng), y + noise(rng), z + noise(rng));
    s.label.push_back(label);
    s.truth.push_back(truth);
  };
  const float g = 0.02f;
  for (int i = 0; i <= 200; ++i)
    for (int j = 0; j <= 250; ++j) add(g * i, g * j, 0, kFloor, kFloor);
  for (int k = 1; k <= 120; ++k) {
    const float z = g * k;
    for (int i = 0; i <= 200; ++i) {
      const float x = g * i;
      int l = kWall;
      if (x > 0.5f && x < 1.5f) l = kCurtain;
      if (x > 2.5f && x < 3.0f && z < 1.0f) l = kChair;
      add(x, 0, z, l, kWall);
      add(x, 5, z, kWall, kWall);
    }
    for (int j = 0; j <= 250; ++j) {
      const float y = g * j;
      add(0, y, z, kWall, kWall);
      const bool door = y > 2.0f && y < 2.9f && z < 2.0f;
      add(4, y, z, door ? kDoor : kWall, door ? kDoor : kWall);
    }
  }
  for (float y = 1.5f; y <= 3.0f; y += g)
    for (float z = 0.f; z <= 1.8f; z += g) add(0.6f, y, z, kBed, kBed);
  for (float x = 2.0f; x <= 2.5f; x += g)
    for (float y = 2.0f; y <= 2.5f; y += g)
      add(x, y, 0.45f, kChair, kChair), add(x, y, 0.9f, kChair, kChair);
  return s;
}

TEST(WallPlanes, WallPointsTakenForFurnitureBecomeWallAndNothingElseChanges) {
  Scene s = MakeScene();
  std::vector<int> label = s.label;
  const WallPlaneResult r = ApplyWallPlanes(s.points, WallPlaneConfig(), &label);
  EXPECT_GE(r.planes.size(), 4u);
  ASSERT_EQ(r.planes.size(), r.areas.size());
  for (double a : r.areas) EXPECT_GE(a, 2.0);
  std::size_t wrong_wall = 0, fixed = 0, changed_other = 0;
  for (std::size_t i = 0; i < label.size(); ++i) {
    if (s.truth[i] == labels::kWall && s.label[i] != labels::kWall) {
      ++wrong_wall;
      fixed += label[i] == labels::kWall;
    } else if (label[i] != s.label[i]) {
      ++changed_other;
    }
  }
  ASSERT_GT(wrong_wall, 5000u);
  EXPECT_GT(fixed, wrong_wall * 98 / 100) << fixed << " of " << wrong_wall;
  EXPECT_EQ(changed_other, 0u);  // the door, the panel (bed) and the chair keep their labels
  EXPECT_EQ(r.relabelled, fixed);
  // Deterministic.
  std::vector<int> again = s.label;
  ApplyWallPlanes(s.points, WallPlaneConfig(), &again);
  EXPECT_EQ(again, label);
}

TEST(WallPlanes, SmallPlanesAndBadInput) {
  using namespace labels;
  // A lone 1 x 1 m vertical panel labelled curtain: below min_area, untouched.
  std::vector<V> pts;
  for (int i = 0; i <= 50; ++i)
    for (int k = 0; k <= 50; ++k) pts.emplace_back(0.02f * i, 0.f, 0.02f * k);
  std::vector<int> lab(pts.size(), kCurtain);
  EXPECT_TRUE(ApplyWallPlanes(pts, WallPlaneConfig(), &lab).planes.empty());
  EXPECT_EQ(lab, std::vector<int>(pts.size(), kCurtain));
  // ... and a wall once the area rule allows it (nothing behind it).
  WallPlaneConfig small;
  small.min_area = 0.5;
  EXPECT_EQ(ApplyWallPlanes(pts, small, &lab).planes.size(), 1u);
  EXPECT_EQ(lab, std::vector<int>(pts.size(), kWall));
  std::vector<int> shortl(3, kWall);
  EXPECT_THROW(ApplyWallPlanes(pts, WallPlaneConfig(), &shortl), InvalidArgument);
  pts[7].z() = NAN;
  lab.assign(pts.size(), kWall);
  try {
    ApplyWallPlanes(pts, WallPlaneConfig(), &lab);
    FAIL() << "no throw";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("point 7"), std::string::npos) << e.what();
  }
  WallPlaneConfig bad;
  bad.distance = 0;
  EXPECT_THROW(bad.Validate(), InvalidArgument);
  EXPECT_TRUE(WallPlaneOverrides(kCurtain));
  EXPECT_TRUE(WallPlaneOverrides(kChair));
  EXPECT_FALSE(WallPlaneOverrides(kDoor));
  EXPECT_FALSE(WallPlaneOverrides(kCabinet));
  EXPECT_FALSE(WallPlaneOverrides(kWall));
}

}  // namespace
}  // namespace dimr::pipeline
