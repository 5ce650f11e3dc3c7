// Stage-1 network: config round trip, training lowers the loss on a fixed tiny batch, save/load
// reproduces predictions, bad inputs and corrupt files give clear errors.
#include "dimr/nn/stage1_model.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include "dimr/geometry/error.h"
#include "dimr/nn/sparse_ops.h"

namespace dimr::nn {
namespace {

// A tiny room: floor (class 1) + two boxes (chair 4 facing +x, table 6) with instances.
Stage1Sample TinyRoom(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  Stage1Sample s;
  s.name = "tiny" + std::to_string(seed);
  s.instances.push_back({1, -1, false, 0.0});  // floor
  s.instances.push_back({4, 1, true, 0.3});    // chair
  s.instances.push_back({6, 0, true, -2.0});   // table
  for (int i = 0; i < 900; ++i) {
    s.points.emplace_back(4 * u(rng), 4 * u(rng), 0.01f * u(rng));
    s.semantic.push_back(1);
    s.instance.push_back(0);
  }
  auto box = [&](Eigen::Vector3f lo, Eigen::Vector3f hi, int sem, int inst, int n) {
    for (int i = 0; i < n; ++i) {
      Eigen::Vector3f p(lo.x() + (hi.x() - lo.x()) * u(rng), lo.y() + (hi.y() - lo.y()) * u(rng),
                        lo.z() + (hi.z() - lo.z()) * u(rng));
      // Snap one coordinate to a face: a surface, like a scan.
      const int axis = static_cast<int>(u(rng) * 3) % 3;
      p[axis] = u(rng) < 0.5f ? lo[axis] : hi[axis];
      s.points.push_back(p);
      s.semantic.push_back(sem);
      s.instance.push_back(inst);
    }
  };
  box({0.5f, 0.5f, 0.0f}, {1.0f, 1.0f, 0.9f}, 4, 1, 400);
  box({2.0f, 2.0f, 0.0f}, {3.2f, 2.8f, 0.75f}, 6, 2, 600);
  // A few ignored clutter points.
  for (int i = 0; i < 30; ++i) {
    s.points.emplace_back(3.5f + 0.2f * u(rng), 0.5f + 0.2f * u(rng), 0.1f * u(rng));
    s.semantic.push_back(kStage1Ignore);
    s.instance.push_back(-1);
  }
  return s;
}

// Largest |a_i - b_i| over two equally long tables (probabilities of two predictions).
double MaxAbsDiff(const std::vector<float>& a, const std::vector<float>& b) {
  double d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(double(a[i]) - b[i]));
  return d;
}

// Largest distance between corresponding predicted offsets (metres).
double MaxOffsetDiff(const Stage1Output& a, const Stage1Output& b) {
  double d = 0;
  for (std::size_t i = 0; i < a.offsets.size(); ++i) {
    d = std::max<double>(d, (a.offsets[i] - b.offsets[i]).norm());
  }
  return d;
}

Stage1Config TinyConfig() {
  Stage1Config c;
  c.input.scale = 10;
  c.widths = {8, 16, 24};
  c.reps = 1;
  return c;
}

TEST(Stage1Config, StringRoundTripAndErrors) {
  const Stage1Config c = Stage1Config::Reference();
  EXPECT_EQ(c.ToString(), "scale=50 rgb=0 widths=32,32,64,64,96,96,128 reps=2 classes=25");
  const Stage1Config d = Stage1Config::FromString(TinyConfig().ToString());
  EXPECT_EQ(d.ToString(), TinyConfig().ToString());
  EXPECT_EQ(d.widths, (std::vector<std::int64_t>{8, 16, 24}));
  EXPECT_THROW(Stage1Config::FromString("scale=20 colour=1"), InvalidArgument);
  EXPECT_THROW(Stage1Config::FromString("scale=abc"), InvalidArgument);
  EXPECT_THROW(Stage1Config::FromString("widths=16,x"), InvalidArgument);
  EXPECT_THROW(Stage1Config::FromString("reps=0"), InvalidArgument);
  try {
    Stage1Config::FromString("widths=16,0");
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("widths[1]"), std::string::npos) << e.what();
  }
  // Strict values: trailing text is an error naming the key (was read as 20 / 2).
  for (const char* bad : {"scale=20x", "reps=2.5", "rgb=2", "widths=16,32,", "classes="}) {
    try {
      Stage1Config::FromString(bad);
      ADD_FAILURE() << bad;
    } catch (const InvalidArgument& e) {
      const std::string key = std::string(bad).substr(0, std::string(bad).find('='));
      EXPECT_NE(std::string(e.what()).find("'" + key + "="), std::string::npos) << e.what();
    }
  }
}

TEST(Stage1Model, ParameterCountOfTheReferenceBackbone) {
  // The reference backbone has about 9.36 M learnable parameters (dimr-method.md section 14);
  // our heads add 25*33 + (32*16+16+2*16) + (16*3+3) + (32*32+32+2*32) + (32*24+24).
  Stage1Model m(Stage1Config::Reference());
  EXPECT_NEAR(static_cast<double>(m.NumParameters()), 9.36e6, 0.03e6);
}

