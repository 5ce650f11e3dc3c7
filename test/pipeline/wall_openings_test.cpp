#include "dimr/pipeline/wall_openings.h"

#include <gtest/gtest.h>

#include <random>
#include <string>

#include "dimr/core/error.h"
#include "dimr/core/labels.h"

namespace dimr::pipeline {
namespace {

using V = Eigen::Vector3f;

// A 4 x 5 m room (2 cm grid, 3 mm noise), walls to 2.4 m, cream walls, as a stage 1 that takes
// flat things in the wall for wall labels it, with per-point probabilities:
//   A  a closed door in the x = 4 wall (y 2.0-2.9, z < 2.0), brown, flush with the wall:
//      P(door) 0.35 - the network's second choice, strong enough alone;
//   B  a window pane in the y = 5 wall (x 1.0-2.2, z 0.9-2.0), 4 cm behind the wall's face,
//      grey-blue: P(window) 0.12 - weak, with colour contrast and recess;
//   C  a stretch of the x = 0 wall (y 1.0-2.0, z 0.5-1.5), wall-coloured, flush: the same
//      weak P(window) 0.12 and nothing else - must stay wall;
//   D  a patch 0.15 x 0.15 m on the y = 0 wall with P(picture) 0.6: too small - stays wall;
//   E  a chair-labelled stretch of the y = 0 wall with P(door) 0.35: only wall labels change;
//   F  a brown panel 0.6 x 0.6 m at the foot of the y = 0 wall (x 1.5-2.1), P(wall) 0.9: by
//      colour an opening, by shape neither door (too low) nor window (on the floor).
// Everywhere else P(wall) 0.9 (walls) or P(floor) 0.9.
struct Scene {
  std::vector<V> points, colours;
  std::vector<int> label;
  std::vector<char> region;  // 'A'..'E' or 0
  nn::Stage1PointRows rows;
};

Scene MakeScene() {
  using namespace labels;
  Scene s;
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.f, 0.003f), tint(0.f, 0.02f);
  auto add = [&](V p, V colour, int label, char region, int cls, float prob) {
    s.points.push_back(p + V(noise(rng), noise(rng), noise(rng)));
    s.colours.push_back(colour + V::Constant(tint(rng)));
    s.label.push_back(label);
    s.region.push_back(region);
    std::vector<float> row(kNumRfsClasses, (1.f - prob) / (kNumRfsClasses - 1));
    row[cls] = prob;
    if (cls != kWall && cls != kFloor) {  // the argmax is wall
      const float rest = 1.f - prob - 0.5f;
      std::fill(row.begin(), row.end(), rest / (kNumRfsClasses - 2));
      row[kWall] = 0.5f, row[cls] = prob;
    }
    s.rows.semantic_prob.insert(s.rows.semantic_prob.end(), row.begin(), row.end());
  };
  const V cream(0.85f, 0.82f, 0.74f), brown(0.45f, 0.3f, 0.18f), glass(0.55f, 0.62f, 0.7f);
  const float g = 0.02f;
  for (int i = 0; i <= 200; ++i)
    for (int j = 0; j <= 250; ++j)
      add(V(g * i, g * j, 0), V(0.5f, 0.45f, 0.4f), kFloor, 0, kFloor, 0.9f);
  for (int k = 1; k <= 120; ++k) {
    const float z = g * k;
    for (int i = 0; i <= 200; ++i) {
      const float x = g * i;
      // y = 0 wall: D (picture patch), E (chair-labelled stretch).
      if (x > 0.5f && x < 0.65f && z > 1.2f && z < 1.35f)
        add(V(x, 0, z), cream, kWall, 'D', kPicture, 0.6f);
      else if (x > 2.5f && x < 3.2f && z < 1.0f)
        add(V(x, 0, z), cream, kChair, 'E', kDoor, 0.35f);
      else if (x > 1.5f && x < 2.1f && z < 0.6f)
        add(V(x, 0, z), brown, kWall, 'F', kWall, 0.9f);
      else
        add(V(x, 0, z), cream, kWall, 0, kWall, 0.9f);
      // y = 5 wall: B, the pane behind the opening (the wall itself is absent there).
      if (x > 1.0f && x < 2.2f && z > 0.9f && z < 2.0f)
        add(V(x, 5.04f, z), glass, kWall, 'B', kWindow, 0.12f);
      else
        add(V(x, 5, z), cream, kWall, 0, kWall, 0.9f);
    }
    for (int j = 0; j <= 250; ++j) {
      const float y = g * j;
      if (y > 1.0f && y < 2.0f && z > 0.5f && z < 1.5f)
        add(V(0, y, z), cream, kWall, 'C', kWindow, 0.12f);
      else
        add(V(0, y, z), cream, kWall, 0, kWall, 0.9f);
      if (y > 2.0f && y < 2.9f && z < 2.0f)
        add(V(4, y, z), brown, kWall, 'A', kDoor, 0.35f);
      else
        add(V(4, y, z), cream, kWall, 0, kWall, 0.9f);
    }
  }
  return s;
}

// Per region (0 = none, 1..6 = A..F): points, and of A / B those now door / window; points
// outside A and B whose label changed.
struct Tally {
  std::size_t count[7] = {}, hit[7] = {}, changed_elsewhere = 0;
};
Tally Count(const Scene& s, const std::vector<int>& label) {
  Tally t;
  for (std::size_t i = 0; i < label.size(); ++i) {
    const int k = s.region[i] ? s.region[i] - 'A' + 1 : 0;
    ++t.count[k];
    if (k == 1) t.hit[k] += label[i] == labels::kDoor;
    if (k == 2) t.hit[k] += label[i] == labels::kWindow;
    if (k == 0 || k >= 3) t.changed_elsewhere += label[i] != s.label[i];
  }
  return t;
}

WallPlaneResult Planes(const Scene& s) {
  std::vector<int> copy = s.label;
  return ApplyWallPlanes(s.points, WallPlaneConfig(), &copy);
}

TEST(WallOpenings, DoorsAndPanesInTheWallPlaneTakeTheirClassNothingElseChanges) {
  using namespace labels;
  const Scene s = MakeScene();
  const WallPlaneResult walls = Planes(s);
  ASSERT_GE(walls.planes.size(), 4u);
  ASSERT_EQ(walls.extents.size(), walls.planes.size());
  // Every plane's normal points into the room (the room's centre is in front of it).
  for (const auto& p : walls.planes) EXPECT_GT(p.x() * 2.f + p.y() * 2.5f + p.w(), 1.5f);

  std::vector<int> label = s.label;
  const WallOpeningResult r =
      ApplyWallOpenings(s.points, &s.colours, walls, s.rows, WallOpeningConfig(), &label);
  const Tally t = Count(s, label);
  const auto& count = t.count;
  const auto& hit = t.hit;
  const std::size_t changed_elsewhere = t.changed_elsewhere;
  ASSERT_GT(count[1], 2000u);
  ASSERT_GT(count[2], 2000u);
  EXPECT_GT(hit[1], count[1] * 95 / 100) << hit[1] << " of " << count[1] << " door points";
  EXPECT_GT(hit[2], count[2] * 95 / 100) << hit[2] << " of " << count[2] << " pane points";
  EXPECT_EQ(changed_elsewhere, 0u);
  // The door and the pane are the two regions, with their extent.
  ASSERT_EQ(r.regions.size(), 2u);
  for (const auto& reg : r.regions) {
    if (reg.rfs_class == kDoor) {
      EXPECT_NEAR(reg.width, 0.9, 0.1);
      EXPECT_NEAR(reg.height, 2.0, 0.1);
      EXPECT_NEAR(reg.probability, 0.35, 0.03);  // border cells hold some wall points
    } else {
      EXPECT_EQ(reg.rfs_class, kWindow);
      EXPECT_NEAR(reg.width, 1.2, 0.1);
      EXPECT_NEAR(reg.z_min, 0.9, 0.06);
    }
  }
  EXPECT_EQ(r.relabelled, hit[1] + hit[2]);

  // Without colours the pane still counts by its recess; with the recess test off (a larger
  // threshold) and no colours it stays wall, and the door (strong probability) is found alone.
  std::vector<int> no_colour = s.label;
  EXPECT_EQ(ApplyWallOpenings(s.points, nullptr, walls, s.rows, WallOpeningConfig(), &no_colour)
                .regions.size(),
            2u);
  WallOpeningConfig deep;
  deep.recess = 0.2;
  std::vector<int> door_only = s.label;
  const WallOpeningResult d = ApplyWallOpenings(s.points, nullptr, walls, s.rows, deep, &door_only);
  ASSERT_EQ(d.regions.size(), 1u);
  EXPECT_EQ(d.regions[0].rfs_class, kDoor);
  // Deterministic.
  std::vector<int> again = s.label;
  ApplyWallOpenings(s.points, &s.colours, walls, s.rows, WallOpeningConfig(), &again);
  EXPECT_EQ(again, label);
}

TEST(WallOpenings, ShapeClassFromColourAndRecessAlone) {
  using namespace labels;
  const Scene s = MakeScene();
  const WallPlaneResult walls = Planes(s);
  // Evidence from colour contrast and recess only (the probability thresholds out of play),
  // the class by shape: A (from the foot, 2 m tall) door, B (sill 0.9 m) window; F (brown,
  // but 0.6 m tall at the foot) neither; C (wall-coloured, flush) not an opening.
  WallOpeningConfig shape;
  shape.seed_prob = 1, shape.weak_prob = 0, shape.contrast = 6, shape.shape_class = true;
  std::vector<int> label = s.label;
  const WallOpeningResult r = ApplyWallOpenings(s.points, &s.colours, walls, s.rows, shape, &label);
  ASSERT_EQ(r.regions.size(), 2u);
  const Tally t = Count(s, label);
  const auto& count = t.count;
  const auto& hit = t.hit;
  const std::size_t changed_elsewhere = t.changed_elsewhere;
  ASSERT_GT(count[6], 800u);  // F exists
  EXPECT_GT(hit[1], count[1] * 95 / 100) << hit[1] << " of " << count[1] << " door points";
  EXPECT_GT(hit[2], count[2] * 95 / 100) << hit[2] << " of " << count[2] << " pane points";
  // Border cells (5 cm) that straddle an opening's edge take their few wall points along.
  EXPECT_LT(changed_elsewhere, (count[1] + count[2]) / 25);
  // F is an opening by colour: a lower door height takes it for a door.
  shape.door_height = 0.5;
  std::vector<int> low = s.label;
  EXPECT_EQ(ApplyWallOpenings(s.points, &s.colours, walls, s.rows, shape, &low).regions.size(), 3u);
}

// Every point kept with probability `keep` (rows and all), e.g. a sparse scan.
Scene Thinned(const Scene& s, double keep) {
  Scene t;
  std::mt19937 rng(11);
  std::bernoulli_distribution take(keep);
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    if (!take(rng)) continue;
    t.points.push_back(s.points[i]);
    t.colours.push_back(s.colours[i]);
    t.label.push_back(s.label[i]);
    t.region.push_back(s.region[i]);
    const float* row = s.rows.SemanticProb(i);
    t.rows.semantic_prob.insert(t.rows.semantic_prob.end(), row, row + labels::kNumRfsClasses);
  }
  return t;
}

