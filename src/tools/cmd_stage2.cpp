// Stage-2 commands: `dimr stage2 prepare` (SynthScan / ScanNet-format rooms -> stage-1
// proposals, canonicalised, with their GT targets and BSP codes -> a cache), `dimr train
// stage2`, `dimr stage2 eval` (score AP, box IoU, latent error on held-out proposals) and
// `dimr stage2 check-gt` (GT codes decoded and placed by the GT boxes vs the placed CAD
// models). Torch-free: the networks live behind nn/*_model.h.
#if defined(DIMR_HAVE_NN) && defined(DIMR_HAVE_PIPELINE) && defined(DIMR_HAVE_DATA) && \
    defined(DIMR_HAVE_EVAL)
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <string>
#include <vector>

#include "dimr/data/labels.h"
#include "dimr/data/scannet_io.h"
#include "dimr/data/shapenet_io.h"
#include "dimr/data/synthscan.h"
#include "dimr/eval/mesh_metrics.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/obj_io.h"
#include "dimr/geometry/oriented_box.h"
#include "dimr/nn/bsp_model.h"
#include "dimr/nn/stage1_model.h"
#include "dimr/nn/stage2_model.h"
#include "dimr/pipeline/bsp_mesher.h"
#include "dimr/pipeline/clustering.h"
#include "dimr/pipeline/stage1_instances.h"
#include "dimr/pipeline/stage1_segmenter.h"
#include "dimr/pipeline/stage2_proposals.h"
#include "tools/bsp_options.h"
#include "tools/command_registry.h"
#include "tools/model_card.h"
#include "tools/sha256.h"
#include "tools/stage1_scenes.h"

