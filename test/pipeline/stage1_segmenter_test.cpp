// Stage-1 segmenter (pipeline/stage1_segmenter.h): the inference config's text form and its
// strict parsing, presets from a model card, the whole chain on the shipped model (bias, vote,
// clustering, timings), the calibration search, and bad clouds (flat room, one point, a plane,
// NaN, millimetres, no colours, empty) giving a result or a clear error.
#include "dimr/pipeline/stage1_segmenter.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "dimr/geometry/error.h"
#include "dimr/pipeline/calibration.h"
#include "dimr/pipeline/model_card.h"

namespace dimr::pipeline {
namespace {

const char* kModel = "models/stage1/stage1.pt";

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Stage1InferenceConfig, TextRoundTripAndStrictValues) {
  Stage1InferenceConfig c;
  EXPECT_EQ(c.ToString(), "rotations=1 mirror=0 vote_radius=0 vote_min_points=20");
  c = Stage1InferenceConfig::FromString(
      "passes=s0.12,s0.2,o0.03 rotations=6 mirror=1 vote_radius=0.08 vote_min_points=5 "
      "vote_exclude=picture,window nms=0.25");
  EXPECT_EQ(c.rotations, 6);
  EXPECT_TRUE(c.mirror);
  EXPECT_EQ(c.network_passes(), 12);
  ASSERT_EQ(c.passes.size(), 3u);
  EXPECT_TRUE(c.passes[0].shifted);
  EXPECT_DOUBLE_EQ(c.passes[1].radius, 0.2);
  EXPECT_FALSE(c.passes[2].shifted);
  EXPECT_EQ(c.vote_exclude, (std::vector<int>{8, 10}));  // sorted ids of window, picture
  EXPECT_DOUBLE_EQ(c.nms_iou, 0.25);
  EXPECT_EQ(c.ToString(),
            "passes=s0.12,s0.2,o0.03 rotations=6 mirror=1 vote_radius=0.08 vote_min_points=5 "
            "vote_exclude=window,picture nms=0.25");
  EXPECT_EQ(Stage1InferenceConfig::FromString(c.ToString()).ToString(), c.ToString());
  // The wall-openings keys (only those off their defaults are written).
  const std::string openings =
      "wall_openings=1 wall_opening_prob=1 wall_opening_weak=0 wall_opening_contrast=6 "
      "wall_opening_shape=1";
  c = Stage1InferenceConfig::FromString(openings);
  EXPECT_TRUE(c.wall_openings && c.wall_opening_shape);
  EXPECT_DOUBLE_EQ(c.wall_opening_weak, 0.0);
  EXPECT_DOUBLE_EQ(c.wall_opening_contrast, 6.0);
  EXPECT_NE(c.ToString().find(openings), std::string::npos) << c.ToString();
  EXPECT_EQ(Stage1InferenceConfig::FromString(c.ToString()).ToString(), c.ToString());
  // vote_max_extent: written when set, reaches the vote's config.
  c = Stage1InferenceConfig::FromString("vote_radius=0.065 vote_max_extent=3");
  EXPECT_DOUBLE_EQ(c.InstanceConfig().semantic_vote.max_extent, 3.0);
  EXPECT_NE(c.ToString().find("vote_max_extent=3"), std::string::npos) << c.ToString();
  EXPECT_EQ(Stage1InferenceConfig().ToString().find("vote_max_extent"), std::string::npos);
  std::string bias = "class_bias=";
  for (int k = 0; k < 25; ++k) bias += (k ? "," : "") + std::to_string(k % 3 - 1);
  EXPECT_FLOAT_EQ(Stage1InferenceConfig::FromString(bias).class_bias[2], 1.0f);

  // Every bad value names its key and value; nothing is half-read ("6x" is not 6).
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"rotations=6x", "'rotations=6x'"},
      {"rotations=5", "must divide 12"},
      {"mirror=2", "'mirror=2'"},
      {"vote_radius=-1", "'vote_radius=-1'"},
      {"vote_radius=nan", "'vote_radius=nan'"},
      {"vote_max_extent=-2", "'vote_max_extent=-2'"},
      {"passes=s0.1,x0.2", "x0.2"},
      {"passes=", "'passes='"},
      {"class_bias=0.1,0.2", "2 values, expected 25"},
      {"vote_exclude=sofa2", "'sofa2' is not an RFS class name"},
      {"scene_norm=1.5", "'scene_norm=1.5'"},
      {"wall_opening_prob=0", "'wall_opening_prob=0'"},
      {"wall_opening_contrast=-1", "'wall_opening_contrast=-1'"},
      {"vote_min_extent=sofa", "not CLASS:VALUE"},
      {"vote_min_extent=sofas:0.8", "'sofas' is not an RFS class name"},
      {"vote_min_extent=sofa:-1", "finite number >= 0"},
      {"vote_min_extent=sofa:0.8m", "finite number >= 0"},
      {"spin=3", "'spin=3': unknown key"},
      {"rotations", "not key=value"}};
  for (const auto& [text, expect] : bad) {
    const std::string e = ErrorOf([&] { Stage1InferenceConfig::FromString(text); });
    EXPECT_NE(e.find(expect), std::string::npos) << text << " -> " << e;
    EXPECT_NE(e.find("stage1 inference"), std::string::npos) << e;
  }
  // Size plausibility: CLASS:metres per class, 25 values, round trip, into the vote config.
  c = Stage1InferenceConfig::FromString("vote_radius=0.065 vote_min_extent=bathtub:0.95,sofa:0.8");
  ASSERT_EQ(c.vote_min_extent.size(), 25u);
  EXPECT_DOUBLE_EQ(c.vote_min_extent[5], 0.8);    // sofa
  EXPECT_DOUBLE_EQ(c.vote_min_extent[18], 0.95);  // bathtub
  EXPECT_DOUBLE_EQ(c.vote_min_extent[4], 0.0);    // chair: no limit
  EXPECT_NE(c.ToString().find("vote_min_extent=sofa:0.8,bathtub:0.95"), std::string::npos)
      << c.ToString();
  EXPECT_EQ(c.InstanceConfig().semantic_vote.min_extent, c.vote_min_extent);
  EXPECT_TRUE(Stage1InferenceConfig::FromString("vote_min_extent=none").vote_min_extent.empty());
  c = Stage1InferenceConfig::FromString("rotations=2 scene_norm=0.5");
  EXPECT_DOUBLE_EQ(c.scene_norm, 0.5);
  EXPECT_NE(c.ToString().find("scene_norm=0.5"), std::string::npos) << c.ToString();
  EXPECT_EQ(Stage1InferenceConfig::FromString("rotations=2").ToString().find("scene_norm"),
            std::string::npos);  // 0 (off) is not written
  Stage1InferenceConfig v;
  v.min_points = -1;
  EXPECT_NE(ErrorOf([&] { v.Validate(); }).find("min_points = -1"), std::string::npos);
}

