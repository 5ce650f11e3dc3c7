#include "dimr/nn/bsp_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <utility>
#include <vector>

#include "dimr/geometry/error.h"

namespace dimr::nn {
namespace {

BspConfig TinyConfig() {
  BspConfig c;
  c.resolution = 8;
  c.latent_dim = 8;
  c.encoder_width = 4;
  c.num_planes = 24;
  c.num_convexes = 4;
  c.num_classes = 2;
  c.decoder_widths = {32};
  return c;
}

// An axis-aligned box [-h, h] as a sample: grid + analytic inside/outside points.
BspSample BoxSample(const Eigen::Vector3f& h, int cls, std::uint64_t seed) {
  const int R = 8;
  BspSample s;
  s.cad_class = cls;
  s.model_id = "box" + std::to_string(seed);
  s.grid.assign(R * R * R, 0);
  for (int k = 0; k < R; ++k)
    for (int j = 0; j < R; ++j)
      for (int i = 0; i < R; ++i) {
        const Eigen::Vector3f c(-1.f + (2.f * i + 1) / R, -1.f + (2.f * j + 1) / R,
                                -1.f + (2.f * k + 1) / R);
        s.grid[i + R * (j + R * k)] = (c.array().abs() <= h.array()).all();
      }
  s.iou_grid = s.grid;
  std::mt19937 rng(static_cast<unsigned>(seed));
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  while (s.inside_points.size() < 3 * 200 || s.outside_points.size() < 3 * 200) {
    const Eigen::Vector3f p(u(rng), u(rng), u(rng));
    auto& dst = (p.array().abs() <= h.array()).all() ? s.inside_points : s.outside_points;
    if (dst.size() >= 3 * 200) continue;
    dst.insert(dst.end(), {p.x(), p.y(), p.z()});
  }
  return s;
}

BspDataset TinyData() {
  BspDataset d;
  d.resolution = 8;
  d.samples.push_back(BoxSample({0.5f, 0.5f, 0.5f}, 0, 1));
  d.samples.push_back(BoxSample({0.8f, 0.3f, 0.4f}, 0, 2));
  d.samples.push_back(BoxSample({0.3f, 0.7f, 0.6f}, 1, 3));
  d.samples.push_back(BoxSample({0.6f, 0.6f, 0.2f}, 1, 4));
  return d;
}

TEST(BspConfig, ValidateNamesTheKeyAndRoundTrips) {
  BspConfig c = TinyConfig();
  EXPECT_NO_THROW(c.Validate());
  EXPECT_EQ(BspConfig::FromString(c.ToString()).ToString(), c.ToString());
  c.resolution = 12;
  try {
    c.Validate();
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("BspConfig: resolution = 12"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(BspConfig::FromString("resolution=32 bogus=1"), InvalidArgument);
  // Strict values: trailing text is an error naming the key, not resolution 32.
  try {
    BspConfig::FromString("resolution=32x");
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("'resolution=32x'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(BspConfig::FromString("decoder_widths=256,,512"), InvalidArgument);
  const BspConfig ref = BspConfig::Reference();
  EXPECT_EQ(ref.resolution, 64);
  EXPECT_EQ(ref.num_planes, 4096);
  EXPECT_EQ(ref.num_convexes, 256);
}

TEST(BspModel, DecoderIsDeterministicAndShaped) {
  BspModel model(TinyConfig(), 7);
  Eigen::VectorXf z = Eigen::VectorXf::LinSpaced(8, -1.f, 1.f);
  const Eigen::MatrixXf a = model.DecodePlanes(z, 1);
  const Eigen::MatrixXf b = model.DecodePlanes(z, 1);
  ASSERT_EQ(a.rows(), 24);
  ASSERT_EQ(a.cols(), 4);
  EXPECT_EQ((a - b).cwiseAbs().maxCoeff(), 0.f);
  const Eigen::MatrixXf c = model.DecodePlanes(z, 0);
  EXPECT_GT((a - c).cwiseAbs().maxCoeff(), 1e-6f) << "class conditioning has no effect";
  // Same seed, same initial weights.
  BspModel twin(TinyConfig(), 7);
  EXPECT_EQ((twin.DecodePlanes(z, 1) - a).cwiseAbs().maxCoeff(), 0.f);
  EXPECT_THROW(model.DecodePlanes(Eigen::VectorXf::Zero(5), 0), InvalidArgument);
  EXPECT_THROW(model.DecodePlanes(z, 2), InvalidArgument);
}

// Options of the tiny training runs: `phase0` continuous then `phase1` discrete epochs.
BspTrainOptions TinyTraining(int phase0, int phase1) {
  BspTrainOptions opt;
  opt.epochs_phase0 = phase0;
  opt.epochs_phase1 = phase1;
  opt.batch_size = 4;
  opt.points_per_sample = 256;
  opt.learning_rate = 3e-3;
  opt.kl_weight = 1e-3;
  opt.threads = 1;
  opt.seed = 5;
  return opt;
}

// Mean reconstruction loss of the first and of the last five epochs of a run.
std::pair<double, double> FirstAndLastLoss(const std::vector<BspEpochLog>& logs) {
  double first = 0, last = 0;
  for (int i = 0; i < 5; ++i) {
    first += logs[i].recon_loss;
    last += logs[logs.size() - 1 - i].recon_loss;
  }
  return {first / 5, last / 5};
}

TEST(BspModel, TinyTrainingLowersTheLoss) {
  BspModel model(TinyConfig(), 3);
  const BspTrainOptions opt = TinyTraining(40, 0);
  const BspDataset data = TinyData();
  const auto logs = model.Train(data, BspDataset(), opt);
  ASSERT_EQ(logs.size(), 40u);
  // Average of the first and last 5 epochs: the reconstruction loss must drop clearly.
  const auto [first, last] = FirstAndLastLoss(logs);
  EXPECT_LT(last, 0.7 * first) << "first " << first << " last " << last;
}

// kl_warmup_epochs: the default anneals beta over the whole run, a warm-up of 2 reaches the
// final weight after 2 epochs, 0 holds it from the first epoch. best_path keeps the weights of
// the best logged validation IoU: reloaded, they give exactly that IoU.
TEST(BspModel, KlWarmupAndKeepingTheBestValidationEpoch) {
  const BspDataset data = TinyData();
  BspTrainOptions opt = TinyTraining(0, 6);
  opt.kl_weight = 0.02;
  opt.checkpoint_every = 1;
  {
    BspModel model(TinyConfig(), 3);
    const auto logs = model.Train(data, BspDataset(), opt);
    ASSERT_EQ(logs.size(), 6u);
    EXPECT_NEAR(logs[0].beta, 0.02 / 6, 1e-12);
    EXPECT_NEAR(logs[5].beta, 0.02, 1e-12);
  }
  opt.kl_warmup_epochs = 2;
  {
    BspModel model(TinyConfig(), 3);
    const auto logs = model.Train(data, BspDataset(), opt);
    EXPECT_NEAR(logs[0].beta, 0.01, 1e-12);
    EXPECT_NEAR(logs[1].beta, 0.02, 1e-12);
    EXPECT_NEAR(logs[4].beta, 0.02, 1e-12);
  }
  opt.kl_warmup_epochs = 0;
  const std::string dir = ::testing::TempDir() + "/bsp_best";
  std::filesystem::create_directories(dir);
  opt.best_path = dir + "/best.pt";
  std::filesystem::remove(opt.best_path);
  opt.learning_rate = 3e-2;  // large steps: validation IoU moves up and down between epochs
  BspModel model(TinyConfig(), 3);
  const auto logs = model.Train(data, data, opt);
  double best = -1;
  for (const auto& e : logs) {
    EXPECT_NEAR(e.beta, 0.02, 1e-12);
    ASSERT_GE(e.val_iou, 0.0) << "epoch " << e.epoch;
    best = std::max(best, e.val_iou);
  }
  ASSERT_TRUE(std::filesystem::exists(opt.best_path));
  const BspModel kept = BspModel::Load(opt.best_path);
  EXPECT_NEAR(kept.EvaluateIoU(data, 0.0, 0.0), best, 1e-6);
  if (logs.back().val_iou < best) {
    EXPECT_GT(std::abs(model.EvaluateIoU(data, 0.0, 0.0) - best), 1e-9);
  }
  int kept_epoch = 0;
  double kept_iou = 0;
  ASSERT_TRUE(ReadKeptEpoch(opt.best_path, &kept_epoch, &kept_iou));
  EXPECT_NEAR(kept_iou, best, 1e-6);
  ASSERT_GE(kept_epoch, 1);
  EXPECT_NEAR(logs[kept_epoch - 1].val_iou, best, 1e-6);

  // Interrupted after 3 epochs and resumed to 6 from the checkpoint: the resumed run competes
  // with the kept epoch. The record is raised to an IoU the tiny model cannot reach, so a resume
  // that forgot it (and kept a later epoch) shows.
  opt.checkpoint_path = dir + "/ck.pt";
  for (const char* ext : {"", ".optim", ".state"})
    std::filesystem::remove(opt.checkpoint_path + ext);
  opt.epochs_phase1 = 3;
  BspModel first(TinyConfig(), 3);
  first.Train(data, data, opt);
  ASSERT_TRUE(ReadKeptEpoch(opt.best_path, &kept_epoch, &kept_iou));
  EXPECT_LE(kept_epoch, 3);
  std::ofstream(opt.best_path + ".txt") << "2 0.99\n";
  opt.epochs_phase1 = 6;
  const auto tail = first.Train(data, data, opt);
  ASSERT_EQ(tail.size(), 3u);
  ASSERT_EQ(tail.front().epoch, 4);
  for (const auto& e : tail) ASSERT_LT(e.val_iou, 0.99);
  ASSERT_TRUE(ReadKeptEpoch(opt.best_path, &kept_epoch, &kept_iou));
  EXPECT_EQ(kept_epoch, 2);
  EXPECT_NEAR(kept_iou, 0.99, 1e-12);
  // A fresh run (no checkpoint) starts its own competition.
  std::filesystem::remove(opt.checkpoint_path);
  opt.epochs_phase1 = 1;
  opt.learning_rate = 0.0;  // the untrained model's IoU, lower than any trained epoch's
  BspModel fresh(TinyConfig(), 3);
  const auto one = fresh.Train(data, data, opt);
  if (one[0].val_iou > 0) {
    ASSERT_TRUE(ReadKeptEpoch(opt.best_path, &kept_epoch, &kept_iou));
    EXPECT_EQ(kept_epoch, 1);
    EXPECT_NEAR(kept_iou, one[0].val_iou, 1e-6);
  } else {
    EXPECT_FALSE(ReadKeptEpoch(opt.best_path, &kept_epoch, &kept_iou)) << "stale kept epoch";
  }
  EXPECT_FALSE(ReadKeptEpoch(dir + "/missing.pt", &kept_epoch, &kept_iou));
}

TEST(BspModel, SaveLoadRoundTripAndCorruptFiles) {
  const std::string dir = ::testing::TempDir() + "/bsp_io";
  std::filesystem::create_directories(dir);
  BspModel model(TinyConfig(), 11);
  const BspDataset data = TinyData();
  const Eigen::MatrixXf codes = model.EncodeAll(data);
  model.Save(dir + "/m.pt");
  const BspModel back = BspModel::Load(dir + "/m.pt");
  EXPECT_EQ(back.config().ToString(), model.config().ToString());
  EXPECT_LT((back.EncodeAll(data) - codes).cwiseAbs().maxCoeff(), 1e-6f);
  EXPECT_EQ(back.ConvexPlanes(), model.ConvexPlanes());
  // fp16 storage: close, not exact.
  model.Save(dir + "/h.pt", /*half=*/true);
  const BspModel half = BspModel::Load(dir + "/h.pt");
  EXPECT_LT((half.EncodeAll(data) - codes).cwiseAbs().maxCoeff(), 5e-2f);
  EXPECT_LT(std::filesystem::file_size(dir + "/h.pt"), std::filesystem::file_size(dir + "/m.pt"));
  // Truncated file.
  {
    std::ifstream in(dir + "/m.pt", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(dir + "/t.pt", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  EXPECT_THROW(BspModel::Load(dir + "/t.pt"), ParseError);
  std::ofstream(dir + "/g.pt") << "garbage";
  EXPECT_THROW(BspModel::Load(dir + "/g.pt"), ParseError);
  EXPECT_THROW(BspModel::Load(dir + "/missing.pt"), ParseError);
  // A model of another configuration loads with its own stored configuration.
  BspConfig other = TinyConfig();
  other.num_planes = 32;
  BspModel(other, 1).Save(dir + "/o.pt");
  EXPECT_NO_THROW(BspModel::Load(dir + "/o.pt"));
}

TEST(BspDataset, RoundTripAndTruncation) {
  const std::string dir = ::testing::TempDir() + "/bsp_data";
  std::filesystem::create_directories(dir);
  const BspDataset data = TinyData();
  data.Save(dir + "/d.bin");
  const BspDataset back = BspDataset::Load(dir + "/d.bin");
  ASSERT_EQ(back.samples.size(), data.samples.size());
  for (std::size_t i = 0; i < data.samples.size(); ++i) {
    EXPECT_EQ(back.samples[i].grid, data.samples[i].grid);
    EXPECT_EQ(back.samples[i].iou_grid, data.samples[i].iou_grid);
    ASSERT_EQ(back.samples[i].inside_points.size(), data.samples[i].inside_points.size());
    ASSERT_EQ(back.samples[i].outside_points.size(), data.samples[i].outside_points.size());
    for (std::size_t k = 0; k < data.samples[i].inside_points.size(); ++k) {
      const float v = data.samples[i].inside_points[k];
      EXPECT_EQ(back.samples[i].inside_points[k], QuantizeBspCoordinate(v));
      EXPECT_NEAR(back.samples[i].inside_points[k], v, 1.6e-5f);
    }
    EXPECT_EQ(back.samples[i].model_id, data.samples[i].model_id);
    EXPECT_EQ(back.samples[i].cad_class, data.samples[i].cad_class);
  }
  std::ifstream in(dir + "/d.bin", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (std::size_t cut : {std::size_t{3}, std::size_t{20}, bytes.size() / 2, bytes.size() - 1}) {
    std::ofstream(dir + "/cut.bin", std::ios::binary) << bytes.substr(0, cut);
    try {
      BspDataset::Load(dir + "/cut.bin");
      FAIL() << "cut at " << cut;
    } catch (const ParseError& e) {
      EXPECT_NE(std::string(e.what()).find("cut.bin"), std::string::npos);
    }
  }
}

TEST(BspModel, LatentRefinementLowersTheShapeLoss) {
  BspModel model(TinyConfig(), 3);
  model.Train(TinyData(), BspDataset(), TinyTraining(30, 10));
  // A box the model never saw.
  const BspSample unseen = BoxSample({0.7f, 0.4f, 0.3f}, 0, 9);
  const auto [mu, logvar] = model.Encode(unseen.grid, unseen.cad_class);
  const Eigen::MatrixXf planes_before = model.DecodePlanes(mu, 0);
  const BspModel::Refined r = model.RefineLatent(mu, unseen, 40, 0.02);
  EXPECT_LT(r.loss_after, 0.9 * r.loss_before) << r.loss_before << " -> " << r.loss_after;
  EXPECT_GT((r.mu - mu).norm(), 1e-4f);
  // Zero steps keep the code; a strong prior keeps the code closer than no prior.
  const BspModel::Refined none = model.RefineLatent(mu, unseen, 0);
  EXPECT_EQ((none.mu - mu).cwiseAbs().maxCoeff(), 0.f);
  EXPECT_DOUBLE_EQ(none.loss_after, none.loss_before);
  const BspModel::Refined tied = model.RefineLatent(mu, unseen, 40, 0.02, 100.0);
  EXPECT_LT((tied.mu - mu).norm(), (r.mu - mu).norm());
  // The decoder is untouched: decoding mu again gives the same planes.
  EXPECT_EQ((model.DecodePlanes(mu, 0) - planes_before).cwiseAbs().maxCoeff(), 0.f);
  BspSample empty = unseen;
  empty.outside_points.clear();
  EXPECT_THROW(model.RefineLatent(mu, empty, 5), InvalidArgument);
  EXPECT_THROW(model.RefineLatent(mu, unseen, -1), InvalidArgument);
  EXPECT_THROW(model.RefineLatent(mu, unseen, 5, 0.0), InvalidArgument);
  EXPECT_THROW(model.RefineLatent(Eigen::VectorXf::Zero(3), unseen, 5), InvalidArgument);
}

TEST(BspModel, FrozenDecoderTrainsTheEncoderOnly) {
  BspModel model(TinyConfig(), 3);
  const BspDataset data = TinyData();
  model.Train(data, BspDataset(), TinyTraining(30, 10));
  const Eigen::VectorXf z = Eigen::VectorXf::LinSpaced(8, -0.5f, 0.5f);
  const Eigen::MatrixXf planes_before = model.DecodePlanes(z, 1);
  const auto convexes_before = model.ConvexPlanes();
  const auto code_before = model.Encode(data.samples[2].grid, 1).first;
  // Shapes the encoder alone cannot fit yet: the frozen run must lower the loss through it.
  BspTrainOptions opt = TinyTraining(0, 30);
  opt.freeze_decoder = true;
  opt.seed = 11;
  const auto logs = model.Train(data, BspDataset(), opt);
  ASSERT_EQ(logs.size(), 30u);
  const auto [first, last] = FirstAndLastLoss(logs);
  EXPECT_LT(last, 0.95 * first) << "first " << first << " last " << last;
  // Decoder (weights and BatchNorm statistics) and convex/union weights bit-identical.
  EXPECT_EQ((model.DecodePlanes(z, 1) - planes_before).cwiseAbs().maxCoeff(), 0.f);
  EXPECT_EQ(model.ConvexPlanes(), convexes_before);
  // The encoder moved.
  EXPECT_GT((model.Encode(data.samples[2].grid, 1).first - code_before).norm(), 1e-4f);
  // The decoder trains again afterwards (its parameters were unfrozen).
  model.Train(data, BspDataset(), TinyTraining(0, 2));
  EXPECT_GT((model.DecodePlanes(z, 1) - planes_before).cwiseAbs().maxCoeff(), 0.f);
}

TEST(BspModel, FrozenDecoderOnMuIsDeterministicAndHonoursTheLossDilation) {
  BspModel base(TinyConfig(), 3);
  const BspDataset data = TinyData();
  base.Train(data, BspDataset(), TinyTraining(30, 10));
  const std::string path = ::testing::TempDir() + "/bsp_frozen_base.pt";
  base.Save(path, /*fp16=*/false);
  BspTrainOptions opt = TinyTraining(0, 20);
  opt.freeze_decoder = true;
  opt.sample_latent = false;
  auto run = [&](double dilation) {
    BspModel m = BspModel::Load(path);
    BspTrainOptions o = opt;
    o.loss_dilation = dilation;
    const auto logs = m.Train(data, BspDataset(), o);
    const auto [first, last] = FirstAndLastLoss(logs);
    EXPECT_LT(last, first) << "dilation " << dilation;
    return m.Encode(data.samples[1].grid, 0).first;
  };
  const Eigen::VectorXf a = run(0.0), b = run(0.0), c = run(0.3);
  // Decoding mu (no sampling) with a frozen decoder: same seed, same encoder.
  EXPECT_EQ((a - b).cwiseAbs().maxCoeff(), 0.f);
  // The dilation enters the loss, so the encoder learns other codes.
  EXPECT_GT((a - c).norm(), 1e-4f);
  BspModel m = BspModel::Load(path);
  opt.loss_dilation = -0.1;
  EXPECT_THROW(m.Train(data, BspDataset(), opt), InvalidArgument);
  std::filesystem::remove(path);
}

TEST(BspModel, LatentDistillationPullsTheEncoderOntoItsTargets) {
  BspModel base(TinyConfig(), 3);
  const BspDataset data = TinyData();
  base.Train(data, BspDataset(), TinyTraining(30, 10));
  const std::string path = ::testing::TempDir() + "/bsp_distill_base.pt";
  base.Save(path, /*fp16=*/false);
  // Targets: the refined codes of every training shape (what RefineLatent finds).
  Eigen::MatrixXf targets(static_cast<Eigen::Index>(data.samples.size()), 8);
  double before = 0;
  for (std::size_t s = 0; s < data.samples.size(); ++s) {
    const auto mu = base.Encode(data.samples[s].grid, data.samples[s].cad_class).first;
    targets.row(static_cast<Eigen::Index>(s)) =
        base.RefineLatent(mu, data.samples[s], 40, 0.05).mu.transpose();
    before += (mu - targets.row(static_cast<Eigen::Index>(s)).transpose()).squaredNorm();
  }
  ASSERT_GT(before, 1e-4);
  auto distance = [&](const BspModel& m) {
    double d = 0;
    for (std::size_t s = 0; s < data.samples.size(); ++s) {
      const auto mu = m.Encode(data.samples[s].grid, data.samples[s].cad_class).first;
      d += (mu - targets.row(static_cast<Eigen::Index>(s)).transpose()).squaredNorm();
    }
    return d;
  };
  // The encoder in eval mode (BatchNorm running statistics) reproduces the base codes.
  EXPECT_NEAR(distance(base), before, 1e-3 * before);
  BspTrainOptions opt = TinyTraining(0, 60);
  opt.freeze_decoder = true;
  opt.sample_latent = false;
  opt.kl_weight = 0;
  opt.learning_rate = 3e-3;
  opt.latent_targets = targets;
  opt.latent_target_weight = 1.0;
  const Eigen::VectorXf z = Eigen::VectorXf::LinSpaced(8, -0.5f, 0.5f);
  const Eigen::MatrixXf planes = base.DecodePlanes(z, 1);
  {  // Regression alone (no decoding): the codes move onto their targets.
    BspModel m = BspModel::Load(path);
    BspTrainOptions o = opt;
    o.recon_weight = 0;
    const auto logs = m.Train(data, BspDataset(), o);
    ASSERT_EQ(logs.size(), 60u);
    EXPECT_EQ(logs.back().recon_loss, 0.0);  // nothing decoded
    EXPECT_LT(logs.back().latent_mse, 0.5 * logs.front().latent_mse);
    EXPECT_LT(distance(m), 0.5 * before) << "before " << before;
    EXPECT_EQ((m.DecodePlanes(z, 1) - planes).cwiseAbs().maxCoeff(), 0.f);  // decoder frozen
  }
  {  // With the reconstruction term both are logged and the codes still approach the targets.
    BspModel m = BspModel::Load(path);
    const auto logs = m.Train(data, BspDataset(), opt);
    EXPECT_GT(logs.back().recon_loss, 0.0);
    EXPECT_GT(logs.front().latent_mse, 0.0);
    EXPECT_LT(distance(m), before);
  }
  // Bad options are named.
  BspModel m = BspModel::Load(path);
  BspTrainOptions bad = opt;
  bad.latent_targets = Eigen::MatrixXf::Zero(3, 8);  // 3 rows for 4 samples
  EXPECT_THROW(m.Train(data, BspDataset(), bad), InvalidArgument);
  bad = opt;
  bad.latent_targets(0, 0) = std::nanf("");
  EXPECT_THROW(m.Train(data, BspDataset(), bad), InvalidArgument);
  bad = opt;
  bad.latent_targets.resize(0, 0);
  bad.recon_weight = 0;  // nothing would train
  EXPECT_THROW(m.Train(data, BspDataset(), bad), InvalidArgument);
  bad = opt;
  bad.freeze_decoder = false;
  bad.recon_weight = 0;  // regression only needs a frozen decoder
  EXPECT_THROW(m.Train(data, BspDataset(), bad), InvalidArgument);
  std::filesystem::remove(path);
}

// Occupancy with a distance dilation equals the discrete BSP rule evaluated by hand on the
// decoded planes with every face moved by the distance (d -= distance * |n|).
TEST(BspModel, OccupancyDistanceDilationMatchesTheShiftedPlanes) {
  BspModel model(TinyConfig(), 3);
  const BspDataset data = TinyData();
  model.Train(data, BspDataset(), TinyTraining(30, 10));
  const Eigen::VectorXf z = model.Encode(data.samples[0].grid, 0).first;
  const Eigen::MatrixXf planes = model.DecodePlanes(z, 0);
  const auto convexes = model.ConvexPlanes();
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  Eigen::MatrixX3f pts(2000, 3);
  for (int i = 0; i < pts.rows(); ++i) pts.row(i) << u(rng), u(rng), u(rng);
  std::vector<int> counts;
  for (const double distance : {0.0, 0.05, 0.2}) {
    const auto occ = model.Occupancy(z, 0, pts, 0.02, distance);
    int inside = 0, mismatches = 0;
    for (int i = 0; i < pts.rows(); ++i) {
      bool in = false;
      for (const auto& ids : convexes) {
        if (ids.empty()) continue;
        double sum = 0;
        for (int p : ids) {
          const double v = planes.row(p).head(3).dot(pts.row(i)) + planes(p, 3) - 0.02 -
                           distance * planes.row(p).head(3).norm();
          sum += std::max(0.0, v);
        }
        if (sum < 0.01) in = true;
      }
      inside += in;
      mismatches += in != (occ[static_cast<std::size_t>(i)] != 0);
    }
    EXPECT_LE(mismatches, 2) << "distance " << distance;  // float round-off at the boundary
    counts.push_back(inside);
  }
  // The box decodes to something, and moving the faces out grows it.
  EXPECT_GT(counts[0], 50);
  EXPECT_GT(counts[2], counts[1]);
  EXPECT_GT(counts[1], counts[0]);
  EXPECT_THROW(model.Occupancy(z, 0, pts, 0.0, -0.1), InvalidArgument);
}

}  // namespace
}  // namespace dimr::nn
