// Hard examples of stage 1 (issue 22): non-wall points flat in a wall's plane (InWallPlanePoints,
// SetInWallPlaneWeights), carried by MixInstances and MakeStage1Batch, and the per-point weighted
// semantic loss they feed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "dimr/core/error.h"
#include "dimr/nn/stage1_data.h"
#include "dimr/nn/stage1_model.h"

namespace dimr::nn {
namespace {

constexpr int kWall = 0, kFloor = 1, kChair = 4, kDoor = 7, kBookshelf = 9, kPicture = 10,
              kCurtain = 13;

// A room with a wall in the plane x = 0 (y in [0, 4], z in [0, 2.5], instance 1) and an
// L-shaped wall instance (2) along y = 6 and x = 6, plus objects:
//   3 a closed door in the x = 0 wall (x = 0, flat),       -> in the plane
//   4 a curtain 5 cm in front of it (x = 0.05, flat),      -> in the plane
//   5 a poster 15 cm in front of it (x = 0.15),            -> too far
//   6 a bookshelf pushed against it (box x in [0, 0.35]),  -> only its edges near the wall
//   7 a chair in the middle of the room,                   -> no
//   8 a door flat in the L-shaped (non-planar) wall,       -> no plane there
// and floor points (instance 0) that reach the wall.
struct Room {
  Stage1Sample sample;
  std::vector<int> object;  // per point: the instance index above
};

Room MakeRoom() {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  Room r;
  Stage1Sample& s = r.sample;
  s.name = "wall-plane room";
  const int classes[] = {kFloor,   kWall,      kWall,  kDoor, kCurtain,
                         kPicture, kBookshelf, kChair, kDoor};
  for (int c : classes) s.instances.push_back({c, -1, false, 0.0});
  auto add = [&](const Eigen::Vector3f& p, int inst) {
    s.points.push_back(p);
    s.colors.emplace_back(0.5f, 0.5f, 0.5f);
    s.semantic.push_back(s.instances[inst].semantic);
    s.instance.push_back(inst);
  };
  for (int i = 0; i < 2000; ++i) add({6 * u(rng), 6 * u(rng), 0.f}, 0);
  // Wall x = 0 (with 1 cm of scan noise), leaving the door's hole.
  for (int i = 0; i < 3000; ++i) {
    const float y = 4 * u(rng), z = 2.5f * u(rng);
    if (y > 1.0f && y < 1.9f && z < 2.0f) continue;
    add({0.01f * (u(rng) - 0.5f), y, z}, 1);
  }
  for (int i = 0; i < 1500; ++i) add({6 * u(rng), 6.f, 2.5f * u(rng)}, 2);  // L: y = 6 and x = 6
  for (int i = 0; i < 1500; ++i) add({6.f, 6 * u(rng), 2.5f * u(rng)}, 2);
  for (int i = 0; i < 400; ++i) add({0.f, 1.0f + 0.9f * u(rng), 2.0f * u(rng)}, 3);
  for (int i = 0; i < 300; ++i) add({0.05f, 2.2f + 0.8f * u(rng), 0.3f + 2.0f * u(rng)}, 4);
  for (int i = 0; i < 100; ++i) add({0.15f, 3.2f + 0.5f * u(rng), 1.2f + 0.6f * u(rng)}, 5);
  // Bookshelf: front face x = 0.35 and two side panels from the wall out.
  for (int i = 0; i < 300; ++i) {
    const float y = 0.1f + 0.8f * u(rng), z = 1.8f * u(rng);
    if (i % 3 == 0) {
      add({0.35f * u(rng), i % 2 ? 0.1f : 0.9f, z}, 6);
    } else {
      add({0.35f, y, z}, 6);
    }
  }
  for (int i = 0; i < 300; ++i) add({3 + 0.5f * u(rng), 3 + 0.5f * u(rng), 0.9f * u(rng)}, 7);
  for (int i = 0; i < 200; ++i) add({2 + 0.9f * u(rng), 6.f, 2.0f * u(rng)}, 8);
  r.object = s.instance;
  return r;
}

TEST(Stage1WallPlane, FindsFlatObjectsInAPlanarWallOnly) {
  const Room room = MakeRoom();
  const std::vector<std::uint8_t> in = InWallPlanePoints(room.sample);
  ASSERT_EQ(in.size(), room.sample.points.size());
  std::vector<int> count(9, 0), total(9, 0);
  for (std::size_t i = 0; i < in.size(); ++i) {
    ++total[room.object[i]];
    count[room.object[i]] += in[i];
  }
  EXPECT_EQ(count[3], total[3]);  // the door in the wall
  EXPECT_EQ(count[4], total[4]);  // the curtain 5 cm in front of it
  EXPECT_EQ(count[0], 0);         // floor is never a hard example
  EXPECT_EQ(count[1], 0);         // nor the walls themselves
  EXPECT_EQ(count[2], 0);
  EXPECT_EQ(count[5], 0);  // the poster is 15 cm out
  EXPECT_EQ(count[6], 0);  // the bookshelf is not flat in the wall
  EXPECT_EQ(count[7], 0);  // the chair is far away
  EXPECT_EQ(count[8], 0);  // the L-shaped wall defines no plane

  // Without the flat-object rule the bookshelf's side panels near the wall count.
  InWallPlaneConfig any;
  any.min_instance_share = 0;
  const std::vector<std::uint8_t> loose = InWallPlanePoints(room.sample, any);
  int shelf = 0;
  for (std::size_t i = 0; i < loose.size(); ++i) shelf += room.object[i] == 6 && loose[i];
  EXPECT_GT(shelf, 5);
  EXPECT_LT(shelf, total[6] / 2);
  // A wider band takes the poster; a stricter wall thickness rejects the noisy wall.
  InWallPlaneConfig wide;
  wide.distance = 0.2;
  const std::vector<std::uint8_t> w = InWallPlanePoints(room.sample, wide);
  int poster = 0;
  for (std::size_t i = 0; i < w.size(); ++i) poster += room.object[i] == 5 && w[i];
  EXPECT_EQ(poster, total[5]);
  InWallPlaneConfig thin;
  thin.max_thickness = 0.001;
  const std::vector<std::uint8_t> none = InWallPlanePoints(room.sample, thin);
  EXPECT_EQ(std::count(none.begin(), none.end(), 1), 0);

  InWallPlaneConfig bad;
  bad.min_instance_share = 1.5;
  EXPECT_THROW(InWallPlanePoints(room.sample, bad), InvalidArgument);
  bad = InWallPlaneConfig();
  bad.distance = 0;
  EXPECT_THROW(InWallPlanePoints(room.sample, bad), InvalidArgument);
}

TEST(Stage1WallPlane, WallContextIsTheWallAroundTheFlatObjects) {
  const Room room = MakeRoom();
  const Stage1Sample& s = room.sample;
  InWallPlaneConfig config;
  config.wall_context = 0.3;
  const std::vector<std::uint8_t> in = InWallPlanePoints(s, config);
  const std::vector<std::uint8_t> plain = InWallPlanePoints(s);
  ASSERT_EQ(in.size(), s.points.size());
  // In-plane distance (y, z) of each x = 0 wall point to the nearest door / curtain point.
  int near_marked = 0, near_total = 0, far_marked = 0, far_total = 0;
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    const int obj = room.object[i];
    if (obj != 1) {
      // Objects keep their marks; no other point becomes context.
      EXPECT_EQ(in[i], plain[i]) << "point " << i << " of object " << obj;
      continue;
    }
    EXPECT_NE(in[i], 1) << "wall point " << i;
    double best = INFINITY;
    for (std::size_t j = 0; j < s.points.size(); ++j) {
      if (room.object[j] != 3 && room.object[j] != 4) continue;
      best = std::min(best, std::hypot(static_cast<double>(s.points[i].y() - s.points[j].y()),
                                       static_cast<double>(s.points[i].z() - s.points[j].z())));
    }
    // The 5 cm grid makes the reach exact to within a cell diagonal (7.1 cm).
    if (best <= 0.3 - 0.075) {
      ++near_total;
      near_marked += in[i] == 2;
    } else if (best > 0.3 + 0.075) {
      ++far_total;
      far_marked += in[i] == 2;
    }
  }
  ASSERT_GT(near_total, 300);
  ASSERT_GT(far_total, 300);
  EXPECT_EQ(near_marked, near_total);
  EXPECT_EQ(far_marked, 0);
  // The weights cover both: 700 object points and the context.
  Stage1Sample w = s;
  const std::size_t context = static_cast<std::size_t>(std::count(in.begin(), in.end(), 2));
  EXPECT_EQ(SetInWallPlaneWeights(&w, 2.0f, config), 700u + context);
  for (std::size_t i = 0; i < in.size(); ++i) ASSERT_EQ(w.weight[i], in[i] ? 2.0f : 1.0f);
  config.wall_context = -1;
  EXPECT_THROW(InWallPlanePoints(s, config), InvalidArgument);
  config.wall_context = NAN;
  EXPECT_THROW(InWallPlanePoints(s, config), InvalidArgument);
}

TEST(Stage1WallPlane, WeightsReachTheBatchAndSurviveInstanceMixing) {
  Room room = MakeRoom();
  Stage1Sample& s = room.sample;
  const std::size_t n = s.points.size();
  EXPECT_EQ(SetInWallPlaneWeights(&s, 4.0f), 700u);  // door 400 + curtain 300
  ASSERT_EQ(s.weight.size(), n);
  for (std::size_t i = 0; i < n; ++i) {
    const bool hard = room.object[i] == 3 || room.object[i] == 4;
    ASSERT_EQ(s.weight[i], hard ? 4.0f : 1.0f) << i;
  }
  EXPECT_THROW(SetInWallPlaneWeights(&s, 0.0f), InvalidArgument);
  EXPECT_THROW(SetInWallPlaneWeights(&s, NAN), InvalidArgument);
  // A bad weight vector is rejected by validation, naming the field.
  Stage1Sample broken = s;
  broken.weight[5] = -1.0f;
  try {
    broken.Validate();
    FAIL() << "negative weight accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("weight[5]"), std::string::npos) << e.what();
  }
  broken.weight.resize(3);
  EXPECT_THROW(broken.Validate(), InvalidArgument);

  // The batch carries the weights in point order (no augmentation); an unweighted sample in the
  // same batch gets 1; a batch without weighted samples has none.
  Stage1Sample plain = MakeRoom().sample;
  Stage1InputConfig input;
  input.use_rgb = true;
  const Stage1Batch batch = MakeStage1Batch({&s, &plain}, input, nullptr, 0);
  ASSERT_EQ(batch.semantic_weight.size(), static_cast<std::size_t>(batch.num_points()));
  for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(batch.semantic_weight[i], s.weight[i]) << i;
  for (std::size_t i = n; i < batch.semantic_weight.size(); ++i)
    ASSERT_EQ(batch.semantic_weight[i], 1.0f) << i;
  EXPECT_TRUE(MakeStage1Batch({&plain}, input, nullptr, 0).semantic_weight.empty());

  // Instance mixing appends points with weight 1.
  Stage1Sample src = MakeRoom().sample;
  src.instances[7].cad_class = 1;  // the chair becomes a CAD instance to paste
  std::mt19937_64 rng(9);
  const Stage1Sample mixed = MixInstances(s, src, 1, &rng);
  ASSERT_EQ(mixed.points.size(), n + 300);
  ASSERT_EQ(mixed.weight.size(), mixed.points.size());
  EXPECT_TRUE(std::equal(s.weight.begin(), s.weight.end(), mixed.weight.begin()));
  for (std::size_t i = n; i < mixed.weight.size(); ++i) EXPECT_EQ(mixed.weight[i], 1.0f);
  mixed.Validate();

  // Weight 1 clears the weights (the unweighted loss, bit for bit).
  EXPECT_EQ(SetInWallPlaneWeights(&s, 1.0f), 700u);
  EXPECT_TRUE(s.weight.empty());
}

// The weighted semantic loss is sum_i w_i ce_i / sum_i w_i: recomputed from Predict's
// per-point probabilities. A loss that ignored the weights, or normalised by the point count,
// misses it by far more than the tolerance (the weighted points are the badly predicted ones).
TEST(Stage1WallPlane, WeightedLossIsTheWeightedMeanOfThePointLosses) {
  Room room = MakeRoom();
  Stage1Sample& s = room.sample;
  Stage1Config config;
  config.input.scale = 10;
  config.input.use_rgb = true;
  config.widths = {8, 16, 24};
  config.reps = 1;
  Stage1Model model(config, 5);
  Stage1TrainOptions opt;
  opt.epochs = 3;
  opt.batch_size = 1;
  opt.augment.enabled = false;
  opt.progress = false;
  opt.threads = 1;
  model.Train({s}, opt);
  const Stage1Batch plain = MakeStage1Batch({&s}, config.input, nullptr, 0);
  const Stage1LossTerms unweighted = model.EvaluateLoss(plain);
  SetInWallPlaneWeights(&s, 10.0f);
  const Stage1Batch batch = MakeStage1Batch({&s}, config.input, nullptr, 0);
  const Stage1LossTerms weighted = model.EvaluateLoss(batch);
  const Stage1Output out = model.Predict(s);
  double sum = 0, wsum = 0, plain_sum = 0;
  int labelled = 0;
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    if (s.semantic[i] == kStage1Ignore) continue;
    const double ce = -std::log(out.SemanticProb(i)[s.semantic[i]]);
    sum += s.weight[i] * ce;
    wsum += s.weight[i];
    plain_sum += ce;
    ++labelled;
  }
  EXPECT_NEAR(weighted.semantic, sum / wsum, 1e-4 * std::max(1.0, sum / wsum));
  EXPECT_NEAR(unweighted.semantic, plain_sum / labelled, 1e-4 * std::max(1.0, unweighted.semantic));
  EXPECT_GT(std::abs(weighted.semantic - unweighted.semantic), 1e-2);
  // The other terms do not depend on the weights.
  EXPECT_NEAR(weighted.offset_norm, unweighted.offset_norm, 1e-6);
  EXPECT_NEAR(weighted.heading_cls, unweighted.heading_cls, 1e-6);
  // Uniform weights give the unweighted loss.
  std::fill(s.weight.begin(), s.weight.end(), 3.0f);
  const Stage1Batch uniform = MakeStage1Batch({&s}, config.input, nullptr, 0);
  EXPECT_NEAR(model.EvaluateLoss(uniform).semantic, unweighted.semantic, 1e-5);
}

}  // namespace
}  // namespace dimr::nn