namespace dimr::tools {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// ---------------------------------------------------------------- stage-1 settings
// The stage-1 inference settings of `dimr stage2 prepare`: the card's (or --stage1-inference's)
// recommended_inference, read by the library parser (pipeline::Stage1InferenceConfig), so every
// key the segmenter knows (colour_norm, cluster_cap, ...) means the same here.
struct Stage1Settings {
  pipeline::Stage1InferenceConfig config;
  std::string text;  // as read
};

Stage1Settings ReadStage1Settings(const std::string& model, const std::string& override_text) {
  Stage1Settings s;
  std::string text = override_text;
  if (text.empty()) {
    if (const auto card = ReadModelCardValue(model, "recommended_inference")) text = *card;
  }
  s.text = text;
  const std::string where = override_text.empty() ? ModelCardPath(model) : "--stage1-inference";
  try {
    s.config = pipeline::Stage1InferenceConfig::FromString(text);
    s.config.Validate();
  } catch (const std::exception& e) {
    throw ParseError(where, e.what());
  }
  return s;
}

// Stage 1 on one room as the segmenter runs it (pipeline::Stage1Segmenter: colour
// standardisation, test-time augmentation, class bias, vote), with the point features, and the
// proposals of every clustering pass (no size filter, no NMS) down to prepare's own
// --min-points, each with its heading vote and its stage-1 score.
struct Stage1Proposals {
  pipeline::Stage1Result result;  // features, offsets, labels; network_origin.z() = floor
  std::vector<pipeline::ScoredInstance> proposals;
};

Stage1Proposals RunStage1(const nn::Stage1Model& model, const nn::Stage1Sample& s,
                          const Stage1Settings& st, int min_points, const std::string& name) {
  const pipeline::Stage1Segmenter seg = pipeline::Stage1Segmenter::Borrow(model, st.config);
  pipeline::PointCloudInput input;
  input.name = name;
  input.points = s.points;
  if (seg.uses_color()) input.colors = s.colors;
  Stage1Proposals r;
  r.result = seg.RunNetwork(input, /*with_features=*/true);
  pipeline::Stage1Segmenter::FinishLabels(input.points, st.config, &r.result,
                                          input.has_colors() ? &input.colors : nullptr);
  pipeline::ClusteringConfig cc = st.config.InstanceConfig().clustering;
  cc.min_points = std::max(1, min_points);
  const pipeline::Stage1Result& o = r.result;
  r.proposals = pipeline::ScoredStage1Proposals(input.points, o.offsets, o.cad_label,
                                                o.semantic_prob, o.heading_prob, o.heading_residual,
                                                pipeline::Stage1RfsToCad(), cc, o.point_row);
  return r;
}

// ---------------------------------------------------------------- GT codes
// Scans folders of one or more SynthScan / ScanNet-format roots: root/scans/<scene>, with
// root/shapenet the CAD models.
struct Root {
  std::string scans, shapenet;
};

Root ResolveRoot(const std::string& path) {
  Root r;
  if (fs::is_directory(fs::path(path) / "scans")) {
    r.scans = (fs::path(path) / "scans").string();
    r.shapenet = (fs::path(path) / "shapenet").string();
  } else if (fs::is_directory(path)) {
    r.scans = path;
    r.shapenet = (fs::path(path).parent_path() / "shapenet").string();
  } else {
    throw InvalidArgument("'" + path + "' is not a SynthScan / ScanNet folder (no scans/)");
  }
  return r;
}

// model id -> [mu, logvar] of the BSP encoder (eval mode) for every CAD model of a tree.
std::map<std::string, Eigen::VectorXf> EncodeTree(const nn::BspModel& bsp, const std::string& dir,
                                                  int jobs) {
  ShapeNetSelection sel;
  sel.resolution = bsp.config().resolution;
  sel.jobs = jobs;
  const nn::BspDataset data = ShapeNetBspDataset(dir, sel);
  const Eigen::MatrixXf codes = bsp.EncodeAll(data);
  std::map<std::string, Eigen::VectorXf> out;
  for (std::size_t s = 0; s < data.samples.size(); ++s) {
    out[data.samples[s].model_id] = codes.row(static_cast<Eigen::Index>(s)).transpose();
  }
  return out;
}

std::vector<std::string> SceneNames(const std::string& scans, int limit) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(scans)) {
    if (e.is_directory()) names.push_back(e.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  if (limit > 0 && static_cast<int>(names.size()) > limit) names.resize(limit);
  return names;
}

// ---------------------------------------------------------------- prepare
struct PrepareArgs {
  std::vector<std::string> scans;
  std::string out, stage1 = "models/stage1/stage1.pt", bsp = "models/bsp/bsp.pt";
  std::string stage1_inference;  // overrides the card's recommended_inference
  int limit = 0, min_points = 20, jobs = 1, threads = 0;
  bool quiet = false;
};

void RunPrepare(const PrepareArgs& a) {
  const auto t0 = Clock::now();
  if (a.threads > 0) nn::SetIntraOpThreads(a.threads);
  const nn::Stage1Model stage1 = nn::Stage1Model::Load(a.stage1);
  const nn::BspModel bsp = nn::BspModel::Load(a.bsp);
  const Stage1Settings st = ReadStage1Settings(a.stage1, a.stage1_inference);
  std::printf("stage 1 %s (%s), inference '%s'\n", a.stage1.c_str(),
              stage1.config().ToString().c_str(), st.text.c_str());
  std::vector<nn::Stage2Sample> samples;
  int scenes = 0, gt_cad = 0, gt_matched = 0, missing_codes = 0;
  for (const std::string& path : a.scans) {
    const Root root = ResolveRoot(path);
    std::map<std::string, Eigen::VectorXf> codes;
    if (fs::is_directory(root.shapenet)) {
      codes = EncodeTree(bsp, root.shapenet, a.jobs);
    } else {
      std::fprintf(stderr, "warning: no ShapeNet tree at %s: proposals get no latent targets\n",
                   root.shapenet.c_str());
    }
    std::printf("%s: %zu CAD models encoded (%.1f s)\n", path.c_str(), codes.size(),
                Seconds(t0, Clock::now()));
    const std::vector<std::string> names = SceneNames(root.scans, a.limit);
    for (const std::string& name : names) {
      const auto ts = Clock::now();
      const std::string dir = (fs::path(root.scans) / name).string();
      data::SynthScene scene;
      nn::Stage1Sample sample;
      try {
        scene = data::ReadScanNetScene(dir);
        sample = Stage1SampleFromScene(scene);
      } catch (const std::exception& e) {
        throw ParseError(dir, e.what());
      }
      const Stage1Proposals sp = RunStage1(stage1, sample, st, a.min_points, dir);
      std::vector<std::vector<int>> lists;
      for (const auto& p : sp.proposals) lists.push_back(p.points);
      const auto matches = pipeline::MatchProposals(lists, sample.instance,
                                                    static_cast<int>(sample.instances.size()));
      std::vector<bool> matched(scene.instances.size(), false);
      for (const auto& in : scene.instances) gt_cad += in.cad_class >= 0 ? 1 : 0;
      const int fd = sp.result.feature_dim;
      const float floor_z = sp.result.network_origin.z();
      for (std::size_t k = 0; k < sp.proposals.size(); ++k) {
        const auto& p = sp.proposals[k];
        if (p.cad_class < 0 || p.cad_class >= nn::kStage2CadClasses) continue;
        pipeline::ProposalFrame frame;
        nn::Stage2Sample s =
            pipeline::CanonicaliseProposal(sample.points, sp.result.features, fd, floor_z, p.points,
                                           p.cad_class, p.heading, &frame);
        s.scene = name;
        s.prior_score = static_cast<float>(p.score);
        const auto& m = matches[k];
        const data::SynthInstance* gt = m.gt >= 0 ? &scene.instances[m.gt] : nullptr;
        const Eigen::VectorXf* code = nullptr;
        if (gt != nullptr && gt->cad_class >= 0) {
          auto it = codes.find(gt->model_id);
          if (it != codes.end()) {
            code = &it->second;
          } else if (m.iou >= 0.5) {
            ++missing_codes;
          }
          if (m.iou >= 0.5 && !matched[m.gt]) {
            matched[m.gt] = true;
            ++gt_matched;
          }
        }
        pipeline::SetStage2Targets(frame, m, gt ? gt->cad_class : -1, gt ? &gt->box : nullptr, code,
                                   &s);
        samples.push_back(std::move(s));
      }
      ++scenes;
      if (!a.quiet) {
        std::fprintf(stderr, "\r%s: scene %d (%s), %zu proposals, %zu samples, %.1f s/scene   ",
                     path.c_str(), scenes, name.c_str(), sp.proposals.size(), samples.size(),
                     Seconds(ts, Clock::now()));
      }
    }
    if (!a.quiet) std::fprintf(stderr, "\n");
  }
  nn::WriteStage2Samples(a.out, samples);
  int fg = 0, with_code = 0;
  for (const auto& s : samples) {
    fg += s.iou > 0.5f ? 1 : 0;
    with_code += s.has_box_target() ? 1 : 0;
  }
  std::printf(
      "%d scenes -> %zu proposals (%d with IoU > 0.5, %d with a GT code); %d of %d GT CAD "
      "instances covered at IoU >= 0.5; %d matched instances without a code; %s (%.1f s)\n",
      scenes, samples.size(), fg, with_code, gt_matched, gt_cad, missing_codes, a.out.c_str(),
      Seconds(t0, Clock::now()));
}

void SetupPrepare(CLI::App& app) {
  auto a = std::make_shared<PrepareArgs>();
  app.add_option("--scans", a->scans,
                 "SynthScan / ScanNet-format roots (DIR/scans + DIR/shapenet), one or more")
      ->required();
  app.add_option("--out", a->out, "output cache file")->required();
  app.add_option("--stage1", a->stage1,
                 "stage-1 weights (its card's recommended_inference is used)");
  app.add_option("--bsp", a->bsp, "BSP-CVAE weights (GT codes of the CAD models)");
  app.add_option("--stage1-inference", a->stage1_inference,
                 "override the card's recommended_inference, e.g. 'passes=s0.12,s0.2 rotations=1'");
  app.add_option("--limit", a->limit, "first N scenes of each root (0 = all)");
  app.add_option("--min-points", a->min_points, "smallest cluster kept as a proposal")
      ->check(CLI::Range(1, 1000000));
  app.add_option("--jobs", a->jobs, "threads encoding the CAD models (0 = all cores)");
  app.add_option("--threads", a->threads, "intra-op threads of the networks (0 = default)");
  app.add_flag("--quiet", a->quiet, "no progress line");
  app.callback([a]() { RunPrepare(*a); });
}

// ---------------------------------------------------------------- metrics
// Average precision of a ranking (all-point interpolation); labels 1 = positive.
double AveragePrecision(const std::vector<double>& score, const std::vector<int>& label) {
  std::vector<std::size_t> order(score.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return score[a] > score[b]; });
  const int positives = static_cast<int>(std::count(label.begin(), label.end(), 1));
  if (positives == 0) return NAN;
  std::vector<double> prec, rec;
  int tp = 0;
  for (std::size_t k = 0; k < order.size(); ++k) {
    tp += label[order[k]];
    prec.push_back(static_cast<double>(tp) / static_cast<double>(k + 1));
    rec.push_back(static_cast<double>(tp) / positives);
  }
  for (int k = static_cast<int>(prec.size()) - 2; k >= 0; --k)
    prec[k] = std::max(prec[k], prec[k + 1]);
  double ap = 0, last = 0;
  for (std::size_t k = 0; k < prec.size(); ++k) {
    ap += (rec[k] - last) * prec[k];
    last = rec[k];
  }
  return ap;
}

