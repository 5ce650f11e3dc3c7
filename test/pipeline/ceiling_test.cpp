#include "dimr/pipeline/ceiling.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "dimr/core/error.h"

namespace dimr::pipeline {
namespace {

using V = Eigen::Vector3f;

// A 4 x 5 m room scanned as mesh vertices (~2 cm spacing, 4 mm noise): floor at z = 0, four
// walls up to `wall_top`, optionally a ceiling at 2.6 m over [cx0, cx1] x [cy0, cy1], a table
// top at 0.75 m and optionally a wardrobe top at 2.1 m. `tag` per point: 0 floor, 1 wall,
// 2 ceiling, 3 table, 4 wardrobe top.
struct Room {
  PointCloudInput cloud;
  std::vector<int> tag;
};

Room MakeRoom(double wall_top, bool ceiling, double cx0 = 0, double cx1 = 4, double cy0 = 0,
              double cy1 = 5, bool wardrobe = false) {
  Room r;
  r.cloud.name = "test room";
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.f, 0.004f);
  const float s = 0.02f;
  auto add = [&](float x, float y, float z, int tag) {
    r.cloud.points.emplace_back(x + noise(rng), y + noise(rng), z + noise(rng));
    r.cloud.colors.emplace_back(0.6f, 0.6f, 0.6f);
    r.tag.push_back(tag);
  };
  for (float x = 0; x <= 4; x += s)
    for (float y = 0; y <= 5; y += s) add(x, y, 0, 0);
  for (float z = 0; z <= wall_top; z += s) {
    for (float x = 0; x <= 4; x += s) add(x, 0, z, 1), add(x, 5, z, 1);
    for (float y = 0; y <= 5; y += s) add(0, y, z, 1), add(4, y, z, 1);
  }
  if (ceiling) {
    for (float x = cx0; x <= cx1; x += s)
      for (float y = cy0; y <= cy1; y += s) add(x, y, 2.6f, 2);
  }
  for (float x = 1.5f; x <= 2.7f; x += s)
    for (float y = 2; y <= 2.8f; y += s) add(x, y, 0.75f, 3);
  if (wardrobe) {
    for (float x = 0.1f; x <= 1.3f; x += s)
      for (float y = 4.3f; y <= 4.9f; y += s) add(x, y, 2.1f, 4);
  }
  return r;
}

TEST(RemoveCeiling, DropsTheCeilingAndNothingBelowIt) {
  const Room room = MakeRoom(2.6, true);
  const CeilingRemoval c = RemoveCeiling(room.cloud, CeilingConfig());
  ASSERT_TRUE(c.found);
  EXPECT_NEAR(c.ceiling_z, 2.6, 0.01);
  EXPECT_NEAR(c.floor_z, 0.0, 0.02);
  EXPECT_GT(c.area, 15.0);  // most of the 20 m² ceiling is flat cells
  ASSERT_EQ(c.kept.size(), c.cloud.points.size());
  ASSERT_EQ(c.cloud.colors.size(), c.cloud.points.size());
  EXPECT_EQ(c.removed + c.kept.size(), room.cloud.points.size());
  std::vector<char> kept(room.cloud.points.size(), 0);
  for (std::size_t j = 0; j < c.kept.size(); ++j) {
    const int i = c.kept[j];
    kept[i] = 1;
    EXPECT_EQ(c.cloud.points[j], room.cloud.points[i]);
  }
  // Every point below the layer stays; wall points in the layer stay up to just below the
  // ceiling (rim rule) except in a few corner cells.
  std::size_t rim = 0, rim_kept = 0;
  for (std::size_t i = 0; i < room.tag.size(); ++i) {
    const float z = room.cloud.points[i].z();
    if (room.tag[i] == 2) {
      EXPECT_FALSE(kept[i]) << "ceiling point " << i << " kept";
    } else if (z < 2.5f) {
      EXPECT_TRUE(kept[i]) << "point " << i << " at z " << z;
    } else if (z < 2.55f) {
      ++rim;
      rim_kept += kept[i];
    }
  }
  ASSERT_GT(rim, 1000u);
  EXPECT_GT(rim_kept, rim * 99 / 100) << rim_kept << " of " << rim;
}

TEST(RemoveCeiling, LeavesRoomsWithoutACeilingAlone) {
  // Walls to 2.6 m without a ceiling: the top layer is walls only, not flat.
  const Room open = MakeRoom(2.6, false);
  CeilingRemoval c = RemoveCeiling(open.cloud, CeilingConfig());
  EXPECT_FALSE(c.found);
  EXPECT_EQ(c.cloud.points.size(), open.cloud.points.size());
  EXPECT_EQ(c.kept.size(), open.cloud.points.size());
  EXPECT_EQ(c.removed, 0u);
  // A scan that stops at 1.4 m (scene0470_00 stops at 1.37 m).
  EXPECT_FALSE(RemoveCeiling(MakeRoom(1.4, false).cloud, CeilingConfig()).found);
  // A wardrobe top at 2.1 m below walls that go on to 2.6 m is not the top of the cloud.
  EXPECT_FALSE(
      RemoveCeiling(MakeRoom(2.6, false, 0, 4, 0, 5, /*wardrobe=*/true).cloud, CeilingConfig())
          .found);
  // A ceiling patch of 1 x 1 m: below min_area (1.5 m²).
  c = RemoveCeiling(MakeRoom(2.6, true, 1, 2, 1, 2).cloud, CeilingConfig());
  EXPECT_FALSE(c.found);
  EXPECT_NEAR(c.area, 1.0, 0.3);
  // ... found once the area rule allows it.
  CeilingConfig small;
  small.min_area = 0.5;
  small.min_area_fraction = 0.02;
  EXPECT_TRUE(RemoveCeiling(MakeRoom(2.6, true, 1, 2, 1, 2).cloud, small).found);
  // A partial ceiling (a third of the room, as a hand-held scan sees it) is found.
  EXPECT_TRUE(RemoveCeiling(MakeRoom(2.6, true, 0, 4, 0, 1.7).cloud, CeilingConfig()).found);
  // Disabled: unchanged even with a ceiling.
  CeilingConfig off;
  off.enabled = false;
  c = RemoveCeiling(MakeRoom(2.6, true).cloud, off);
  EXPECT_FALSE(c.found);
  EXPECT_EQ(c.removed, 0u);
}

TEST(RemoveCeiling, BadInputAndConfigNameTheProblem) {
  Room room = MakeRoom(1.0, false);
  room.cloud.points[17].y() = NAN;
  try {
    RemoveCeiling(room.cloud, CeilingConfig());
    FAIL() << "no throw";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("'test room': point 17"), std::string::npos) << e.what();
  }
  room = MakeRoom(1.0, false);
  room.cloud.colors.pop_back();
  EXPECT_THROW(RemoveCeiling(room.cloud, CeilingConfig()), InvalidArgument);
  CeilingConfig bad;
  bad.band = 0;
  EXPECT_THROW(RemoveCeiling(MakeRoom(1.0, false).cloud, bad), InvalidArgument);
  bad = CeilingConfig();
  bad.min_area_fraction = 2;
  EXPECT_THROW(bad.Validate(), InvalidArgument);
  // An empty cloud is returned as it is.
  EXPECT_FALSE(RemoveCeiling(PointCloudInput(), CeilingConfig()).found);
}