TEST(Stage1InferenceConfig, PresetsFromTheModelCard) {
  const ModelCard card = ModelCard::Parse(
      "name: stage1\nrecommended_inference: \"passes=s0.12,s0.2 rotations=6 mirror=1 "
      "vote_radius=0.08\"  # chosen on validation\n",
      "card.yaml");
  const auto accurate = Stage1InferenceConfig::FromModelCard(card, Stage1Preset::kAccurate);
  EXPECT_EQ(accurate.network_passes(), 12);
  EXPECT_DOUBLE_EQ(accurate.vote_radius, 0.08);
  const auto fast = Stage1InferenceConfig::FromModelCard(card, Stage1Preset::kFast);
  EXPECT_EQ(fast.network_passes(), 1);
  EXPECT_DOUBLE_EQ(fast.vote_radius, 0.08);  // the cheap parts stay
  EXPECT_EQ(fast.passes.size(), 2u);
  EXPECT_EQ(Stage1PresetNames().Parse("fast"), Stage1Preset::kFast);
  EXPECT_NE(ErrorOf([] { Stage1PresetNames().Parse("quick"); }).find("fast, accurate"),
            std::string::npos);
  // A YAML mapping of the same keys overrides single values of the line.
  const ModelCard mapped = ModelCard::Parse(
      "recommended_inference: \"rotations=6 mirror=1 vote_radius=0.08\"\n"
      "stage1_inference:\n  rotations: 3\n  vote_exclude: picture\n",
      "mapped.yaml");
  const auto m = Stage1InferenceConfig::FromModelCard(mapped);
  EXPECT_EQ(m.rotations, 3);
  EXPECT_TRUE(m.mirror);
  EXPECT_EQ(m.vote_exclude, (std::vector<int>{10}));
  const ModelCard bad_map =
      ModelCard::Parse("stage1_inference:\n  rotations: 4x\n", "bad_map.yaml");
  try {
    Stage1InferenceConfig::FromModelCard(bad_map);
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("bad_map.yaml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("stage1_inference.rotations"), std::string::npos)
        << e.what();
  }
  // No recommendation: the defaults.
  EXPECT_EQ(
      Stage1InferenceConfig::FromModelCard(ModelCard::Parse("name: x\n", "c.yaml")).ToString(),
      Stage1InferenceConfig().ToString());
  const ModelCard broken =
      ModelCard::Parse("recommended_inference: \"rotations=2 spin=3\"\n", "broken.yaml");
  try {
    Stage1InferenceConfig::FromModelCard(broken);
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("broken.yaml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("spin=3"), std::string::npos) << e.what();
  }
}

// A room: floor, walls, and a box-shaped object; colours grey-ish.
PointCloudInput Room(float sx, float sy, float height, int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  PointCloudInput in;
  in.name = "room" + std::to_string(seed);
  for (int i = 0; i < n; ++i) {
    const float r = u(rng);
    Eigen::Vector3f p;
    if (r < 0.45f) {
      p = {sx * u(rng), sy * u(rng), 0.0f};
    } else if (r < 0.85f) {
      const bool along_x = u(rng) < 0.5f;
      const float side = u(rng) < 0.5f ? 0.0f : 1.0f;
      p = {along_x ? sx * u(rng) : sx * side, along_x ? sy * side : sy * u(rng), height * u(rng)};
    } else {
      p = {1.0f + 0.6f * u(rng), 1.0f + 0.6f * u(rng), 0.45f};
      p[static_cast<int>(u(rng) * 2.99f)] = u(rng) < 0.5f ? 1.0f : 1.6f;
      p.z() = std::min(p.z(), 0.45f);
    }
    in.points.push_back(p);
    in.colors.emplace_back(0.5f + 0.1f * u(rng), 0.45f, 0.4f);
  }
  return in;
}

TEST(Stage1Segmenter, RunsTheWholeChainWithBiasVoteAndTimings) {
  Stage1InferenceConfig cfg;
  const Stage1Segmenter seg = Stage1Segmenter::Load(kModel, cfg);
  EXPECT_TRUE(seg.uses_color());
  const PointCloudInput room = Room(4.0f, 3.0f, 2.5f, 8000, 1);
  const Stage1Result r = seg.Segment(room, /*with_features=*/true);
  const std::size_t n = room.size();
  ASSERT_EQ(r.semantic.size(), n);
  ASSERT_EQ(r.cad_label.size(), n);
  // One pass: probability rows per voxel, point_row maps the points to them.
  ASSERT_EQ(r.point_row.size(), n);
  EXPECT_LT(r.NumRows(), n);
  EXPECT_NO_THROW(r.CheckShape("r", n));
  EXPECT_EQ(r.feature_dim, seg.feature_dim());
  EXPECT_EQ(r.features.size(), n * static_cast<std::size_t>(seg.feature_dim()));
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_EQ(r.cad_label[i], Stage1RfsToCad()[r.semantic[i]]);
  }
  for (const char* stage : {"network", "unet", "class_bias", "vote", "clustering", "total"}) {
    EXPECT_TRUE(r.timings.has(stage)) << stage;
  }
  EXPECT_GE(r.timings.ms("total"), r.timings.ms("network"));
  // Most floor points (z = 0, 45 % of the room) come out as floor.
  int floor_points = 0, floor_right = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (room.points[i].z() == 0.0f && (room.points[i].x() < 0.9f || room.points[i].x() > 1.7f)) {
      ++floor_points;
      floor_right += r.semantic[i] == 1;
    }
  }
  EXPECT_GT(floor_right, 0.8 * floor_points);

  // A strong bias towards chair makes every point a chair, and clustering finds chairs.
  cfg.class_bias.assign(25, 0.0f);
  cfg.class_bias[4] = 40.0f;
  cfg.min_points = 50;
  const Stage1Segmenter chairs = Stage1Segmenter::Load(kModel, cfg);
  const Stage1Result c = chairs.Segment(room);
  for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(c.semantic[i], 4);
  ASSERT_FALSE(c.instances.empty());
  std::set<int> seen;
  for (const auto& inst : c.instances) {
    EXPECT_EQ(inst.cad_class, 1);
    EXPECT_GT(static_cast<int>(inst.points.size()), 50);
    for (int i : inst.points) {
      ASSERT_GE(i, 0);
      ASSERT_LT(i, static_cast<int>(n));
    }
    EXPECT_GE(inst.score, 0.0);
    EXPECT_LE(inst.score, 1.0 + 1e-6);
  }
  // Segment is RunNetwork + Finish.
  Stage1Result split = chairs.RunNetwork(room);
  Stage1Segmenter::Finish(room.points, chairs.config(), &split);
  EXPECT_EQ(split.semantic, c.semantic);
  ASSERT_EQ(split.instances.size(), c.instances.size());
  for (std::size_t k = 0; k < c.instances.size(); ++k) {
    EXPECT_EQ(split.instances[k].points, c.instances[k].points);
  }
  // FinishLabels is Finish without the clustering (labels, no instances), and the proposals of
  // every pass (ScoredStage1Proposals, what `dimr stage2 prepare` samples) hold each instance
  // with its score and heading, bit for bit.
  Stage1Result labels = chairs.RunNetwork(room);
  Stage1Segmenter::FinishLabels(room.points, chairs.config(), &labels);
  EXPECT_EQ(labels.semantic, c.semantic);
  EXPECT_EQ(labels.cad_label, c.cad_label);
  EXPECT_TRUE(labels.instances.empty());
  EXPECT_FALSE(labels.timings.has("clustering"));
  const std::vector<ScoredInstance> proposals =
      ScoredStage1Proposals(room.points, labels.offsets, labels.cad_label, labels.semantic_prob,
                            labels.heading_prob, labels.heading_residual, Stage1RfsToCad(),
                            chairs.config().InstanceConfig().clustering, labels.point_row);
  ASSERT_GE(proposals.size(), c.instances.size());
  for (const auto& inst : c.instances) {
    int found = 0;
    for (const auto& p : proposals) {
      if (p.points == inst.points && p.cad_class == inst.cad_class) {
        ++found;
        EXPECT_EQ(p.score, inst.score);
        EXPECT_EQ(p.heading, inst.heading);
      }
    }
    EXPECT_GE(found, 1);
  }
  // Bias, vote, scores and headings read the per-voxel rows (one pass) or the per-point rows
  // in voxel order (test-time augmentation) as the same rows spread to every point would give
  // them (a wrong point -> row lookup changes labels, scores or headings).
  Stage1InferenceConfig tta_cfg = cfg;
  tta_cfg.rotations = 2;
  tta_cfg.mirror = true;
  const Stage1Segmenter tta = Stage1Segmenter::Load(kModel, tta_cfg);
  for (const Stage1Segmenter* s : {&seg, &chairs, &tta}) {
    Stage1Result voxel_rows = s->RunNetwork(room);
    Stage1Result point_rows = voxel_rows;
    point_rows.ExpandToPoints(n);
    ASSERT_TRUE(point_rows.point_row.empty());
    Stage1Segmenter::Finish(room.points, s->config(), &voxel_rows);
    Stage1Segmenter::Finish(room.points, s->config(), &point_rows);
    EXPECT_EQ(voxel_rows.semantic, point_rows.semantic);
    ASSERT_EQ(voxel_rows.instances.size(), point_rows.instances.size());
    for (std::size_t k = 0; k < voxel_rows.instances.size(); ++k) {
      EXPECT_EQ(voxel_rows.instances[k].points, point_rows.instances[k].points);
      EXPECT_EQ(voxel_rows.instances[k].score, point_rows.instances[k].score);
      EXPECT_EQ(voxel_rows.instances[k].heading, point_rows.instances[k].heading);
    }
    for (std::size_t i = 0; i < n; i += 53) {
      ASSERT_EQ(voxel_rows.SemanticProb(i)[4], point_rows.SemanticProb(i)[4]);  // biased alike
    }
  }
  // A map that does not fit the points is refused, naming it.
  Stage1Result bad = chairs.RunNetwork(room);
  bad.point_row.pop_back();
  EXPECT_THROW(Stage1Segmenter::Finish(room.points, chairs.config(), &bad), InvalidArgument);
  bad = chairs.RunNetwork(room);
  bad.point_row[7] = static_cast<std::int64_t>(bad.NumRows());
  try {
    Stage1Segmenter::Finish(room.points, chairs.config(), &bad);
    ADD_FAILURE() << "no throw";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("point_row[7]"), std::string::npos) << e.what();
  }
}