TEST(Stage1Model, TrainingLowersTheLossOnAFixedBatch) {
  std::vector<Stage1Sample> data{TinyRoom(1)};
  Stage1Model model(TinyConfig(), 7);
  Stage1TrainOptions opt;
  opt.epochs = 150;
  opt.batch_size = 1;
  opt.learning_rate = 1e-2;
  opt.lr_decay = 1.0;
  opt.augment.enabled = false;
  opt.progress = false;
  opt.threads = 1;
  const Stage1Batch batch = MakeStage1Batch({&data[0]}, model.config().input, nullptr, 0);
  const Stage1LossTerms before = model.EvaluateLoss(batch);
  const auto logs = model.Train(data, opt);
  ASSERT_EQ(logs.size(), 150u);
  // Phase timings: every step has a forward and a backward pass; they add up to at most the
  // step's wall time.
  for (std::size_t i = 1; i < logs.size(); ++i) {
    const auto& l = logs[i];
    EXPECT_GT(l.unet_ms, 0);
    EXPECT_GT(l.backward_ms, 0);
    EXPECT_GE(l.data_ms, 0);
    EXPECT_GE(l.optimizer_ms, 0);
    const double sum =
        l.data_ms + l.voxelize_ms + l.unet_ms + l.loss_ms + l.backward_ms + l.optimizer_ms;
    EXPECT_LE(sum, 1000 * (l.seconds - logs[i - 1].seconds) + 1.0) << "step " << i;
  }
  const Stage1LossTerms after = model.EvaluateLoss(batch);
  EXPECT_GT(before.total, 0);
  EXPECT_LT(logs.back().loss.total, 0.5 * logs.front().loss.total)
      << logs.front().loss.total << " -> " << logs.back().loss.total;
  EXPECT_LT(after.semantic, 0.5 * before.semantic);
  EXPECT_LT(after.offset_norm, before.offset_norm);
  EXPECT_LT(after.heading_cls, before.heading_cls);
  // Semantic accuracy on the training scene after fitting it.
  const Stage1Output out = model.Predict(data[0]);
  int correct = 0, labelled = 0;
  for (std::size_t i = 0; i < out.semantic.size(); ++i) {
    if (data[0].semantic[i] == kStage1Ignore) continue;
    ++labelled;
    correct += out.semantic[i] == data[0].semantic[i];
  }
  EXPECT_GT(static_cast<double>(correct) / labelled, 0.9);
}

// The torch-ops sparse path (the one CUDA builds use) trains exactly like the fused CPU path:
// same losses step by step, same weights after training.
TEST(Stage1Model, TorchOpsBackendTrainsLikeTheFusedPath) {
  std::vector<Stage1Sample> data{TinyRoom(4), TinyRoom(5)};
  Stage1TrainOptions opt;
  opt.epochs = 3;
  opt.batch_size = 2;
  opt.learning_rate = 1e-2;
  opt.progress = false;
  opt.threads = 1;
  std::vector<std::vector<Stage1StepLog>> logs;
  std::vector<Stage1Output> outs;
  for (SparseBackend b : {SparseBackend::kFused, SparseBackend::kTorchOps}) {
    SetSparseBackend(b);
    Stage1Model model(TinyConfig(), 11);
    try {
      logs.push_back(model.Train(data, opt));
      outs.push_back(model.Predict(data[0]));
    } catch (...) {
      SetSparseBackend(SparseBackend::kAuto);
      throw;
    }
    SetSparseBackend(SparseBackend::kAuto);
  }
  ASSERT_EQ(logs[0].size(), 3u);
  ASSERT_EQ(logs[1].size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(logs[1][i].loss.total, logs[0][i].loss.total, 1e-3 * logs[0][i].loss.total)
        << "step " << i;
    EXPECT_NEAR(logs[1][i].loss.heading_cls, logs[0][i].loss.heading_cls, 1e-3) << "step " << i;
  }
  ASSERT_EQ(outs[0].offsets.size(), outs[1].offsets.size());
  EXPECT_LT(MaxOffsetDiff(outs[0], outs[1]),
            1e-2);  // metres; Adam amplifies float-order noise a little
}

// With lr_by_time the schedule follows the time budget: a budget already spent at the first step
// gives the final learning rate at once (and stops after that step).
TEST(Stage1Model, LearningRateCanFollowTheTimeBudget) {
  std::vector<Stage1Sample> data{TinyRoom(6)};
  Stage1TrainOptions opt;
  opt.epochs = 4;
  opt.batch_size = 1;
  opt.learning_rate = 1e-2;
  opt.lr_decay = 0.1;
  opt.augment.enabled = false;
  opt.progress = false;
  opt.threads = 1;
  Stage1Model by_step(TinyConfig(), 2);
  const auto a = by_step.Train(data, opt);
  ASSERT_EQ(a.size(), 4u);
  EXPECT_DOUBLE_EQ(a[0].lr, 1e-2);
  EXPECT_NEAR(a[3].lr, 1e-2 * std::pow(0.1, 0.75), 1e-9);
  opt.max_minutes = 1e-9;
  opt.lr_by_time = true;
  Stage1Model by_time(TinyConfig(), 2);
  const auto b = by_time.Train(data, opt);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_NEAR(b[0].lr, 1e-3, 1e-12);
}