TEST(RemoveCeiling, AGivenAwayCloudGivesTheSameResultWithoutACopy) {
  for (const bool with_ceiling : {true, false}) {
    Room room = MakeRoom(2.6, with_ceiling);
    room.cloud.normals.assign(room.cloud.points.size(), V(0, 0, 1));
    room.cloud.normals[5] = V(1, 0, 0);
    const CeilingRemoval copy = RemoveCeiling(room.cloud, CeilingConfig());
    const V* data = room.cloud.points.data();
    const CeilingRemoval moved = RemoveCeiling(std::move(room.cloud), CeilingConfig());
    EXPECT_EQ(moved.found, with_ceiling);
    EXPECT_EQ(moved.found, copy.found);
    EXPECT_EQ(moved.removed, copy.removed);
    EXPECT_EQ(moved.kept, copy.kept);
    EXPECT_EQ(moved.cloud.name, "test room");
    EXPECT_EQ(moved.cloud.points.data(), data);  // the same storage, compacted in place
    ASSERT_EQ(moved.cloud.points.size(), copy.cloud.points.size());
    ASSERT_EQ(moved.cloud.colors.size(), moved.cloud.points.size());
    ASSERT_EQ(moved.cloud.normals.size(), moved.cloud.points.size());
    for (std::size_t j = 0; j < moved.cloud.points.size(); ++j) {
      ASSERT_EQ(moved.cloud.points[j], copy.cloud.points[j]) << j;
      ASSERT_EQ(moved.cloud.normals[j], copy.cloud.normals[j]) << j;
    }
    EXPECT_EQ(moved.cloud.normals[5], V(1, 0, 0));  // point 5 (floor) is kept at its index
  }
  // A throw leaves the given-away cloud as it was.
  Room bad = MakeRoom(2.6, true);
  bad.cloud.points[3].x() = INFINITY;
  const std::size_t n = bad.cloud.points.size();
  try {
    RemoveCeiling(std::move(bad.cloud), CeilingConfig());
    FAIL() << "no throw";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("ceiling removal: point cloud 'test room': point 3"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(bad.cloud.points.size(), n);
  EXPECT_EQ(bad.cloud.colors.size(), n);
}

TEST(PointCloudInput, ValidateShapeAcceptsAnEmptyCloudAndNamesBadOnes) {
  EXPECT_NO_THROW(PointCloudInput().ValidateShape());
  EXPECT_THROW(PointCloudInput().Validate(), InvalidArgument);  // Validate wants points
  Room room = MakeRoom(1.0, false);
  room.cloud.colors[2] = V(3, 0, 0);  // out of range: Validate's business, not the shape's
  EXPECT_NO_THROW(room.cloud.ValidateShape());
  EXPECT_THROW(room.cloud.Validate(), InvalidArgument);
  room.cloud.normals.resize(4);
  try {
    room.cloud.ValidateShape();
    FAIL() << "no throw";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("4 normals for"), std::string::npos) << e.what();
  }
}

TEST(RemoveCeiling, ResultsGoBackToTheInputPoints) {
  const std::vector<int> kept = {0, 2, 3};
  EXPECT_EQ(ExpandKeptLabels({5, 6, 7}, kept, 5, -1), std::vector<int>({5, -1, 6, 7, -1}));
  EXPECT_EQ(ExpandKeptPoints({2, 0}, kept), std::vector<int>({3, 0}));
  EXPECT_THROW(ExpandKeptLabels({5, 6}, kept, 5, -1), InvalidArgument);
  EXPECT_THROW(ExpandKeptLabels({5, 6, 7}, kept, 3, -1), InvalidArgument);
  EXPECT_THROW(ExpandKeptPoints({3}, kept), InvalidArgument);
}

}  // namespace
}  // namespace dimr::pipeline