TEST(Stage1Segmenter, TestTimeAugmentationAveragesThePasses) {
  Stage1InferenceConfig cfg;
  const PointCloudInput room = Room(3.5f, 3.0f, 2.4f, 3000, 2);
  const Stage1Result one = Stage1Segmenter::Load(kModel, cfg).Segment(room);
  cfg.rotations = 2;
  cfg.mirror = true;
  const Stage1Result four = Stage1Segmenter::Load(kModel, cfg).Segment(room);
  double diff = 0, row = 0;
  // Each point its own mean: one row per point, in the plain pass's voxel order.
  ASSERT_EQ(four.point_row.size(), room.size());
  ASSERT_EQ(four.semantic_prob.size(), room.size() * 25);
  for (std::size_t i = 0; i < room.size(); ++i) {
    for (int k = 0; k < 25; ++k) {
      diff = std::max<double>(diff, std::abs(one.SemanticProb(i)[k] - four.SemanticProb(i)[k]));
    }
  }
  for (int k = 0; k < 25; ++k) row += four.semantic_prob[k];
  EXPECT_GT(diff, 1e-4);  // the passes differ, so the average is not the plain pass
  EXPECT_NEAR(row, 1.0, 1e-4);
}

// scene_norm reaches the network: the blend moves the probabilities, 0 gives the plain
// numbers again, and the shipped model's own training statistics are not altered by a run.
TEST(Stage1Segmenter, SceneNormalisationAdaptsThePassesToTheScene) {
  Stage1InferenceConfig cfg;
  const PointCloudInput room = Room(3.5f, 3.0f, 2.4f, 3000, 2);
  const Stage1Segmenter seg = Stage1Segmenter::Load(kModel, cfg);
  const Stage1Result plain = seg.Segment(room);
  Stage1InferenceConfig adapted_cfg = cfg;
  adapted_cfg.scene_norm = 1.0;
  Stage1Segmenter adapted = Stage1Segmenter::Load(kModel, adapted_cfg);
  const Stage1Result full = adapted.Segment(room);
  adapted_cfg.scene_norm = 0.3;
  adapted.set_config(adapted_cfg);
  const Stage1Result part = adapted.Segment(room);
  adapted_cfg.scene_norm = 0.0;
  adapted.set_config(adapted_cfg);
  const Stage1Result again = adapted.Segment(room);
  ASSERT_EQ(plain.semantic_prob.size(), full.semantic_prob.size());
  double d_full = 0, d_part = 0, d_again = 0;
  for (std::size_t k = 0; k < plain.semantic_prob.size(); ++k) {
    d_full = std::max<double>(d_full, std::abs(plain.semantic_prob[k] - full.semantic_prob[k]));
    d_part = std::max<double>(d_part, std::abs(plain.semantic_prob[k] - part.semantic_prob[k]));
    d_again = std::max<double>(d_again, std::abs(plain.semantic_prob[k] - again.semantic_prob[k]));
  }
  EXPECT_GT(d_full, 1e-3);
  EXPECT_GT(d_part, 1e-4);
  EXPECT_LT(d_part, d_full);
  EXPECT_EQ(d_again, 0.0);
}