TEST(Stage1Model, PredictShapesAndDeterminism) {
  const Stage1Sample s = TinyRoom(2);
  Stage1Model model(TinyConfig(), 3);
  Stage1Timing timing;
  const Stage1Output a = model.Predict(s, /*with_features=*/true, &timing);
  const Stage1Output b = model.Predict(s);
  const std::size_t n = s.points.size();
  ASSERT_EQ(a.semantic.size(), n);
  // One pass: the probability tables per voxel (10 cm voxels: several points share one).
  ASSERT_EQ(a.point_row.size(), n);
  const std::size_t rows = a.NumRows();
  ASSERT_LT(rows, n);
  ASSERT_EQ(a.semantic_prob.size(), rows * kStage1Classes);
  ASSERT_EQ(a.heading_prob.size(), rows * kHeadingBins);
  ASSERT_EQ(a.heading_residual.size(), rows * kHeadingBins);
  EXPECT_NO_THROW(a.CheckShape("a", n));
  EXPECT_THROW(a.CheckShape("a", n + 1), InvalidArgument);
  std::vector<int> used(rows, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const float* p = a.SemanticProb(i);
    ASSERT_EQ(a.semantic[i], std::max_element(p, p + kStage1Classes) - p) << i;
    used[a.Row(i)] = 1;
  }
  EXPECT_EQ(std::count(used.begin(), used.end(), 1), static_cast<long>(rows));  // no dead row
  // Expanded: one row per point, each the point's voxel row.
  Stage1Output e = a;
  e.ExpandToPoints(n);
  ASSERT_TRUE(e.point_row.empty());
  ASSERT_EQ(e.semantic_prob.size(), n * kStage1Classes);
  for (std::size_t i = 0; i < n; i += 37) {
    for (int b = 0; b < kHeadingBins; ++b) {
      ASSERT_EQ(e.heading_prob[i * kHeadingBins + b], a.HeadingProb(i)[b]);
      ASSERT_EQ(e.heading_residual[i * kHeadingBins + b], a.HeadingResidual(i)[b]);
    }
    ASSERT_EQ(e.semantic_prob[i * kStage1Classes + 3], a.SemanticProb(i)[3]);
  }
  ASSERT_EQ(a.offsets.size(), n);
  ASSERT_EQ(a.features.size(), n * 8);
  EXPECT_TRUE(b.features.empty());
  EXPECT_EQ(a.semantic, b.semantic);
  EXPECT_EQ(a.semantic_prob, b.semantic_prob);
  double row = 0;
  for (int c = 0; c < kStage1Classes; ++c) row += a.semantic_prob[c];
  EXPECT_NEAR(row, 1.0, 1e-5);
  EXPECT_GT(timing.unet_ms, 0);
  // The network frame puts the floor at z = 0 and the x-y centre at the origin.
  EXPECT_NEAR(a.frame.floor_z, 0.0, 0.03);
  // Translating the whole room does not change the prediction (origin-free input).
  Stage1Sample moved = s;
  for (auto& p : moved.points) p += Eigen::Vector3f(120.0f, -37.0f, 2.5f);
  const Stage1Output c = model.Predict(moved);
  int same = 0;
  for (std::size_t i = 0; i < n; ++i) same += c.semantic[i] == a.semantic[i];
  EXPECT_GT(same, static_cast<int>(0.97 * n));
}