struct Stage2Metrics {
  int proposals = 0, positives = 0, matched = 0;
  nn::Stage2LossTerms loss;
  double score_ap = NAN, prior_ap = NAN;          // stage-2 score vs stage-1 score ranking
  double combined_ap = NAN;                       // sqrt(stage-1 score x stage-2 score)
  double box_iou = 0, box_iou_baseline = 0;       // mean over matched proposals
  double box_iou50 = 0, box_iou50_baseline = 0;   // share of matched with box IoU >= 0.5
  double latent_l1 = 0, latent_l1_mean_code = 0;  // mean |mu - mu_gt| (per dim)
  double code_l1 = 0;                             // over [mu, logvar]
};

// Per-class mean of the GT codes (the "mean code" baseline).
std::vector<Eigen::VectorXf> MeanCodes(const std::vector<nn::Stage2Sample>& samples, int dim) {
  std::vector<Eigen::VectorXf> mean(nn::kStage2CadClasses, Eigen::VectorXf::Zero(dim));
  std::vector<int> n(nn::kStage2CadClasses, 0);
  Eigen::VectorXf all = Eigen::VectorXf::Zero(dim);
  int total = 0;
  for (const auto& s : samples) {
    if (!s.has_box_target() || static_cast<int>(s.code.size()) != dim) continue;
    const Eigen::Map<const Eigen::VectorXf> c(s.code.data(), dim);
    mean[s.gt_class] += c;
    all += c;
    ++n[s.gt_class];
    ++total;
  }
  for (int c = 0; c < nn::kStage2CadClasses; ++c) {
    mean[c] = n[c] > 0 ? Eigen::VectorXf(mean[c] / n[c])
                       : (total > 0 ? Eigen::VectorXf(all / total) : mean[c]);
  }
  return mean;
}