TEST(Stage1Segmenter, BadCloudsGiveAResultOrAClearError) {
  const Stage1Segmenter seg = Stage1Segmenter::Load(kModel, Stage1InferenceConfig());
  // A ScanNet-like room whose points reach only 1.37 m (28 voxels at 5 cm, fewer than the 32
  // that five down-samplings need): it used to throw "cannot downsample spatial shape".
  const Stage1Result low = seg.Segment(Room(3.4f, 2.6f, 1.37f, 5000, 3));
  EXPECT_EQ(low.semantic.size(), 5000u);
  // No floor visible: walls and an object only.
  PointCloudInput no_floor = Room(3.4f, 2.6f, 2.5f, 4000, 4);
  PointCloudInput walls;
  for (std::size_t i = 0; i < no_floor.size(); ++i) {
    if (no_floor.points[i].z() > 0.3f) {
      walls.points.push_back(no_floor.points[i]);
      walls.colors.push_back(no_floor.colors[i]);
    }
  }
  EXPECT_EQ(seg.Segment(walls).semantic.size(), walls.size());
  // One point, a plane: valid, with no instances.
  PointCloudInput one;
  one.points = {{0.3f, 0.2f, 0.1f}};
  one.colors = {{0.5f, 0.5f, 0.5f}};
  const Stage1Result r1 = seg.Segment(one);
  EXPECT_EQ(r1.semantic.size(), 1u);
  EXPECT_TRUE(r1.instances.empty());
  PointCloudInput plane;
  for (int i = 0; i < 60; ++i) {
    for (int j = 0; j < 60; ++j) {
      plane.points.emplace_back(0.05f * i, 0.05f * j, 0.8f);
      plane.colors.emplace_back(0.3f, 0.3f, 0.3f);
    }
  }
  EXPECT_EQ(seg.Segment(plane).semantic.size(), plane.size());

  auto error = [&](const PointCloudInput& in) { return ErrorOf([&] { seg.Segment(in); }); };
  PointCloudInput nan = Room(3.0f, 3.0f, 2.0f, 200, 5);
  nan.name = "nan_room";
  nan.points[17].z() = std::numeric_limits<float>::infinity();
  EXPECT_NE(error(nan).find("point 17 is not finite"), std::string::npos) << error(nan);
  EXPECT_NE(error(nan).find("nan_room"), std::string::npos);
  PointCloudInput mm = Room(3.0f, 3.0f, 2.0f, 500, 6);
  for (auto& p : mm.points) p *= 1000.0f;
  EXPECT_NE(error(mm).find("millimetres"), std::string::npos) << error(mm);
  PointCloudInput grey = Room(3.0f, 3.0f, 2.0f, 100, 7);
  grey.colors.clear();
  EXPECT_NE(error(grey).find("uses colour"), std::string::npos) << error(grey);
  grey.colors.assign(100, Eigen::Vector3f(128, 128, 128));
  EXPECT_NE(error(grey).find("colour 0 is not in [0, 1]"), std::string::npos) << error(grey);
  grey.colors.resize(99);
  EXPECT_NE(error(grey).find("99 colours for 100 points"), std::string::npos) << error(grey);
  EXPECT_NE(error(PointCloudInput()).find("no points"), std::string::npos);
  EXPECT_NE(ErrorOf([] {
              Stage1Segmenter::Load("no/such/model.pt", Stage1InferenceConfig());
            }).find("no/such/model.pt"),
            std::string::npos);
}