TEST(Stage1Model, SaveLoadReproducesAndRejectsCorruptFiles) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / "dimr_stage1_model_test";
  fs::create_directories(dir);
  const Stage1Sample s = TinyRoom(3);
  Stage1Model model(TinyConfig(), 5);
  const std::string path = (dir / "m.pt").string();
  model.Save(path);
  const Stage1Model loaded = Stage1Model::Load(path);
  EXPECT_EQ(loaded.config().ToString(), model.config().ToString());
  EXPECT_EQ(model.Predict(s).semantic_prob, loaded.Predict(s).semantic_prob);
  // fp16 file: predictions close.
  model.Save((dir / "h.pt").string(), /*half=*/true);
  const Stage1Output h = Stage1Model::Load((dir / "h.pt").string()).Predict(s);
  const Stage1Output f = model.Predict(s);
  ASSERT_EQ(h.semantic_prob.size(), f.semantic_prob.size());
  EXPECT_LT(MaxAbsDiff(f.semantic_prob, h.semantic_prob), 0.02);
  // Truncated file and garbage file.
  {
    std::ifstream in(path, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(dir / "trunc.pt", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
    std::ofstream(dir / "junk.pt", std::ios::binary) << "not a model at all";
  }
  EXPECT_THROW(Stage1Model::Load((dir / "trunc.pt").string()), ParseError);
  EXPECT_THROW(Stage1Model::Load((dir / "junk.pt").string()), ParseError);
  EXPECT_THROW(Stage1Model::Load((dir / "missing.pt").string()), ParseError);
  // A model of another configuration does not load into a name/shape check silently: the
  // config is stored, so Load builds the right network.
  Stage1Config other = TinyConfig();
  other.widths = {8, 16};
  Stage1Model small(other);
  small.Save((dir / "small.pt").string());
  EXPECT_EQ(Stage1Model::Load((dir / "small.pt").string()).config().widths.size(), 2u);
  fs::remove_all(dir);
}

TEST(Stage1Model, AverageIsTheMeanOfTheWeights) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / "dimr_stage1_average_test";
  fs::create_directories(dir);
  const Stage1Sample s = TinyRoom(8);
  const std::string a = (dir / "a.pt").string(), b = (dir / "b.pt").string(),
                    m = (dir / "m.pt").string();
  Stage1Model(TinyConfig(), 1).Save(a);
  Stage1Model(TinyConfig(), 2).Save(b);
  const std::vector<float> pa = Stage1Model::Load(a).Predict(s).semantic_prob;
  const std::vector<float> pb = Stage1Model::Load(b).Predict(s).semantic_prob;
  // One file, or a file with itself: that model.
  EXPECT_EQ(Stage1Model::Average({a}).Predict(s).semantic_prob, pa);
  EXPECT_EQ(Stage1Model::Average({a, a}).Predict(s).semantic_prob, pa);
  // The mean m of a and b differs from both; the mean of a, b and m is m again (a sum without
  // the division, or a copy of the first model, would not be).
  const Stage1Model mean = Stage1Model::Average({a, b});
  mean.Save(m);
  const std::vector<float> pm = mean.Predict(s).semantic_prob;
  const std::vector<float> pm3 = Stage1Model::Average({a, b, m}).Predict(s).semantic_prob;
  double d_a = 0, d_b = 0, d_m = 0;
  for (std::size_t i = 0; i < pm.size(); ++i) {
    d_a = std::max(d_a, std::abs(double(pm[i]) - pa[i]));
    d_b = std::max(d_b, std::abs(double(pm[i]) - pb[i]));
    d_m = std::max(d_m, std::abs(double(pm[i]) - pm3[i]));
  }
  EXPECT_GT(d_a, 1e-3);
  EXPECT_GT(d_b, 1e-3);
  EXPECT_LT(d_m, 1e-5);
  // Errors: nothing to average, another configuration (both named), a missing file.
  EXPECT_THROW(Stage1Model::Average({}), InvalidArgument);
  Stage1Config other = TinyConfig();
  other.widths = {8, 16};
  const std::string o = (dir / "other.pt").string();
  Stage1Model(other).Save(o);
  try {
    Stage1Model::Average({a, o});
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("other.pt"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Stage1Model::Average({a, (dir / "missing.pt").string()}), ParseError);
  fs::remove_all(dir);
}

TEST(Stage1Model, LoadingAtAnotherScaleKeepsEveryTensorAndChangesOnlyTheGrid) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / "dimr_stage1_rescale_test";
  fs::create_directories(dir);
  const Stage1Config coarse_config = TinyConfig();  // scale 10
  const std::string coarse_path = (dir / "coarse.pt").string();
  Stage1Model(coarse_config, 11).Save(coarse_path);
  const Stage1Model coarse = Stage1Model::Load(coarse_path);

  const Stage1Model fine = Stage1Model::LoadAtScale(coarse_path, 20);
  Stage1Config expect = coarse_config;
  expect.input.scale = 20;
  EXPECT_EQ(fine.config().ToString(), expect.ToString());
  EXPECT_EQ(fine.NumParameters(), coarse.NumParameters());

  const Stage1Sample room = TinyRoom(12);
  const Stage1Output at10 = coarse.Predict(room);
  const Stage1Output at20 = fine.Predict(room);
  // The grid changed: the outputs are stored per voxel row (25 per row), and twice as many
  // voxels per metre give more occupied voxels on the same points ...
  EXPECT_EQ(at10.semantic_prob.size() % 25, 0u);
  EXPECT_GT(at20.semantic_prob.size(), at10.semantic_prob.size() * 5 / 4);
  // ... but every parameter and buffer was carried: back at scale 10 the model is the original
  // (a tensor left at its fresh initialisation would change these).
  const std::string fine_path = (dir / "fine.pt").string();
  fine.Save(fine_path);
  const Stage1Output back = Stage1Model::LoadAtScale(fine_path, 10).Predict(room);
  EXPECT_LT(MaxAbsDiff(back.semantic_prob, at10.semantic_prob), 1e-6);
  EXPECT_LT(MaxAbsDiff(back.heading_prob, at10.heading_prob), 1e-6);
  EXPECT_EQ(back.semantic, at10.semantic);

  try {
    Stage1Model::LoadAtScale(coarse_path, -5);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("coarse.pt"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("scale"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Stage1Model::LoadAtScale((dir / "missing.pt").string(), 20), ParseError);
  fs::remove_all(dir);
}

TEST(Stage1Model, DeepeningAddsIdentityBlocksAndKeepsThePredictions) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / "dimr_stage1_deepen_test";
  fs::create_directories(dir);
  const Stage1Config shallow_config = TinyConfig();  // reps 1, widths 8,16,24
  const std::string shallow_path = (dir / "shallow.pt").string();
  Stage1Model(shallow_config, 13).Save(shallow_path);
  const Stage1Model shallow = Stage1Model::Load(shallow_path);

  const Stage1Model deep = Stage1Model::LoadDeeper(shallow_path, 2);
  Stage1Config expect = shallow_config;
  expect.reps = 2;
  EXPECT_EQ(deep.config().ToString(), expect.ToString());
  // One more (c, c) residual block on each side of each level: 2 BatchNorms (2c weights + 2c
  // biases) and two 3x3x3 c -> c convolutions.
  std::int64_t added = 0;
  for (std::int64_t c : shallow_config.widths) {
    const std::int64_t per_block = 4 * c + 2 * 27 * c * c;
    added += (c == shallow_config.widths.back() ? 1 : 2) * per_block;
  }
  EXPECT_EQ(deep.NumParameters(), shallow.NumParameters() + added);

  const Stage1Sample room = TinyRoom(12);
  const Stage1Output before = shallow.Predict(room);
  const Stage1Output after = deep.Predict(room);
  ASSERT_EQ(after.semantic_prob.size(), before.semantic_prob.size());
  EXPECT_LT(MaxAbsDiff(after.semantic_prob, before.semantic_prob), 1e-5);
  ASSERT_EQ(after.offsets.size(), before.offsets.size());
  EXPECT_LT(MaxOffsetDiff(after, before), 1e-5);
  EXPECT_EQ(after.semantic, before.semantic);
  // A fresh reps=2 network (the added blocks not zeroed) predicts differently: the equality
  // above is the carried tensors' and the zeroed convolutions' doing.
  const Stage1Output fresh = Stage1Model(expect, 13).Predict(room);
  EXPECT_GT(MaxAbsDiff(fresh.semantic_prob, before.semantic_prob), 1e-3);

  try {
    Stage1Model::LoadDeeper(shallow_path, 1);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("shallow.pt"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("reps=1"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Stage1Model::LoadDeeper((dir / "missing.pt").string(), 2), ParseError);
  fs::remove_all(dir);
}

TEST(Stage1Model, DroppingTheColourInputIsExactForGreyClouds) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / "dimr_stage1_drop_colour_test";
  fs::create_directories(dir);
  Stage1Config colour_config = TinyConfig();
  colour_config.input.use_rgb = true;
  const std::string path = (dir / "colour.pt").string();
  Stage1Model(colour_config, 11).Save(path);
  const Stage1Model colour = Stage1Model::Load(path);
  const Stage1Model geometry = Stage1Model::LoadWithoutColour(path);
  EXPECT_FALSE(geometry.config().input.use_rgb);
  Stage1Config expect = colour_config;
  expect.input.use_rgb = false;
  EXPECT_EQ(geometry.config().ToString(), expect.ToString());
  // 3 x 27 x 8 input weights fewer.
  EXPECT_EQ(colour.NumParameters() - geometry.NumParameters(), 27 * 3 * 8);

  Stage1Sample grey = TinyRoom(12);
  grey.colors.assign(grey.points.size(), Eigen::Vector3f::Constant(0.5f));
  Stage1Sample coloured = grey;
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<float> u(0, 1);
  for (auto& c : coloured.colors) c = Eigen::Vector3f(u(rng), u(rng), u(rng));
  const Stage1Output g = geometry.Predict(grey);
  const Stage1Output c_grey = colour.Predict(grey);
  const Stage1Output c_col = colour.Predict(coloured);
  ASSERT_EQ(g.semantic_prob.size(), c_grey.semantic_prob.size());
  // The colour weights matter (a zero or dropped colour input would not change this) ...
  EXPECT_GT(MaxAbsDiff(c_col.semantic_prob, c_grey.semantic_prob), 1e-3);
  // ... and the geometry-only copy is the colour model on grey input: every head.
  EXPECT_LT(MaxAbsDiff(g.semantic_prob, c_grey.semantic_prob), 1e-5);
  ASSERT_EQ(g.offsets.size(), c_grey.offsets.size());
  double offset_diff = 0;
  for (std::size_t i = 0; i < g.offsets.size(); ++i) {
    offset_diff =
        std::max(offset_diff, double((g.offsets[i] - c_grey.offsets[i]).cwiseAbs().maxCoeff()));
  }
  EXPECT_LT(offset_diff, 1e-5);
  EXPECT_LT(MaxAbsDiff(g.heading_prob, c_grey.heading_prob), 1e-5);
  EXPECT_EQ(g.semantic, c_grey.semantic);
  // Its colours are ignored: any colours, the same output.
  EXPECT_LT(MaxAbsDiff(geometry.Predict(coloured).semantic_prob, g.semantic_prob), 1e-6);

  // A model without colour input has nothing to drop; the message names the file.
  const std::string plain = (dir / "plain.pt").string();
  Stage1Model(TinyConfig(), 3).Save(plain);
  try {
    Stage1Model::LoadWithoutColour(plain);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("plain.pt"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Stage1Model::LoadWithoutColour((dir / "missing.pt").string()), ParseError);
  fs::remove_all(dir);
}

TEST(Stage1Model, BadInputsGiveClearErrors) {
  Stage1Model model(TinyConfig());
  Stage1Sample empty;
  empty.name = "empty_scene";
  try {
    model.Predict(empty);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("empty_scene"), std::string::npos);
  }
  Stage1Sample bad = TinyRoom(4);
  bad.points[17].x() = std::nanf("");
  try {
    model.Predict(bad);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("point 17"), std::string::npos) << e.what();
  }
  Stage1TrainOptions opt;
  EXPECT_THROW(model.Train({}, opt), InvalidArgument);
  opt.device = "tpu";
  std::vector<Stage1Sample> one{TinyRoom(5)};
  EXPECT_THROW(model.Train(one, opt), InvalidArgument);
}

TEST(Stage1Model, CheckpointResumeContinuesTraining) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / "dimr_stage1_resume_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::vector<Stage1Sample> data{TinyRoom(6), TinyRoom(7)};
  Stage1TrainOptions opt;
  opt.epochs = 4;
  opt.batch_size = 1;
  opt.progress = false;
  opt.threads = 1;
  opt.checkpoint_path = (dir / "ckpt.pt").string();
  opt.checkpoint_every_steps = 1;
  opt.max_minutes = 1e-9;  // stops after the first step
  Stage1Model a(TinyConfig(), 9);
  EXPECT_EQ(a.Train(data, opt).size(), 1u);
  opt.max_minutes = 0;
  Stage1Model b(TinyConfig(), 9);
  const auto rest = b.Train(data, opt);
  ASSERT_EQ(rest.size(), 7u);  // 8 steps in total
  EXPECT_EQ(rest.front().step, 2);
  fs::remove_all(dir);
}