Stage2Metrics EvaluateStage2(const nn::Stage2Model& model,
                             const std::vector<nn::Stage2Sample>& samples,
                             const std::vector<Eigen::VectorXf>& mean_codes,
                             const std::vector<float>& class_weights) {
  Stage2Metrics m;
  m.proposals = static_cast<int>(samples.size());
  if (samples.empty()) return m;
  const nn::Stage2Output o = model.Predict(samples);
  // Loss terms in chunks (eval mode).
  const int chunk = 64;
  double wsum = 0;
  for (std::size_t first = 0; first < samples.size(); first += chunk) {
    std::vector<const nn::Stage2Sample*> part;
    for (std::size_t i = first; i < std::min(samples.size(), first + chunk); ++i) {
      part.push_back(&samples[i]);
    }
    const nn::Stage2LossTerms l =
        model.EvaluateLoss(nn::MakeStage2Batch(part, model.config().input, class_weights));
    const double w = static_cast<double>(part.size());
    m.loss.total += w * l.total;
    m.loss.score += w * l.score;
    m.loss.latent += w * l.latent;
    m.loss.center += w * l.center;
    m.loss.size += w * l.size;
    wsum += w;
  }
  m.loss.total /= wsum;
  m.loss.score /= wsum;
  m.loss.latent /= wsum;
  m.loss.center /= wsum;
  m.loss.size /= wsum;
  std::vector<double> score, prior, combined;
  std::vector<int> label;
  const int L = model.config().latent_dim;
  double iou_sum = 0, base_sum = 0, l1 = 0, l1_mean = 0, code_l1 = 0;
  int iou50 = 0, base50 = 0;
  for (int i = 0; i < m.proposals; ++i) {
    const nn::Stage2Sample& s = samples[i];
    score.push_back(o.score(i));
    prior.push_back(s.prior_score);
    combined.push_back(std::sqrt(std::max(0.0f, s.prior_score) * o.score(i)));
    const bool positive = s.iou >= 0.5f && s.gt_class == s.proposal_class;
    label.push_back(positive ? 1 : 0);
    m.positives += positive ? 1 : 0;
    if (s.iou < 0.5f || !s.has_box_target()) continue;
    ++m.matched;
    // Boxes in the proposal's canonical frame (heading 0 = the proposal's heading).
    pipeline::ProposalFrame f;
    f.extent = s.extent.cast<double>();
    const int c = s.proposal_class;
    const geometry::OrientedBox pred =
        pipeline::DecodeBox(f, o.CenterResidual(i, c), o.SizeResidual(i, c));
    const geometry::OrientedBox base = pipeline::ProposalBox(f);
    geometry::OrientedBox gt;
    gt.center = s.center_target.cast<double>();
    gt.size = s.size_target.cast<double>();
    gt.heading = s.heading_target;
    const double a = geometry::BoxIoU(pred, gt), b = geometry::BoxIoU(base, gt);
    iou_sum += a;
    base_sum += b;
    iou50 += a >= 0.5 ? 1 : 0;
    base50 += b >= 0.5 ? 1 : 0;
    const Eigen::VectorXf code = o.Code(i);
    const Eigen::Map<const Eigen::VectorXf> gtc(s.code.data(),
                                                static_cast<Eigen::Index>(s.code.size()));
    if (gtc.size() == code.size()) {
      l1 += (code.head(L) - gtc.head(L)).cwiseAbs().mean();
      code_l1 += (code - gtc).cwiseAbs().mean();
      l1_mean += (mean_codes[s.gt_class].head(L) - gtc.head(L)).cwiseAbs().mean();
    }
  }
  m.score_ap = AveragePrecision(score, label);
  m.prior_ap = AveragePrecision(prior, label);
  m.combined_ap = AveragePrecision(combined, label);
  if (m.matched > 0) {
    m.box_iou = iou_sum / m.matched;
    m.box_iou_baseline = base_sum / m.matched;
    m.box_iou50 = static_cast<double>(iou50) / m.matched;
    m.box_iou50_baseline = static_cast<double>(base50) / m.matched;
    m.latent_l1 = l1 / m.matched;
    m.latent_l1_mean_code = l1_mean / m.matched;
    m.code_l1 = code_l1 / m.matched;
  }
  return m;
}

void PrintMetrics(const Stage2Metrics& m) {
  std::printf("%d proposals, %d positive (IoU >= 0.5, same class), %d matched with a GT code\n",
              m.proposals, m.positives, m.matched);
  std::printf("loss %.4f (score %.4f, latent %.4f, centre %.4f, size %.4f)\n", m.loss.total,
              m.loss.score, m.loss.latent, m.loss.center, m.loss.size);
  std::printf("\n| metric | stage 2 | baseline |\n|---|---|---|\n");
  std::printf("| proposal score AP (IoU >= 0.5) | %.4f | %.4f (stage-1 score) |\n", m.score_ap,
              m.prior_ap);
  std::printf("| AP of sqrt(stage-1 x stage-2 score) | %.4f | - |\n", m.combined_ap);
  std::printf("| mean box IoU (matched) | %.4f | %.4f (proposal box c0, s0) |\n", m.box_iou,
              m.box_iou_baseline);
  std::printf("| box IoU >= 0.5 (matched) | %.4f | %.4f |\n", m.box_iou50, m.box_iou50_baseline);
  std::printf("| latent L1 on mu (per dim) | %.4f | %.4f (per-class mean code) |\n", m.latent_l1,
              m.latent_l1_mean_code);
  std::printf("| code L1 on [mu, logvar] | %.4f | - |\n", m.code_l1);
}

nlohmann::json MetricsJson(const Stage2Metrics& m) {
  auto num = [](double v) { return std::isnan(v) ? nlohmann::json(nullptr) : nlohmann::json(v); };
  return {{"proposals", m.proposals},     {"positives", m.positives},
          {"matched", m.matched},         {"loss", m.loss.total},
          {"loss_score", m.loss.score},   {"loss_latent", m.loss.latent},
          {"loss_center", m.loss.center}, {"loss_size", m.loss.size},
          {"score_ap", num(m.score_ap)},  {"stage1_score_ap", num(m.prior_ap)},
          {"box_iou", m.box_iou},         {"box_iou_baseline", m.box_iou_baseline},
          {"box_iou50", m.box_iou50},     {"box_iou50_baseline", m.box_iou50_baseline},
          {"latent_l1", m.latent_l1},     {"latent_l1_mean_code", m.latent_l1_mean_code},
          {"code_l1", m.code_l1}};
}