TEST(WallOpenings, SparseCloudsUseCoarserCells) {
  // 12 % of the 2 cm grid (as sparse as 4.5 cm voxel means on a wall that is not axis-aligned):
  // ~0.75 points per 5 cm cell, 45 % of the cells empty - a 5-cell opening would erode every
  // region away; the raster falls back to 10 cm cells and finds both.
  const Scene s = Thinned(MakeScene(), 0.12);
  WallOpeningConfig shape;
  shape.seed_prob = 1, shape.weak_prob = 0, shape.contrast = 6, shape.shape_class = true;
  std::vector<int> label = s.label;
  const WallOpeningResult r =
      ApplyWallOpenings(s.points, &s.colours, Planes(s), s.rows, shape, &label);
  ASSERT_EQ(r.regions.size(), 2u);
  const Tally t = Count(s, label);
  EXPECT_GT(t.hit[1], t.count[1] * 9 / 10) << t.hit[1] << " of " << t.count[1];
  EXPECT_GT(t.hit[2], t.count[2] * 9 / 10) << t.hit[2] << " of " << t.count[2];
  EXPECT_LT(t.changed_elsewhere, (t.count[1] + t.count[2]) / 10);
}

TEST(WallOpenings, BadInputIsRefusedByName) {
  const Scene s = MakeScene();
  const WallPlaneResult walls = Planes(s);
  std::vector<int> label = s.label;
  auto expect_message = [](const std::function<void()>& f, const std::string& part) {
    try {
      f();
      ADD_FAILURE() << "no error, expected one naming " << part;
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  std::vector<int> short_labels(10, 0);
  expect_message([&] { ApplyWallOpenings(s.points, &s.colours, walls, s.rows, {}, &short_labels); },
                 "labels");
  std::vector<V> few_colours(3);
  expect_message([&] { ApplyWallOpenings(s.points, &few_colours, walls, s.rows, {}, &label); },
                 "colours");
  nn::Stage1PointRows rows = s.rows;
  rows.semantic_prob.resize(rows.semantic_prob.size() / 2);
  expect_message([&] { ApplyWallOpenings(s.points, &s.colours, walls, rows, {}, &label); },
                 "semantic_prob has");
  WallOpeningConfig bad;
  bad.cell = 0;
  expect_message([&] { ApplyWallOpenings(s.points, &s.colours, walls, s.rows, bad, &label); },
                 "cell must be");
  // No planes: nothing changes.
  EXPECT_TRUE(ApplyWallOpenings(s.points, &s.colours, WallPlaneResult(), s.rows, {}, &label)
                  .regions.empty());
  EXPECT_EQ(label, s.label);
}

}  // namespace
}  // namespace dimr::pipeline