TEST(Stage1Model, SemanticClassWeightsFromFrequencies) {
  Stage1Sample s;
  auto add = [&](int cls, int n) {
    for (int i = 0; i < n; ++i) {
      s.points.emplace_back(0.01f * static_cast<float>(s.points.size()), 0, 0);
      s.semantic.push_back(cls);
      s.instance.push_back(-1);
    }
  };
  add(0, 64);
  add(4, 16);
  add(6, 4);
  add(kStage1Ignore, 50);  // ignored points do not count
  const std::vector<float> w = SemanticClassWeights({s});
  ASSERT_EQ(w.size(), static_cast<std::size_t>(kStage1Classes));
  // Frequencies 64/84, 16/84, 4/84 -> median 16/84 -> weights sqrt(16/64), 1, sqrt(16/4).
  EXPECT_NEAR(w[0], 0.5, 1e-6);
  EXPECT_NEAR(w[4], 1.0, 1e-6);
  EXPECT_NEAR(w[6], 2.0, 1e-6);
  EXPECT_NEAR(w[1], 1.0, 1e-6);  // absent class
  const std::vector<float> c = SemanticClassWeights({s}, kStage1Classes, 0.6, 1.5);
  EXPECT_NEAR(c[0], 0.6, 1e-6);
  EXPECT_NEAR(c[6], 1.5, 1e-6);
  EXPECT_THROW(SemanticClassWeights({s}, kStage1Classes, 2.0, 1.0), InvalidArgument);
  // Plain inverse frequency (power 1): 16/64, 1, 16/4.
  const std::vector<float> inv = SemanticClassWeights({s}, kStage1Classes, 0.1, 10.0, 1.0);
  EXPECT_NEAR(inv[0], 0.25, 1e-6);
  EXPECT_NEAR(inv[4], 1.0, 1e-6);
  EXPECT_NEAR(inv[6], 4.0, 1e-6);
  EXPECT_THROW(SemanticClassWeights({s}, kStage1Classes, 0.1, 10.0, 0.0), InvalidArgument);
  // A wrong-sized weight vector is rejected by the trainer.
  Stage1Model model(TinyConfig());
  Stage1TrainOptions opt;
  opt.class_weights = {1.0f, 2.0f};
  std::vector<Stage1Sample> one{TinyRoom(8)};
  EXPECT_THROW(model.Train(one, opt), InvalidArgument);
}