std::vector<nn::Stage2Sample> LoadCaches(const std::vector<std::string>& paths) {
  std::vector<nn::Stage2Sample> out;
  for (const auto& p : paths) {
    auto s = nn::ReadStage2Samples(p);
    out.insert(out.end(), std::make_move_iterator(s.begin()), std::make_move_iterator(s.end()));
  }
  return out;
}

// ---------------------------------------------------------------- train
struct TrainArgs {
  std::vector<std::string> train, val;
  std::string out = "models/stage2", config = "cpu", device = "cpu", class_weights = "data";
  std::string init;
  int epochs = 60, batch = 32, threads = 0, checkpoint_every = 200, val_every = 1;
  double lr = 1e-3, lr_decay = 0.1, max_minutes = 0, keep_min = 0.7, jitter = 0.005;
  std::uint64_t seed = 123;
  bool no_augment = false, fp32 = false, quiet = false, lr_by_time = false;
  bool finetune_stage1 = false;
};

nn::Stage2Config ConfigFromArg(const std::string& text, int feature_dim) {
  nn::Stage2Config c;
  if (text == "reference") {
    c = nn::Stage2Config::Reference();
  } else if (text != "cpu") {
    c = nn::Stage2Config::FromString(text);
  }
  if (text == "cpu" || text == "reference") c.input.feature_dim = feature_dim;
  return c;
}

std::string WeightsToString(const std::vector<float>& w) {
  std::string r;
  for (float v : w) {
    char b[32];
    std::snprintf(b, sizeof(b), "%.3f", v);
    r += (r.empty() ? "" : ",") + std::string(b);
  }
  return r;
}

void WriteCard(const TrainArgs& a, const std::string& command, const nn::Stage2Model& model,
               std::size_t train_n, std::size_t val_n, long long steps, double minutes,
               const std::vector<float>& weights, const Stage2Metrics* val,
               const std::string& weights_path) {
  std::ofstream y(a.out + "/model.yaml");
  y << "name: stage2\n";
  y << "description: \"DIMR stage 2 (per-proposal sparse U-Net on the 20^3 grid, max-pool, heads: "
       "score 1, latent [mu, logvar] 2x"
    << model.config().latent_dim
    << ", box residuals 8x3 centre + 8x3 size), dimr-method.md section 4\"\n";
  y << "architecture: \"" << model.config().ToString() << "\"\n";
  y << "parameters: " << model.NumParameters() << "\n";
  y << "input: \"canonical proposal points (rotated by -heading, centred on the heading-aligned "
       "box), "
       "features [stage-1 point feature, canonical xyz, height above floor]; pooled [max, s0, "
       "centre height] - no absolute coordinates\"\n";
  y << "stage1_model: models/stage1/stage1.pt\n";
  y << "bsp_model: models/bsp/bsp.pt   # GT codes = its encoder on the GT CAD models\n";
  y << "training:\n";
  y << "  command: \"" << command << "\"\n";
  y << "  seed: " << a.seed << "\n";
  y << "  train_data: \"";
  for (std::size_t i = 0; i < a.train.size(); ++i) y << (i ? " " : "") << a.train[i];
  y << "\"\n  train_proposals: " << train_n << "\n  val_data: \"";
  for (std::size_t i = 0; i < a.val.size(); ++i) y << (i ? " " : "") << a.val[i];
  y << "\"\n  val_proposals: " << val_n << "\n";
  y << "  steps: " << steps << "\n";
  y << "  batch_size: " << a.batch << "\n";
  y << "  minutes_this_run: " << minutes << "\n";
  y << "  device: " << a.device << "\n";
  y << "  lr: " << a.lr << "\n  lr_decay: " << a.lr_decay << "\n";
  y << "  stage1: frozen (features precomputed by dimr stage2 prepare)\n";
  y << "  augmentation: "
    << (a.no_augment ? std::string("none")
                     : "keep " + std::to_string(a.keep_min) + "..1 of the points, jitter " +
                           std::to_string(a.jitter) + " m")
    << "\n";
  y << "  class_weights: \"" << a.class_weights << ": " << WeightsToString(weights) << "\"\n";
  if (!a.init.empty()) y << "  initialised_from: \"" << a.init << "\"\n";
  if (val) {
    y << "metrics_val:\n";
    y << "  proposals: " << val->proposals << "\n";
    y << "  score_ap50: " << val->score_ap << "\n";
    y << "  stage1_score_ap50: " << val->prior_ap << "\n";
    y << "  box_iou_mean: " << val->box_iou << "\n";
    y << "  box_iou_mean_proposal_box: " << val->box_iou_baseline << "\n";
    y << "  latent_l1_mu: " << val->latent_l1 << "\n";
    y << "  latent_l1_mu_mean_code: " << val->latent_l1_mean_code << "\n";
  }
  y << "recommended_inference: \"score_threshold=0.05 min_points=100 nms_iou=0.3\"\n";
  y << "weights:\n";
  y << "  file: " << fs::path(weights_path).filename().string() << "\n";
  y << "  dtype: " << (a.fp32 ? "float32" : "float16") << "\n";
  y << "  sha256: " << Sha256File(weights_path) << "\n";
}