TEST(CalibrateStage1, FitsABiasThatDoesNotLowerTheMiou) {
  Stage1InferenceConfig cfg;
  cfg.vote_radius = 0.05;
  cfg.vote_min_points = 5;
  const Stage1Segmenter seg = Stage1Segmenter::Load(kModel, cfg);
  std::vector<PointCloudInput> rooms = {Room(4.0f, 3.0f, 2.5f, 3000, 8),
                                        Room(3.0f, 3.5f, 2.5f, 3000, 9)};
  std::vector<std::vector<int>> labels;
  std::vector<Stage1Result> outs;
  for (const auto& r : rooms) {
    std::vector<int> l(r.size());
    for (std::size_t i = 0; i < r.size(); ++i) {
      const auto& p = r.points[i];
      const bool object = p.x() >= 1.0f && p.x() <= 1.6f && p.y() >= 1.0f && p.y() <= 1.6f &&
                          p.z() <= 0.45f && p.z() > 0.0f;
      l[i] = object ? 6 : (p.z() == 0.0f ? 1 : 0);  // table / floor / wall
    }
    labels.push_back(l);
    outs.push_back(seg.RunNetwork(r));
  }
  std::vector<CalibrationScene> scenes;
  for (std::size_t k = 0; k < rooms.size(); ++k) {
    scenes.push_back({&rooms[k].points, &labels[k], &outs[k]});
  }
  CalibrationOptions opt;
  opt.fit.step = 0.25;
  opt.vote_radii = {0.03, 0.08};
  const CalibrationReport rep = CalibrateStage1(scenes, cfg, opt);
  EXPECT_EQ(rep.config.class_bias.size(), 25u);
  EXPECT_GE(rep.fit.miou_after, rep.fit.miou_before - 1e-12);
  EXPECT_GE(rep.miou_vote_after, rep.miou_vote_configured - 1e-12);
  EXPECT_EQ(rep.cross_validation.size(), 5u);
  EXPECT_EQ(rep.radii.size(), 2u);
  EXPECT_TRUE(rep.config.vote_radius == 0.05 || rep.config.vote_radius == 0.03 ||
              rep.config.vote_radius == 0.08);
  // The reported voted mIoU is what the segmenter gets with the printed config.
  std::vector<int> gt, pred;
  for (std::size_t k = 0; k < rooms.size(); ++k) {
    Stage1Result r = outs[k];
    Stage1Segmenter::Finish(rooms[k].points, rep.config, &r);
    gt.insert(gt.end(), labels[k].begin(), labels[k].end());
    pred.insert(pred.end(), r.semantic.begin(), r.semantic.end());
  }
  EXPECT_NEAR(MeanIouPresent(gt, pred, 25), rep.miou_vote_after, 1e-12);

  opt.folds = 3;
  EXPECT_NE(ErrorOf([&] { CalibrateStage1(scenes, cfg, opt); }).find("folds 3 exceeds the 2"),
            std::string::npos);
  opt.folds = 1;
  EXPECT_NE(ErrorOf([&] { CalibrateStage1(scenes, cfg, opt); }).find("folds"), std::string::npos);
}

}  // namespace
}  // namespace dimr::pipeline