// A scene whose voxelisation is exact under 90-degree rotations and mirroring about its
// centroid: every point sits in (0.3, 0.7) of its voxel relative to the bounding-box corner
// anchors at 0.1 and M + 0.9 voxels, so any rotation by k * 90 degrees or mirror image
// partitions the points into the same voxels (the voxel grid starts at the minimum corner).
Stage1Sample LatticeScene(int scale) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> f(0.3f, 0.7f), u(0, 1);
  const int m = 24;
  const float h = 1.0f / static_cast<float>(scale);
  Stage1Sample s;
  s.name = "lattice";
  auto add = [&](float x, float y, float z) {
    s.points.emplace_back(x * h, y * h, z * h);
    s.semantic.push_back(kStage1Ignore);
    s.instance.push_back(-1);
  };
  add(0.1f, 0.1f, 0.5f);
  add(m + 0.9f, m + 0.9f, 0.5f);
  for (int i = 0; i <= m; ++i) {
    for (int j = 0; j <= m; ++j) {
      add(i + f(rng), j + f(rng), f(rng));  // floor
      // An L-shaped block and a scattered column make the scene asymmetric.
      const bool block =
          (i > 3 && i < 10 && j > 2 && j < 16) || (i >= 10 && i < 14 && j > 2 && j < 6);
      for (int k = 1; k < 8; ++k) {
        if ((block && k < 5) || (i == 18 && j == 7) || u(rng) < 0.01f)
          add(i + f(rng), j + f(rng), k + f(rng));
      }
    }
  }
  return s;
}

// p -> centre + R(p - centre) in x-y, R = rotation by k * 90 degrees, optionally after x -> -x.
Stage1Sample Transform(const Stage1Sample& s, int quarter_turns, bool mirror,
                       Eigen::Vector2f* centre_out) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& p : s.points) c += p.head<2>().cast<double>();
  c /= static_cast<double>(s.points.size());
  *centre_out = c.cast<float>();
  Stage1Sample t = s;
  for (auto& p : t.points) {
    double x = p.x() - c.x(), y = p.y() - c.y();
    if (mirror) x = -x;
    for (int k = 0; k < quarter_turns; ++k) {
      const double nx = -y, ny = x;
      x = nx;
      y = ny;
    }
    p = Eigen::Vector3f(static_cast<float>(c.x() + x), static_cast<float>(c.y() + y), p.z());
  }
  return t;
}