void RunTrain(const TrainArgs& a, const std::string& command) {
  if (a.finetune_stage1) {
    throw InvalidArgument(
        "--finetune-stage1: joint training of stage 1 is not implemented yet (stage 1 stays "
        "frozen; docs/stage2.md)");
  }
  const auto t0 = Clock::now();
  const std::vector<nn::Stage2Sample> train = LoadCaches(a.train);
  const std::vector<nn::Stage2Sample> val = LoadCaches(a.val);
  if (train.empty()) throw InvalidArgument("no training proposals in the --train caches");
  nn::Stage2Config config = ConfigFromArg(a.config, train.front().feature_dim);
  nn::Stage2TrainOptions opt;
  opt.epochs = a.epochs;
  opt.batch_size = a.batch;
  opt.learning_rate = a.lr;
  opt.lr_decay = a.lr_decay;
  opt.seed = a.seed;
  opt.threads = a.threads;
  opt.device = a.device;
  opt.max_minutes = a.max_minutes;
  opt.lr_by_time = a.lr_by_time;
  opt.checkpoint_every_steps = a.checkpoint_every;
  opt.validate_every_epochs = a.val_every;
  opt.progress = !a.quiet;
  opt.augment.enabled = !a.no_augment;
  opt.augment.keep_min = a.keep_min;
  opt.augment.jitter = a.jitter;
  if (a.class_weights == "data") {
    opt.class_weights = nn::Stage2ClassWeights(train);
  } else if (a.class_weights == "reference") {
    opt.class_weights = nn::Stage2ReferenceClassWeights();
  } else if (a.class_weights != "none") {
    throw InvalidArgument("--class-weights must be data, reference or none");
  }
  fs::create_directories(a.out + "/checkpoint");
  opt.checkpoint_path = a.out + "/checkpoint/stage2.pt";
  nn::Stage2Model model =
      a.init.empty() ? nn::Stage2Model(config, a.seed) : nn::Stage2Model::Load(a.init);
  if (model.config().ToString() != config.ToString()) {
    throw InvalidArgument("--init '" + a.init + "' holds '" + model.config().ToString() +
                          "', not '" + config.ToString() + "'");
  }
  const std::vector<Eigen::VectorXf> mean_codes = MeanCodes(train, 2 * config.latent_dim);
  int with_code = 0;
  for (const auto& s : train) with_code += s.has_box_target() ? 1 : 0;
  std::printf(
      "stage 2 %s, %lld parameters; %zu training proposals (%d with a GT code), %zu "
      "validation; class weights (%s) %s (loaded in %.1f s)\n",
      config.ToString().c_str(), static_cast<long long>(model.NumParameters()), train.size(),
      with_code, val.size(), a.class_weights.c_str(), WeightsToString(opt.class_weights).c_str(),
      Seconds(t0, Clock::now()));
  std::fflush(stdout);
  const std::string log_path = a.out + "/train_log.csv";
  const bool fresh = !fs::exists(log_path);
  std::ofstream csv(log_path, std::ios::app);
  if (fresh)
    csv << "step,epoch,lr,loss,score,latent,center,size,seconds,data_ms,forward_ms,backward_ms\n";
  const bool fresh_val = !fs::exists(a.out + "/val_log.csv");
  std::ofstream vcsv(a.out + "/val_log.csv", std::ios::app);
  if (fresh_val) {
    vcsv << "epoch,loss,score,latent,center,size,score_ap,stage1_score_ap,box_iou,box_iou_baseline,"
            "latent_l1,latent_l1_mean_code,seconds\n";
  }
  std::unique_ptr<Stage2Metrics> last;
  long long last_step = 0;
  auto on_epoch = [&](int epoch, const nn::Stage2Model& m) -> std::map<std::string, double> {
    if (val.empty()) return {};
    auto r = std::make_unique<Stage2Metrics>(EvaluateStage2(m, val, mean_codes, opt.class_weights));
    vcsv << epoch << "," << r->loss.total << "," << r->loss.score << "," << r->loss.latent << ","
         << r->loss.center << "," << r->loss.size << "," << r->score_ap << "," << r->prior_ap << ","
         << r->box_iou << "," << r->box_iou_baseline << "," << r->latent_l1 << ","
         << r->latent_l1_mean_code << "," << Seconds(t0, Clock::now()) << "\n";
    vcsv.flush();
    std::map<std::string, double> out{{"val_loss", r->loss.total},
                                      {"val_score_ap", r->score_ap},
                                      {"val_box_iou", r->box_iou},
                                      {"val_latent_l1", r->latent_l1}};
    last = std::move(r);
    return out;
  };
  model.Train(
      train, opt,
      [&](const nn::Stage2StepLog& s) {
        last_step = s.step;
        csv << s.step << "," << s.epoch << "," << s.lr << "," << s.loss.total << "," << s.loss.score
            << "," << s.loss.latent << "," << s.loss.center << "," << s.loss.size << ","
            << s.seconds << "," << s.data_ms << "," << s.forward_ms << "," << s.backward_ms << "\n";
        if (s.step % 20 == 0) csv.flush();
      },
      on_epoch);
  csv.flush();
  const std::string weights = a.out + "/stage2.pt";
  model.Save(weights, !a.fp32);
  const double minutes = Seconds(t0, Clock::now()) / 60.0;
  WriteCard(a, command, model, train.size(), val.size(), last_step, minutes, opt.class_weights,
            last.get(), weights);
  std::printf("saved %s after %lld steps (%.1f min), model card %s/model.yaml\n", weights.c_str(),
              last_step, minutes, a.out.c_str());
  if (last) PrintMetrics(*last);
}

void SetupTrain(CLI::App& app) {
  auto a = std::make_shared<TrainArgs>();
  app.add_option("--train", a->train, "training caches (dimr stage2 prepare)")->required();
  app.add_option("--val", a->val, "validation caches");
  app.add_option("--out", a->out, "output folder (weights, card, logs, checkpoint/)");
  app.add_option("--config", a->config,
                 "cpu | reference | 'features=16 height=1 grid=20 widths=16,32,48,64 reps=1 "
                 "latent=128 center_height=1'");
  app.add_option("--epochs", a->epochs, "epochs")->check(CLI::Range(1, 100000));
  app.add_option("--batch", a->batch, "proposals per step")->check(CLI::Range(1, 4096));
  app.add_option("--lr", a->lr, "Adam learning rate")->check(CLI::PositiveNumber);
  app.add_option("--lr-decay", a->lr_decay, "learning-rate factor reached at the end (0, 1]");
  app.add_option("--seed", a->seed, "seed (weights, shuffling, augmentation)");
  app.add_option("--threads", a->threads, "intra-op threads (0 = default)");
  app.add_option("--device", a->device, "cpu | cuda");
  app.add_option("--max-minutes", a->max_minutes, "stop (checkpointed) after this many minutes");
  app.add_option("--checkpoint-every", a->checkpoint_every, "steps between checkpoints");
  app.add_option("--val-every", a->val_every, "epochs between validation passes");
  app.add_option("--class-weights", a->class_weights,
                 "data (inverse GT-class frequency of the training proposals, mean 1) | reference "
                 "(the ScanNet table of the reference) | none");
  app.add_option("--keep-min", a->keep_min, "augmentation: keep at least this share of points");
  app.add_option("--jitter", a->jitter, "augmentation: point jitter (m)");
  app.add_flag("--no-augment", a->no_augment, "no augmentation");
  app.add_option("--init", a->init, "start from these stage-2 weights (same config)");
  app.add_flag("--lr-by-time", a->lr_by_time, "with --max-minutes: decay over the time budget");
  app.add_flag("--finetune-stage1", a->finetune_stage1,
               "train stage 1 jointly (not implemented yet: stage 1 is frozen)");
  app.add_flag("--fp32", a->fp32, "store float32 weights (default float16)");
  app.add_flag("--quiet", a->quiet, "no progress bar");
  app.callback([a, &app]() { RunTrain(*a, CommandLine(app)); });
}

// ---------------------------------------------------------------- eval
struct EvalArgs {
  std::string model = "models/stage2/stage2.pt", json;
  std::vector<std::string> data, train;
  std::string class_weights = "data";
};

void RunEval(const EvalArgs& a) {
  const nn::Stage2Model model = nn::Stage2Model::Load(a.model);
  const std::vector<nn::Stage2Sample> data = LoadCaches(a.data);
  const std::vector<nn::Stage2Sample> train = LoadCaches(a.train);
  const int dim = 2 * model.config().latent_dim;
  const std::vector<Eigen::VectorXf> mean_codes = MeanCodes(train.empty() ? data : train, dim);
  std::vector<float> weights;
  if (a.class_weights == "data") {
    weights = nn::Stage2ClassWeights(train.empty() ? data : train);
  } else if (a.class_weights == "reference") {
    weights = nn::Stage2ReferenceClassWeights();
  }
  std::printf("model %s (%s); mean-code baseline from %s\n", a.model.c_str(),
              model.config().ToString().c_str(),
              train.empty() ? "the evaluated proposals themselves (no --train)" : "--train");
  const Stage2Metrics m = EvaluateStage2(model, data, mean_codes, weights);
  PrintMetrics(m);
  if (!a.json.empty()) {
    std::ofstream f(a.json);
    if (!f) throw Error("cannot write '" + a.json + "'");
    f << MetricsJson(m).dump(1) << "\n";
  }
}

void SetupEval(CLI::App& app) {
  auto a = std::make_shared<EvalArgs>();
  app.add_option("--model", a->model, "stage-2 weights");
  app.add_option("--data", a->data, "held-out caches (dimr stage2 prepare)")->required();
  app.add_option("--train", a->train, "training caches (the mean-code baseline)");
  app.add_option("--class-weights", a->class_weights, "loss weights: data | reference | none");
  app.add_option("--json", a->json, "write the metrics as JSON");
  app.callback([a]() { RunEval(*a); });
}

// ---------------------------------------------------------------- check-gt
// Does decoding a GT code and placing it by the GT box give back the GT object? For every CAD
// instance: the CAD mesh placed by the 9-DoF alignment (the truth), its AABB in the box frame
// (must be the box), and the decoded GT code placed by the box (v -> Rz(h) (v * size / 2s) + c,
// s = 1 - 1/R the BSP normalisation) compared by Chamfer distance, also against the same mesh
// placed with the heading turned by 90 degrees (a frame error would make that one closer).
struct CheckArgs {
  std::string scans, bsp = "models/bsp/bsp.pt", json;
  int limit = 2, max_instances = 0;
};