TEST(Stage1Model, RotationAndMirrorAveragingIsEquivariant) {
  Stage1Config config = TinyConfig();
  const Stage1Sample s = LatticeScene(config.input.scale);
  const Stage1Model model(config, 13);
  const std::size_t n = s.points.size();
  Eigen::Vector2f centre;
  const Stage1Sample turned = Transform(s, 1, false, &centre);

  // Single passes are not rotation-invariant: the test has something to show.
  const Stage1Output plain = model.Predict(s), plain_turned = model.Predict(turned);
  double plain_diff = 0;
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 0; c < kStage1Classes; ++c) {
      plain_diff = std::max<double>(
          plain_diff, std::abs(plain.SemanticProb(i)[c] - plain_turned.SemanticProb(i)[c]));
    }
  }
  EXPECT_GT(plain_diff, 1e-3);

  // Four rotations: the same average, offsets turned by 90 degrees, heading bins shifted by 3.
  // (Per-point tables: the TTA rows are stored in each scene's own voxel order.)
  Stage1Output a = model.PredictAugmented(s, 4, false);
  Stage1Output b = model.PredictAugmented(turned, 4, false);
  a.ExpandToPoints(n);
  b.ExpandToPoints(n);
  ASSERT_EQ(b.semantic_prob.size(), a.semantic_prob.size());
  double row = 0;
  for (int c = 0; c < kStage1Classes; ++c) row += a.semantic_prob[c];
  EXPECT_NEAR(row, 1.0, 1e-5);
  for (std::size_t i = 0; i < a.semantic_prob.size(); ++i) {
    ASSERT_NEAR(b.semantic_prob[i], a.semantic_prob[i], 2e-4) << i;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f& o = a.offsets[i];
    ASSERT_NEAR(b.offsets[i].x(), -o.y(), 2e-4) << i;
    ASSERT_NEAR(b.offsets[i].y(), o.x(), 2e-4) << i;
    ASSERT_NEAR(b.offsets[i].z(), o.z(), 2e-4) << i;
    for (int k = 0; k < kHeadingBins; ++k) {
      const std::size_t to = i * kHeadingBins + (k + 3) % kHeadingBins;
      ASSERT_NEAR(b.heading_prob[to], a.heading_prob[i * kHeadingBins + k], 2e-4);
      ASSERT_NEAR(b.heading_residual[to], a.heading_residual[i * kHeadingBins + k], 2e-4);
    }
  }
  EXPECT_EQ(a.semantic, b.semantic);

  // Rotations and mirror images: the mirrored scene's average is the mirrored average
  // (offset x negated, heading bin k -> 6 - k with the residual negated).
  const Stage1Sample mirrored = Transform(s, 0, true, &centre);
  Stage1Output am = model.PredictAugmented(s, 2, true);
  Stage1Output bm = model.PredictAugmented(mirrored, 2, true);
  am.ExpandToPoints(n);
  bm.ExpandToPoints(n);
  for (std::size_t i = 0; i < am.semantic_prob.size(); ++i) {
    ASSERT_NEAR(bm.semantic_prob[i], am.semantic_prob[i], 2e-4) << i;
  }
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_NEAR(bm.offsets[i].x(), -am.offsets[i].x(), 2e-4) << i;
    ASSERT_NEAR(bm.offsets[i].y(), am.offsets[i].y(), 2e-4) << i;
    for (int k = 0; k < kHeadingBins; ++k) {
      const std::size_t to = i * kHeadingBins + (kHeadingBins + 6 - k) % kHeadingBins;
      ASSERT_NEAR(bm.heading_prob[to], am.heading_prob[i * kHeadingBins + k], 2e-4);
      ASSERT_NEAR(bm.heading_residual[to], -am.heading_residual[i * kHeadingBins + k], 2e-4);
    }
  }
  // (1, false) is the plain prediction; counts not dividing 12 are rejected.
  EXPECT_EQ(model.PredictAugmented(s, 1, false).semantic_prob, plain.semantic_prob);
  EXPECT_THROW(model.PredictAugmented(s, 5, false), InvalidArgument);
  EXPECT_THROW(model.PredictAugmented(s, 0, true), InvalidArgument);
}

}  // namespace
}  // namespace dimr::nn

namespace dimr::nn {
namespace {

// A room of `height` metres: floor, four walls up to `height`, a box; ~`n` points.
std::vector<Eigen::Vector3f> LowRoom(float sx, float sy, float height, int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  std::vector<Eigen::Vector3f> p;
  for (int i = 0; i < n; ++i) {
    const float r = u(rng);
    if (r < 0.5f) {
      p.emplace_back(sx * u(rng), sy * u(rng), 0.0f);
    } else if (r < 0.9f) {
      const bool along_x = u(rng) < 0.5f;
      const float side = u(rng) < 0.5f ? 0.0f : 1.0f;
      p.emplace_back(along_x ? sx * u(rng) : sx * side, along_x ? sy * side : sy * u(rng),
                     height * u(rng));
    } else {
      p.emplace_back(1.0f + 0.5f * u(rng), 1.0f + 0.5f * u(rng), 0.45f * u(rng));
    }
  }
  return p;
}

// Six U-Net levels at 5 cm like the shipped model: the grid is down-sampled 5 times (stride 32).
Stage1Config SixLevels() {
  Stage1Config c;
  c.input.scale = 20;
  c.widths = {4, 4, 4, 4, 4, 4};
  return c;
}

TEST(Stage1Model, NetworkInputMatchesTheTrainingBatch) {
  const Stage1Sample s = TinyRoom(5);
  Stage1InputConfig input;
  input.scale = 10;
  const Stage1Batch batch = MakeStage1Batch({&s}, input, nullptr, 0);
  const Stage1NetworkInput in =
      MakeStage1NetworkInput(ScenePoints(s.points, nullptr, s.name), input);
  EXPECT_EQ(in.voxel, batch.voxel);
  EXPECT_EQ(in.features, batch.features);
  EXPECT_EQ(in.frame.origin, batch.frames[0].origin);
  std::int32_t zmax = 0;
  for (std::size_t i = 0; i < in.voxel.size(); i += 4) zmax = std::max(zmax, in.voxel[i + 3]);
  EXPECT_EQ(in.extent[2], zmax + 1);
}

// Inference runs the heads on the voxels and gathers each point's row (issue 21); training
// runs them on the gathered point features, with BatchNorm unfolded. Both must give the same
// per-point outputs: the semantic cross-entropy, offset L1 and heading-bin cross-entropy that
// EvaluateLoss computes on the training path are recomputed here from Predict's per-point
// outputs. A wrong point ->
// voxel row (a shifted or unsorted index) changes both by far more than the tolerance.
TEST(Stage1Model, VoxelHeadsGiveThePointPathsOutputs) {
  const Stage1Sample s = TinyRoom(6);
  Stage1Model model(TinyConfig(), 11);
  // A few steps so that the BatchNorm running statistics are not the identity.
  Stage1TrainOptions opt;
  opt.epochs = 2;
  opt.batch_size = 1;
  opt.seed = 4;
  model.Train({s}, opt);
  Stage1InputConfig input = TinyConfig().input;
  const Stage1Batch batch = MakeStage1Batch({&s}, input, nullptr, 0);
  const Stage1LossTerms ref = model.EvaluateLoss(batch);
  const Stage1Output out = model.Predict(s);
  const std::size_t n = s.points.size();
  ASSERT_EQ(batch.semantic.size(), n);
  double ce = 0, l1 = 0, hcls = 0;
  int labelled = 0, valid = 0, boxed = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (batch.semantic[i] != kStage1Ignore) {
      ce -= std::log(out.SemanticProb(i)[batch.semantic[i]]);
      ++labelled;
    }
    if (batch.heading_bin[i] != kStage1Ignore) {
      hcls -= std::log(out.HeadingProb(i)[batch.heading_bin[i]]);
      ++boxed;
    }
    if (batch.offset_valid[i]) {
      for (int a = 0; a < 3; ++a)
        l1 += std::abs(out.offsets[i][a] - batch.offset_target[3 * i + a]);
      ++valid;
    }
  }
  ASSERT_GT(labelled, 0);
  ASSERT_GT(valid, 0);
  EXPECT_NEAR(ce / labelled, ref.semantic, 1e-4 * std::max(1.0, ref.semantic));
  EXPECT_NEAR(l1 / valid, ref.offset_norm, 1e-4 * std::max(1.0, ref.offset_norm));
  ASSERT_GT(boxed, 0);
  EXPECT_NEAR(hcls / boxed, ref.heading_cls, 1e-4 * std::max(1.0, ref.heading_cls));
  EXPECT_GT(ref.semantic, 0.0);
}

TEST(Stage1Model, FlatRoomsPlanesAndSinglePointsSegment) {
  const Stage1Model model(SixLevels(), 3);
  // A ScanNet-like room whose points reach only 1.37 m: 28 voxels high at 5 cm, fewer than the
  // 32 that five down-samplings need. It used to throw "cannot downsample spatial shape
  // [4, 3, 1] (stride 16)".
  const auto room = LowRoom(3.4f, 2.6f, 1.37f, 6000, 1);
  const ScenePoints view(room, nullptr, "low_room");
  EXPECT_LT(MakeStage1NetworkInput(view, model.config().input).extent[2], 32);
  const Stage1Output out = model.PredictAugmented(view, 2, true);
  ASSERT_EQ(out.semantic.size(), room.size());
  ASSERT_EQ(out.semantic_prob.size(), room.size() * kStage1Classes);
  for (float v : out.semantic_prob) ASSERT_TRUE(std::isfinite(v));
  // The Stage1Sample path is the same computation.
  Stage1Sample sample;
  sample.name = "low_room";
  sample.points = room;
  EXPECT_EQ(model.PredictAugmented(sample, 2, true).semantic_prob, out.semantic_prob);

  // One point; all points on one plane; a line.
  const std::vector<Eigen::Vector3f> one{{1.0f, 2.0f, 0.5f}};
  EXPECT_EQ(model.Predict(ScenePoints(one, nullptr)).semantic.size(), 1u);
  std::vector<Eigen::Vector3f> plane, line;
  for (int i = 0; i < 50; ++i) {
    for (int j = 0; j < 50; ++j) plane.emplace_back(0.04f * i, 0.03f * j, 0.7f);
    line.emplace_back(0.05f * i, 0.0f, 0.0f);
  }
  EXPECT_EQ(model.Predict(ScenePoints(plane, nullptr)).semantic.size(), plane.size());
  EXPECT_EQ(model.PredictAugmented(ScenePoints(line, nullptr), 4, true).semantic.size(),
            line.size());
}

TEST(Stage1Model, AMillionPointsAndBadCloudsDoNotCrash) {
  const Stage1Model model(SixLevels(), 3);
  const auto big = LowRoom(4.0f, 3.0f, 2.5f, 1000000, 2);
  const Stage1Output out = model.Predict(ScenePoints(big, nullptr, "big"));
  EXPECT_EQ(out.semantic.size(), big.size());
  EXPECT_EQ(out.offsets.size(), big.size());

  // A room in millimetres: a clear error, not a crash or a huge grid.
  std::vector<Eigen::Vector3f> mm = LowRoom(3.4f, 2.6f, 2.4f, 2000, 3);
  for (auto& p : mm) p *= 1000.0f;
  try {
    model.Predict(ScenePoints(mm, nullptr, "mm_room"));
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("millimetres"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("mm_room"), std::string::npos) << e.what();
  }
  std::vector<Eigen::Vector3f> nan = LowRoom(3.0f, 3.0f, 2.0f, 100, 4);
  nan[42].y() = std::numeric_limits<float>::quiet_NaN();
  try {
    model.Predict(ScenePoints(nan, nullptr, "nan_room"));
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("point 42"), std::string::npos) << e.what();
  }
  const std::vector<Eigen::Vector3f> none;
  EXPECT_THROW(model.Predict(ScenePoints(none, nullptr, "empty")), InvalidArgument);
  Stage1Config rgb = SixLevels();
  rgb.input.use_rgb = true;
  const std::vector<Eigen::Vector3f> one{{0.0f, 0.0f, 0.0f}};
  EXPECT_THROW(Stage1Model(rgb).Predict(ScenePoints(one, nullptr)), InvalidArgument);
}

}  // namespace
}  // namespace dimr::nn