void RunCheckGt(const CheckArgs& a) {
  const Root root = ResolveRoot(a.scans);
  const nn::BspModel bsp = nn::BspModel::Load(a.bsp);
  pipeline::BspMeshOptions mo;
  ApplyBspDilation(a.bsp, BspDilation(), &mo);
  const auto convexes = bsp.ConvexPlanes();
  const std::map<std::string, Eigen::VectorXf> codes = EncodeTree(bsp, root.shapenet, 0);
  const double s = 1.0 - 1.0 / bsp.config().resolution;
  std::vector<double> box_err, cd, cd_rot, rel;
  int n = 0;
  for (const std::string& name : SceneNames(root.scans, a.limit)) {
    const data::SynthScene scene = data::ReadScanNetScene((fs::path(root.scans) / name).string());
    for (const data::SynthInstance& in : scene.instances) {
      if (in.cad_class < 0 || in.model_id.empty()) continue;
      if (a.max_instances > 0 && n >= a.max_instances) break;
      const auto it = codes.find(in.model_id);
      if (it == codes.end()) throw ParseError(root.shapenet, "no model " + in.model_id);
      const std::string obj =
          (fs::path(root.shapenet) / data::ShapeNetRelativePath(in.synset, in.model_id)).string();
      geometry::TriangleMesh cad = data::ReadShapeNetModel(obj, in.synset).mesh;
      // The truth: the raw OBJ vertices q placed by p = t + R diag(scale) q.
      const geometry::TriangleMesh raw = geometry::ReadMesh(obj);
      geometry::TriangleMesh truth = raw;
      const Eigen::Matrix3d R = in.rotation.toRotationMatrix();
      for (auto& v : truth.vertices) v = in.translation + R * in.scale.cwiseProduct(v);
      // AABB of the truth in the box frame vs the box.
      const Eigen::Matrix3d B = in.box.Rotation();
      Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
      for (const auto& v : truth.vertices) {
        const Eigen::Vector3d u = B.transpose() * (v - in.box.center);
        lo = lo.cwiseMin(u);
        hi = hi.cwiseMax(u);
      }
      box_err.push_back(std::max((lo + 0.5 * in.box.size).cwiseAbs().maxCoeff(),
                                 (hi - 0.5 * in.box.size).cwiseAbs().maxCoeff()));
      // Decoded GT code, placed by the box (and by the box turned by 90 degrees).
      const Eigen::VectorXf mu = it->second.head(bsp.config().latent_dim);
      const geometry::TriangleMesh dec =
          pipeline::ExtractBspMesh(bsp.DecodePlanes(mu, in.cad_class), convexes, mo).mesh;
      if (dec.vertices.empty()) continue;
      auto place = [&](double extra_heading) {
        geometry::OrientedBox b = in.box;
        b.heading += extra_heading;
        const Eigen::Matrix3d Rb = b.Rotation();
        geometry::TriangleMesh m = dec;
        for (auto& v : m.vertices) v = b.center + Rb * v.cwiseProduct(b.size / (2 * s));
        return m;
      };
      const auto truth_pts = eval::ChamferSamples(truth, 1, 2048);
      const double d = eval::ChamferDistance(eval::ChamferSamples(place(0), 2, 2048), truth_pts);
      const double d90 =
          eval::ChamferDistance(eval::ChamferSamples(place(M_PI / 2), 2, 2048), truth_pts);
      cd.push_back(d);
      cd_rot.push_back(d90);
      rel.push_back(d / in.box.size.norm());
      (void)cad;
      ++n;
    }
  }
  if (n == 0) throw InvalidArgument("check-gt: no CAD instances in " + root.scans);
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  auto maxv = [](const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); };
  int rot_better = 0;
  for (std::size_t i = 0; i < cd.size(); ++i) rot_better += cd_rot[i] < cd[i] ? 1 : 0;
  std::printf("%d CAD instances: CAD AABB vs GT box max error %.4f m (median %.4f)\n", n,
              maxv(box_err), median(box_err));
  std::printf(
      "decoded GT code placed by the GT box: Chamfer median %.4f m, max %.4f m, median "
      "relative to the box diagonal %.4f; with the heading turned 90 deg: median %.4f m "
      "(%d of %zu closer)\n",
      median(cd), maxv(cd), median(rel), median(cd_rot), rot_better, cd.size());
  if (!a.json.empty()) {
    nlohmann::json j{{"instances", n},
                     {"box_error_max", maxv(box_err)},
                     {"chamfer_median", median(cd)},
                     {"chamfer_max", maxv(cd)},
                     {"chamfer_relative_median", median(rel)},
                     {"chamfer_rotated_median", median(cd_rot)},
                     {"rotated_closer", rot_better}};
    std::ofstream f(a.json);
    f << j.dump(1) << "\n";
  }
}

void SetupCheckGt(CLI::App& app) {
  auto a = std::make_shared<CheckArgs>();
  app.add_option("--scans", a->scans, "SynthScan root (scans/ + shapenet/)")->required();
  app.add_option("--bsp", a->bsp, "BSP-CVAE weights");
  app.add_option("--limit", a->limit, "first N scenes");
  app.add_option("--max-instances", a->max_instances, "at most N instances (0 = all)");
  app.add_option("--json", a->json, "write the numbers as JSON");
  app.callback([a]() { RunCheckGt(*a); });
}

const Registrar kPrepare(
    "stage2", "prepare",
    "Rooms -> stage-1 proposals (canonicalised) + GT targets and codes -> cache", &SetupPrepare);
const Registrar kEval("stage2", "eval",
                      "Score AP, box IoU and latent error of a stage-2 model on held-out proposals",
                      &SetupEval);
const Registrar kCheck("stage2", "check-gt",
                       "GT codes decoded and placed by the GT boxes vs the placed CAD models",
                       &SetupCheckGt);
const Registrar kTrain("train", "stage2", "Train the stage-2 network on prepared proposals",
                       &SetupTrain);

}  // namespace
}  // namespace dimr::tools
#endif
