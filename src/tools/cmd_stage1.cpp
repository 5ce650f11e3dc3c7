// Stage-1 commands: `dimr train stage1`, `dimr stage1 eval / calibrate / average`,
// `dimr bench stage1`. Flags in, library calls, tables out: inference is
// pipeline::Stage1Segmenter (configured by pipeline::Stage1InferenceConfig from the model card
// and the flags), calibration pipeline::CalibrateStage1, the metrics eval::Stage1Metrics.
// Torch-free: the network lives behind nn/stage1_model.h.
#if defined(DIMR_HAVE_NN) && defined(DIMR_HAVE_PIPELINE)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "dimr/data/labels.h"
#include "dimr/data/synthscan.h"
#include "dimr/eval/stage1_metrics.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/ply_io.h"
#include "dimr/nn/stage1_model.h"
#include "dimr/pipeline/calibration.h"
#include "dimr/pipeline/ceiling.h"
#include "dimr/pipeline/colour_norm.h"
#include "dimr/pipeline/model_card.h"
#include "dimr/pipeline/stage1_segmenter.h"
#include "tools/command_registry.h"
#include "tools/config_options.h"
#include "tools/render.h"
#include "tools/repeated_set.h"
#include "tools/sha256.h"
#include "tools/stage1_inference_args.h"
#include "tools/stage1_scenes.h"

namespace dimr::tools {
namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// ---------------------------------------------------------------- data
// A scans folder (DIR or DIR/scans) or a cache written by `dimr stage1 prepare`.
std::vector<nn::Stage1Sample> LoadScenes(const std::string& path, int limit, int threads) {
  std::vector<nn::Stage1Sample> scenes;
  if (std::filesystem::is_regular_file(path)) {
    scenes = nn::ReadStage1Samples(path);
  } else {
    std::string dir = path;
    if (std::filesystem::is_directory(path + "/scans")) dir = path + "/scans";
    if (!std::filesystem::is_directory(dir)) {
      throw InvalidArgument("'" + path + "' is neither a scans folder nor a stage-1 cache file");
    }
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
      if (e.is_directory()) names.push_back(e.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    if (limit > 0 && static_cast<int>(names.size()) > limit) names.resize(limit);
    scenes = LoadStage1Scenes(dir, names, threads);
  }
  if (limit > 0 && static_cast<int>(scenes.size()) > limit) scenes.resize(limit);
  if (scenes.empty()) throw InvalidArgument("no scenes in '" + path + "'");
  return scenes;
}

// Several scene sets, in order: each spec is a scans folder or cache as above, optionally
// with a repeat count "PATH@N" (N in 1..100) that includes its scenes N times — to oversample
// a small set (e.g. a few SynthScan v2 rooms among many v1 rooms). `limit` applies to the
// concatenation.
std::vector<nn::Stage1Sample> LoadSceneSets(const std::vector<std::string>& specs, int limit,
                                            int threads) {
  if (specs.empty()) throw InvalidArgument("no scene set given");
  std::vector<nn::Stage1Sample> all;
  for (const std::string& spec : specs) {
    const RepeatedSet set = ParseRepeatedSet(spec, "scene set");
    const auto part = LoadScenes(set.path, 0, threads);
    for (int r = 0; r < set.repeat; ++r) all.insert(all.end(), part.begin(), part.end());
  }
  if (limit > 0 && static_cast<int>(all.size()) > limit) all.resize(limit);
  return all;
}

std::string JoinSpecs(const std::vector<std::string>& specs) {
  std::string s;
  for (const auto& p : specs) s += (s.empty() ? "" : ",") + p;
  return s;
}

nn::Stage1Config ConfigFromArg(const std::string& text) {
  if (text == "cpu") return nn::Stage1Config::CpuDefault();
  if (text == "reference") return nn::Stage1Config::Reference();
  return nn::Stage1Config::FromString(text);
}

// The inference input of a labelled scene (its points and colours, nothing else).
pipeline::PointCloudInput InputOf(const nn::Stage1Sample& s) {
  pipeline::PointCloudInput in;
  in.name = s.name;
  in.points = s.points;
  in.colors = s.colors;
  return in;
}

// ---------------------------------------------------------------- evaluation
pipeline::CeilingConfig NoCeilingRemoval() {
  pipeline::CeilingConfig c;
  c.enabled = false;
  return c;
}

struct Stage1EvalRun : eval::Stage1Metrics {
  double network_s = 0, cluster_s = 0;
  int ceilings = 0;                // scenes in which a ceiling was found and removed
  std::size_t ceiling_points = 0;  // points removed with them
  std::vector<std::vector<pipeline::ScoredInstance>> predictions;  // per scene (if kept)
  std::vector<std::vector<int>> pred_semantic;  // per scene, per point predicted RFS id (if kept)
  std::map<int, int> opening_regions;           // wall openings (wall_openings=1) per RFS class
  std::size_t opening_points = 0;               // points they relabelled
};

// Every scene through the segmenter, scored against its labels.
// With `ceiling` enabled a detected ceiling is removed first (pipeline/ceiling.h): its points
// are predicted as no class and belong to no instance.
Stage1EvalRun EvaluateScenes(const pipeline::Stage1Segmenter& segmenter,
                             const std::vector<nn::Stage1Sample>& scenes, bool keep_predictions,
                             const pipeline::CeilingConfig& ceiling = NoCeilingRemoval()) {
  Stage1EvalRun run;
  eval::Stage1MetricsAccumulator acc(nn::kStage1Classes, data::kNumCadClasses);
  for (const auto& s : scenes) {
    // cut.cloud is the scene itself when no ceiling is found.
    const pipeline::CeilingRemoval cut = pipeline::RemoveCeiling(InputOf(s), ceiling);
    pipeline::Stage1Result r = segmenter.Segment(cut.cloud);
    for (const auto& o : r.wall_openings.regions) ++run.opening_regions[o.rfs_class];
    run.opening_points += r.wall_openings.relabelled;
    if (cut.found) {
      r.semantic = pipeline::ExpandKeptLabels(r.semantic, cut.kept, s.points.size(), -1);
      for (auto& inst : r.instances)
        inst.points = pipeline::ExpandKeptPoints(inst.points, cut.kept);
      ++run.ceilings;
      run.ceiling_points += cut.removed;
    }
    run.network_s += r.timings.ms("network") / 1e3;
    run.cluster_s += (r.timings.ms("class_bias") + r.timings.ms("vote") +
                      r.timings.ms("wall_planes") + r.timings.ms("clustering")) /
                     1e3;
    eval::Stage1SceneEval e;
    e.gt_semantic = s.semantic;
    e.gt_instance = s.instance;
    for (const auto& g : s.instances)
      e.gt_instances.push_back({g.cad_class, g.has_heading, g.heading});
    if (keep_predictions) run.pred_semantic.push_back(r.semantic);
    e.pred_semantic = std::move(r.semantic);
    for (const auto& p : r.instances)
      e.preds.push_back({p.points, p.cad_class, p.score, p.heading});
    acc.Add(e);
    if (keep_predictions) run.predictions.push_back(std::move(r.instances));
  }
  static_cast<eval::Stage1Metrics&>(run) = acc.Result();
  return run;
}

std::string Fmt(double v) {
  if (std::isnan(v)) return "-";
  char b[32];
  std::snprintf(b, sizeof(b), "%.3f", v);
  return b;
}

// Classes with fewer GT objects than this are left out of the "supported" mean (--min-objects).
constexpr int kDefaultMinObjects = 10;

void PrintEval(const Stage1EvalRun& r, int min_objects = kDefaultMinObjects) {
  std::printf("%d scenes, %lld points; network %.1f s, clustering %.1f s\n", r.scenes, r.points,
              r.network_s, r.cluster_s);
  std::printf(
      "\n| RFS class | IoU | GT points | GT objects (scenes) | most often taken for |\n"
      "|---|---|---|---|---|\n");
  const auto& names = data::RfsClassNames();
  for (int c = 0; c < nn::kStage1Classes; ++c) {
    if (r.semantic.tp[c] + r.semantic.fn[c] + r.semantic.fp[c] == 0) continue;
    std::string confused = "-";
    if (r.confused_with[c] >= 0) {
      char b[64];
      std::snprintf(b, sizeof(b), "%s (%.0f%%)", names[r.confused_with[c]],
                    100.0 * r.confused_share[c]);
      confused = b;
    }
    std::printf("| %s | %s | %lld | %d (%d) | %s |\n", names[c], Fmt(r.semantic.iou[c]).c_str(),
                r.semantic.tp[c] + r.semantic.fn[c], r.gt_objects[c], r.gt_scenes[c],
                confused.c_str());
  }
  std::printf(
      "\nsemantic mIoU over the %d classes present: %.4f (all predicted/present: %.4f), "
      "accuracy %.4f\n",
      r.classes_present, r.miou_present, r.semantic.miou, r.semantic.accuracy);
  int supported = 0;
  const double supported_miou = eval::SupportedMiou(r, min_objects, &supported);
  std::printf("semantic mIoU over the %d classes with >= %d GT objects: %.4f\n", supported,
              min_objects, supported_miou);
  std::printf("\n| CAD class | AP | AP@50 | AP@25 | GT instances |\n|---|---|---|---|---|\n");
  const auto& cad = data::CadClassNames();
  int gt_total = 0;
  for (int c = 0; c < data::kNumCadClasses; ++c) {
    std::printf("| %s | %s | %s | %s | %d |\n", cad[c], Fmt(r.instances.class_ap[c]).c_str(),
                Fmt(r.instances.class_ap50[c]).c_str(), Fmt(r.instances.class_ap25[c]).c_str(),
                r.instances.gt_instances[c]);
    gt_total += r.instances.gt_instances[c];
  }
  std::printf("| **mean** | %s | %s | %s | %d |\n", Fmt(r.instances.map).c_str(),
              Fmt(r.instances.map50).c_str(), Fmt(r.instances.map25).c_str(), gt_total);
  std::printf("\nmedian heading error of matched CAD instances: %.1f deg\n", r.heading_error_deg);
}

nlohmann::json EvalJson(const Stage1EvalRun& r, int min_objects = kDefaultMinObjects) {
  nlohmann::json j;
  auto num = [](double v) { return std::isnan(v) ? nlohmann::json(nullptr) : nlohmann::json(v); };
  j["scenes"] = r.scenes;
  j["points"] = r.points;
  j["network_seconds"] = r.network_s;
  j["cluster_seconds"] = r.cluster_s;
  j["miou_present"] = r.miou_present;
  j["classes_present"] = r.classes_present;
  j["miou"] = r.semantic.miou;
  j["accuracy"] = r.semantic.accuracy;
  int supported = 0;
  j["miou_supported"] = eval::SupportedMiou(r, min_objects, &supported);
  j["classes_supported"] = supported;
  j["supported_min_objects"] = min_objects;
  const auto& names = data::RfsClassNames();
  for (int c = 0; c < nn::kStage1Classes; ++c) {
    j["semantic_iou"][names[c]] = num(r.semantic.iou[c]);
    j["semantic_support"][names[c]] = {{"points", r.semantic.tp[c] + r.semantic.fn[c]},
                                       {"objects", r.gt_objects[c]},
                                       {"scenes", r.gt_scenes[c]}};
  }
  const auto& cad = data::CadClassNames();
  for (int c = 0; c < data::kNumCadClasses; ++c) {
    j["instance"][cad[c]] = {{"ap", num(r.instances.class_ap[c])},
                             {"ap50", num(r.instances.class_ap50[c])},
                             {"ap25", num(r.instances.class_ap25[c])},
                             {"gt_instances", r.instances.gt_instances[c]}};
  }
  j["map"] = r.instances.map;
  j["map50"] = r.instances.map50;
  j["map25"] = r.instances.map25;
  j["heading_error_deg_median"] = r.heading_error_deg;
  return j;
}

// Top-down pictures: ground-truth CAD instances | predicted instances, side by side.
data::SynthScene ColouredScene(const nn::Stage1Sample& s, const std::vector<int>& instance) {
  data::SynthScene scene;
  scene.name = s.name;
  scene.points.reserve(s.points.size());
  for (const auto& p : s.points) scene.points.push_back(p.cast<double>());
  scene.colors.assign(s.points.size(), geometry::Color(128, 128, 128));
  scene.instance = instance;
  return scene;
}

void RenderComparison(const nn::Stage1Sample& s, const std::vector<pipeline::ScoredInstance>& pred,
                      const std::string& path) {
  std::vector<int> gt(s.points.size(), 0), pr(s.points.size(), 0);
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    const int k = s.instance[i];
    if (k >= 0 && s.instances[k].cad_class >= 0) gt[i] = k + 1;
  }
  for (std::size_t k = 0; k < pred.size(); ++k) {
    for (int i : pred[k].points) pr[i] = static_cast<int>(k) + 1000;
  }
  const double mpp = 0.02;
  const data::RgbImage a = data::RenderTopDown(ColouredScene(s, gt), mpp, true);
  const data::RgbImage b = data::RenderTopDown(ColouredScene(s, pr), mpp, true);
  const int gap = 8, w = a.width + gap + b.width, h = std::max(a.height, b.height);
  std::vector<std::uint8_t> img(static_cast<std::size_t>(w) * h * 3, 255);
  auto blit = [&](const data::RgbImage& src, int x0) {
    for (int y = 0; y < src.height; ++y) {
      std::copy_n(&src.rgb[static_cast<std::size_t>(y) * src.width * 3], src.width * 3,
                  &img[(static_cast<std::size_t>(y) * w + x0) * 3]);
    }
  };
  blit(a, 0);
  blit(b, a.width + gap);
  WritePng(path, w, h, img);
}

// One scene as a labelled point cloud for inspection outside dimr (CloudCompare, MeshLab, a
// script): x y z, the input colour, and per point gt_label / pred_label (RFS-25 ids, -1 = none)
// and gt_instance / pred_instance (-1 = none; predicted instances in the order the evaluation
// scored them).
void WriteLabelledCloud(const nn::Stage1Sample& s, const std::vector<int>& pred_semantic,
                        const std::vector<pipeline::ScoredInstance>& pred,
                        const std::string& path) {
  const std::size_t n = s.points.size();
  if (pred_semantic.size() != n) {
    throw InvalidArgument("stage1 eval --dump: scene '" + s.name + "' has " + std::to_string(n) +
                          " points but " + std::to_string(pred_semantic.size()) +
                          " predicted labels");
  }
  geometry::PointCloud cloud;
  cloud.points.reserve(n);
  for (const auto& p : s.points) cloud.points.push_back(p.cast<double>());
  if (s.colors.size() == n) {
    cloud.colors.reserve(n);
    for (const auto& c : s.colors) {
      const Eigen::Vector3f v = (c.cwiseMax(0.f).cwiseMin(1.f) * 255.f).array().round();
      cloud.colors.push_back(v.cast<std::uint8_t>());
    }
  }
  std::vector<double> gt(n), pr(n), gt_inst(n), pr_inst(n, -1.0);
  for (std::size_t i = 0; i < n; ++i) {
    gt[i] = s.semantic[i] >= 0 && s.semantic[i] < nn::kStage1Classes ? s.semantic[i] : -1;
    pr[i] = pred_semantic[i];
    gt_inst[i] = s.instance[i];
  }
  for (std::size_t k = 0; k < pred.size(); ++k) {
    for (int i : pred[k].points) pr_inst[static_cast<std::size_t>(i)] = static_cast<double>(k);
  }
  cloud.SetAttribute("gt_label", geometry::ScalarType::kInt16, std::move(gt));
  cloud.SetAttribute("pred_label", geometry::ScalarType::kInt16, std::move(pr));
  cloud.SetAttribute("gt_instance", geometry::ScalarType::kInt32, std::move(gt_inst));
  cloud.SetAttribute("pred_instance", geometry::ScalarType::kInt32, std::move(pr_inst));
  geometry::WritePly(path, cloud);
}

std::string PassesText(const pipeline::Stage1InferenceConfig& c) {
  std::string passes;
  for (const auto& p : c.passes) {
    passes += (passes.empty() ? "" : ",") + std::string(p.shifted ? "s" : "o") + Fmt(p.radius);
  }
  return passes;
}

// ---------------------------------------------------------------- train
struct TrainArgs {
  std::vector<std::string> train, val;  // scene sets (LoadSceneSets), concatenated
  std::string out = "models/stage1", config = "cpu", device = "cpu";
  int epochs = 40, batch = 4, threads = 0, loader_threads = 1, checkpoint_every = 200;
  int limit_train = 0, val_scenes = 20, val_every = 1, data_threads = 2;
  double lr = 1e-3, lr_decay = 0.1, max_minutes = 0;
  double wall_plane_weight = 1;   // semantic-loss weight of non-wall points in a wall's plane
  double wall_plane_context = 0;  // m: also weight the wall this close to them (0 = off)
  std::uint64_t seed = 123;
  bool no_augment = false, no_elastic = false, rgb = false, fp32 = false, quiet = false;
  bool lr_by_time = false;
  std::string class_weights = "none";
  std::string init;     // start from these weights (fine-tuning), same configuration
  std::string realism;  // --augment: nn::RealismAugment text form (off by default)
};

// Opens the per-step CSV for appending from `first_step` on: rows of a previous run at or after
// that step (training resumed from an earlier checkpoint) are dropped, so every step appears once.
void OpenStepLog(const std::string& path, long long first_step, std::ofstream* csv) {
  const char* header =
      "step,epoch,lr,loss,semantic,offset_norm,offset_dir,heading_cls,heading_res,seconds,"
      "data_ms,voxelize_ms,kernel_map_ms,unet_ms,loss_ms,backward_ms,optimizer_ms";
  std::vector<std::string> keep;
  if (std::ifstream in(path); in) {
    std::string line;
    while (std::getline(in, line)) {
      if (line.empty() || line == header) continue;
      try {
        if (std::stoll(line.substr(0, line.find(','))) < first_step) keep.push_back(line);
      } catch (const std::logic_error&) {
        // not a data row
      }
    }
  }
  csv->open(path, std::ios::trunc);
  if (!*csv) throw Error("cannot write '" + path + "'");
  *csv << header << "\n";
  for (const auto& l : keep) *csv << l << "\n";
}

void WriteModelCard(const TrainArgs& a, const std::string& command, const nn::Stage1Model& model,
                    std::size_t train_scenes, std::size_t val_scenes, long long steps,
                    double minutes, const Stage1EvalRun* val, const std::string& weights) {
  std::ofstream y(a.out + "/model.yaml");
  y << "name: stage1\n";
  y << "description: DIMR stage 1 (sparse U-Net + semantic 25 / offset / 12-bin heading heads), "
       "dimr-method.md sections 1-3\n";
  y << "architecture: \"" << model.config().ToString() << "\"\n";
  y << "parameters: " << model.NumParameters() << "\n";
  y << "input: network frame (x-y centred on the cloud, floor at z = 0), features xyz"
    << (model.config().input.use_rgb ? " + rgb" : "") << ", voxel "
    << 100.0 / model.config().input.scale << " cm\n";
  y << "label_set: rfs25\n";
  y << "training:\n";
  y << "  command: \"" << command << "\"\n";
  y << "  seed: " << a.seed << "\n";
  y << "  train_data: \"" << JoinSpecs(a.train) << "\"\n";
  y << "  train_scenes: " << train_scenes << "\n";
  y << "  val_data: \"" << JoinSpecs(a.val) << "\"\n";
  y << "  val_scenes: " << val_scenes << "\n";
  y << "  steps: " << steps << "\n";
  y << "  batch_size: " << a.batch << "\n";
  y << "  minutes_this_run: " << minutes << "\n";
  y << "  device: " << a.device << "\n";
  y << "  lr: " << a.lr << "\n";
  y << "  lr_decay: " << a.lr_decay << "\n";
  y << "  augmentation: "
    << (a.no_augment ? "none"
                     : (a.no_elastic ? "affine + crop (no elastic)" : "affine + elastic + crop"))
    << "\n";
  if (!a.no_augment && !a.realism.empty())
    y << "  realism_augmentation: \"" << nn::RealismAugment::FromString(a.realism).ToString()
      << "\"\n";
  y << "  class_weights: " << a.class_weights << "\n";
  if (a.wall_plane_weight != 1) y << "  wall_plane_weight: " << a.wall_plane_weight << "\n";
  if (a.wall_plane_context > 0)  // RunTrain refuses it without a weight
    y << "  wall_plane_context: " << a.wall_plane_context << "\n";
  if (a.lr_by_time) y << "  lr_schedule: by time (decay reached at --max-minutes)\n";
  if (!a.init.empty()) y << "  initialised_from: \"" << a.init << "\"\n";
  if (val) {
    y << "metrics_val:\n";
    y << "  semantic_miou_present: " << val->miou_present << "\n";
    y << "  instance_ap50_cad: " << val->instances.map50 << "\n";
    y << "  instance_ap25_cad: " << val->instances.map25 << "\n";
    y << "  instance_ap_cad: " << val->instances.map << "\n";
    y << "  heading_error_deg_median: " << val->heading_error_deg << "\n";
  }
  y << "weights:\n";
  y << "  file: " << std::filesystem::path(weights).filename().string() << "\n";
  y << "  dtype: " << (a.fp32 ? "float32" : "float16") << "\n";
  y << "  sha256: " << Sha256File(weights) << "\n";
}

void RunTrain(const TrainArgs& a, const std::string& command) {
  const auto t_start = Clock::now();
  if (a.wall_plane_context > 0 && a.wall_plane_weight == 1) {
    throw InvalidArgument("--wall-plane-context " + std::to_string(a.wall_plane_context) +
                          " needs --wall-plane-weight W (W != 1)");
  }
  nn::Stage1Config config = ConfigFromArg(a.config);
  if (a.rgb) config.input.use_rgb = true;
  nn::Stage1TrainOptions opt;
  opt.epochs = a.epochs;
  opt.batch_size = a.batch;
  opt.learning_rate = a.lr;
  opt.lr_decay = a.lr_decay;
  opt.seed = a.seed;
  opt.threads = a.threads;
  opt.loader_threads = a.loader_threads;
  opt.device = nn::DeviceNames().Name(nn::DeviceNames().Parse(a.device));
  opt.max_minutes = a.max_minutes;
  opt.lr_by_time = a.lr_by_time;
  opt.checkpoint_every_steps = a.checkpoint_every;
  opt.validate_every_epochs = a.val_every;
  opt.progress = !a.quiet;
  opt.augment.enabled = !a.no_augment;
  opt.augment.elastic = !a.no_elastic;
  if (!a.realism.empty()) opt.augment.realism = nn::RealismAugment::FromString(a.realism);
  std::filesystem::create_directories(a.out + "/checkpoint");
  opt.checkpoint_path = a.out + "/checkpoint/stage1.pt";

  auto train = LoadSceneSets(a.train, a.limit_train, a.data_threads);
  if (a.wall_plane_weight != 1) {
    std::size_t hard = 0, labelled = 0;
    std::vector<std::size_t> by_class(nn::kStage1Classes, 0);
    nn::InWallPlaneConfig plane;
    plane.wall_context = a.wall_plane_context;
    for (auto& sample : train) {
      hard += nn::SetInWallPlaneWeights(&sample, static_cast<float>(a.wall_plane_weight), plane);
      for (std::size_t i = 0; i < sample.semantic.size(); ++i) {
        if (sample.semantic[i] == nn::kStage1Ignore) continue;
        ++labelled;
        if (!sample.weight.empty() && sample.weight[i] != 1.0f) ++by_class[sample.semantic[i]];
      }
    }
    char context[96] = "";
    if (a.wall_plane_context > 0) {
      std::snprintf(context, sizeof(context), " and the wall within %g m of them",
                    a.wall_plane_context);
    }
    std::printf(
        "wall-plane weight %g on %zu points (%.2f %% of the labelled points): non-wall "
        "points in the plane of a labelled wall%s; by class:",
        a.wall_plane_weight, hard, labelled ? 100.0 * hard / labelled : 0.0, context);
    for (int c = 0; c < nn::kStage1Classes; ++c) {
      if (by_class[c] > 0) std::printf(" %s %zu", labels::RfsClassNames()[c], by_class[c]);
    }
    std::printf("\n");
  }
  std::vector<nn::Stage1Sample> val;
  if (!a.val.empty()) val = LoadSceneSets(a.val, a.val_scenes, a.data_threads);
  const nn::ClassWeighting weighting = nn::ClassWeightingNames().Parse(a.class_weights);
  if (weighting != nn::ClassWeighting::kNone) {
    opt.class_weights = nn::SemanticClassWeights(train, weighting, config.num_classes);
    std::printf("class weights (%s frequency):", weighting == nn::ClassWeighting::kSqrtInverse
                                                     ? "sqrt inverse"
                                                     : "inverse, clamped to [0.1, 10]");
    for (float w : opt.class_weights) std::printf(" %.2f", w);
    std::printf("\n");
  }
  nn::Stage1Model model =
      a.init.empty() ? nn::Stage1Model(config, a.seed) : nn::Stage1Model::Load(a.init);
  nn::Stage1Config init_without_colour = model.config();
  init_without_colour.input.use_rgb = false;
  if (!a.init.empty() && model.config().input.use_rgb && !config.input.use_rgb &&
      init_without_colour.ToString() == config.ToString()) {
    // A geometry-only fine-tune of a colour model: the colour input weights are dropped.
    model = nn::Stage1Model::LoadWithoutColour(a.init);
    std::printf("--init %s: colour input dropped (rgb=1 -> rgb=0)\n", a.init.c_str());
  }
  nn::Stage1Config init_at_scale = model.config();
  init_at_scale.input.scale = config.input.scale;
  if (!a.init.empty() && model.config().input.scale != config.input.scale &&
      init_at_scale.ToString() == config.ToString()) {
    // A fine-tune at another voxel size: the weights as they are, the grid of --config.
    const double from = model.config().input.scale;
    model = nn::Stage1Model::LoadAtScale(a.init, config.input.scale);
    std::printf("--init %s: voxel size %.4g m -> %.4g m (scale %g -> %g)\n", a.init.c_str(),
                1.0 / from, 1.0 / config.input.scale, from, config.input.scale);
  }
  nn::Stage1Config init_deeper = model.config();
  init_deeper.reps = config.reps;
  if (!a.init.empty() && model.config().reps < config.reps &&
      init_deeper.ToString() == config.ToString()) {
    // A fine-tune with more residual blocks: the added blocks start as the identity.
    const int from = model.config().reps;
    model = nn::Stage1Model::LoadDeeper(a.init, config.reps);
    std::printf(
        "--init %s: residual blocks per level and side %d -> %d (added blocks start as "
        "the identity)\n",
        a.init.c_str(), from, config.reps);
  }
  if (model.config().ToString() != config.ToString()) {
    throw InvalidArgument("--init '" + a.init + "' holds a model of configuration '" +
                          model.config().ToString() + "', not the --config '" + config.ToString() +
                          "'");
  }
  if (!a.init.empty()) std::printf("initialised from %s\n", a.init.c_str());
  long long points = 0;
  for (const auto& s : train) points += static_cast<long long>(s.points.size());
  std::printf(
      "stage 1 %s, %lld parameters; %zu training scenes (%lld points), %zu validation "
      "scenes (loaded in %.1f s)\n",
      config.ToString().c_str(), static_cast<long long>(model.NumParameters()), train.size(),
      points, val.size(), Seconds(t_start, Clock::now()));
  std::fflush(stdout);

  const std::string log_path = a.out + "/train_log.csv";
  std::ofstream csv;
  const bool fresh_val = !std::filesystem::exists(a.out + "/val_log.csv");
  std::ofstream vcsv(a.out + "/val_log.csv", std::ios::app);
  if (fresh_val) vcsv << "epoch,miou_present,map50,map25,map,heading_error_deg,seconds\n";
  long long last_step = 0;
  std::unique_ptr<Stage1EvalRun> last_val;
  auto on_epoch = [&](int epoch, const nn::Stage1Model& m) -> std::map<std::string, double> {
    if (val.empty()) return {};
    // Plain inference (one pass, reference clustering, no vote) of the model being trained.
    auto r = std::make_unique<Stage1EvalRun>(
        EvaluateScenes(pipeline::Stage1Segmenter::Borrow(m, {}), val, false));
    vcsv << epoch << "," << r->miou_present << "," << r->instances.map50 << ","
         << r->instances.map25 << "," << r->instances.map << "," << r->heading_error_deg << ","
         << Seconds(t_start, Clock::now()) << "\n";
    vcsv.flush();
    std::map<std::string, double> out{{"val_miou", r->miou_present},
                                      {"val_ap50", r->instances.map50},
                                      {"val_ap25", r->instances.map25},
                                      {"val_heading_err_deg", r->heading_error_deg}};
    last_val = std::move(r);
    return out;
  };
  const auto logs = model.Train(
      train, opt,
      [&](const nn::Stage1StepLog& s) {
        if (!csv.is_open()) OpenStepLog(log_path, s.step, &csv);
        last_step = s.step;
        csv << s.step << "," << s.epoch << "," << s.lr << "," << s.loss.total << ","
            << s.loss.semantic << "," << s.loss.offset_norm << "," << s.loss.offset_dir << ","
            << s.loss.heading_cls << "," << s.loss.heading_res << "," << s.seconds << ","
            << s.data_ms << "," << s.voxelize_ms << "," << s.kernel_map_ms << "," << s.unet_ms
            << "," << s.loss_ms << "," << s.backward_ms << "," << s.optimizer_ms << "\n";
        if (s.step % 20 == 0) csv.flush();
      },
      on_epoch);
  csv.flush();
  const std::string weights = a.out + "/stage1.pt";
  model.Save(weights, !a.fp32);
  const double minutes = Seconds(t_start, Clock::now()) / 60.0;
  WriteModelCard(a, command, model, train.size(), val.size(), last_step, minutes, last_val.get(),
                 weights);
  std::printf("saved %s after %lld steps (%.1f min), model card %s/model.yaml\n", weights.c_str(),
              last_step, minutes, a.out.c_str());
  if (last_val) PrintEval(*last_val);
}

void SetupTrain(CLI::App& app) {
  auto a = std::make_shared<TrainArgs>();
  app.add_option("--train", a->train,
                 "training scenes: scans folder or `dimr stage1 prepare` cache; repeatable (sets "
                 "are concatenated), PATH@N includes a set N times (oversampling)")
      ->required();
  app.add_option("--val", a->val,
                 "validation scenes (scans folder or cache; repeatable like --train); none = no "
                 "validation");
  app.add_option("--out", a->out, "output folder (weights, model card, logs, checkpoint/)");
  app.add_option("--config", a->config,
                 "cpu | reference | 'scale=20 rgb=0 widths=16,32,48,64,96,128 reps=2 classes=25'");
  app.add_option("--epochs", a->epochs, "epochs")->check(CLI::Range(1, 100000));
  app.add_option("--batch", a->batch, "scenes per step")->check(CLI::Range(1, 256));
  app.add_option("--lr", a->lr, "Adam learning rate")->check(CLI::PositiveNumber);
  app.add_option("--lr-decay", a->lr_decay, "learning-rate factor reached at the end (0, 1]");
  app.add_option("--seed", a->seed, "seed (weights, shuffling, augmentation)");
  app.add_option("--threads", a->threads, "intra-op threads (0 = default)")
      ->check(CLI::Range(0, 256));
  app.add_option("--loader-threads", a->loader_threads, "batch-building threads")
      ->check(CLI::Range(1, 64));
  app.add_option("--data-threads", a->data_threads, "threads reading scene folders")
      ->check(CLI::Range(1, 64));
  app.add_option("--device", a->device, "cpu | cuda");
  app.add_option("--max-minutes", a->max_minutes, "stop (checkpointed) after this many minutes");
  app.add_option("--checkpoint-every", a->checkpoint_every, "steps between checkpoints");
  app.add_option("--limit-train", a->limit_train, "use only the first N training scenes");
  app.add_option("--val-scenes", a->val_scenes, "validation scenes used (first N)");
  app.add_option("--val-every", a->val_every, "epochs between validation passes");
  app.add_flag("--no-augment", a->no_augment, "no augmentation");
  app.add_flag("--no-elastic", a->no_elastic, "no elastic distortion");
  app.add_option("--augment", a->realism,
                 "real-scan augmentation, e.g. 'color_jitter=0.1 greyscale=0.2 color_drop=0.1 "
                 "point_noise=0.004 scale_min=0.9 scale_max=1.1 point_dropout=0.3' (keys: "
                 "color_jitter, color_contrast, color_noise, greyscale, color_drop, point_noise, "
                 "scale_min, scale_max, point_dropout; all off by default; docs/stage1.md)");
  app.add_flag("--rgb", a->rgb, "also feed colours");
  app.add_option(
      "--class-weights", a->class_weights,
      "semantic loss weights: none (reference) | sqrt-inverse | inverse (of class frequency)");
  app.add_option("--wall-plane-weight", a->wall_plane_weight,
                 "semantic-loss weight of labelled non-wall points in the plane of a labelled "
                 "wall (closed doors, flat curtains, windows, posters; 1 = off; "
                 "nn::SetInWallPlaneWeights)")
      ->check(CLI::PositiveNumber);
  app.add_option("--wall-plane-context", a->wall_plane_context,
                 "with --wall-plane-weight: also weight the wall's own points within this many "
                 "metres (in its plane) of those objects, so that both sides of the boundary "
                 "count (0 = off)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--init", a->init,
                 "start from these stage-1 weights (fine-tuning; same --config, or the same with "
                 "rgb=0 to fine-tune a colour model into a geometry-only one, or with another "
                 "scale to fine-tune it at another voxel size; a checkpoint in --out still "
                 "takes precedence)");
  app.add_flag("--lr-by-time", a->lr_by_time,
               "with --max-minutes: decay the learning rate over the time budget rather than "
               "the epochs (hosts of unknown speed)");
  app.add_flag("--fp32", a->fp32, "store the final weights as float32 (default float16)");
  app.add_flag("--quiet", a->quiet, "no progress bar");
  app.callback([a, &app]() { RunTrain(*a, CommandLine(app)); });
}

// ---------------------------------------------------------------- eval
struct EvalArgs {
  InferenceArgs inference;
  std::vector<std::string> scans;  // scene sets (LoadSceneSets)
  std::string json, render_dir, dump_dir;
  int limit = 0, render = 0, dump = 0, threads = 2;
  int min_objects = kDefaultMinObjects;
  std::string ceiling = "auto";
};

void AddSceneFlags(CLI::App& app, EvalArgs* a) {
  app.add_option("--scans", a->scans,
                 "scenes: scans folder or `dimr stage1 prepare` cache; repeatable (concatenated), "
                 "PATH@N includes a set N times")
      ->required();
  app.add_option("--limit", a->limit, "first N scenes only");
  app.add_option("--threads", a->threads, "threads reading scene folders");
}

void RunEval(const EvalArgs& a) {
  std::string source;
  const pipeline::Stage1InferenceConfig inf = ResolveInference(a.inference, &source);
  const pipeline::Stage1Segmenter segmenter =
      pipeline::Stage1Segmenter::Load(a.inference.model, inf);
  auto scenes = LoadSceneSets(a.scans, a.limit, a.threads);
  std::printf("model %s (%s), %zu scenes\n", a.inference.model.c_str(),
              segmenter.model_config().c_str(), scenes.size());
  const std::string passes = PassesText(inf);
  std::printf("inference %s (from %s and the flags)\n", inf.ToString().c_str(), source.c_str());
  std::printf("clustering passes %s, min %d points per cluster, NMS %.2f, keep > %d points\n",
              passes.c_str(), inf.cluster_min_points, inf.nms_iou, inf.min_points);
  const Stage1EvalRun r =
      EvaluateScenes(segmenter, scenes, a.render > 0 || a.dump > 0, CeilingFromFlag(a.ceiling));
  PrintEval(r, a.min_objects);
  std::printf("ceiling removed in %d of %zu scenes (%zu points; --ceiling %s)\n", r.ceilings,
              scenes.size(), r.ceiling_points, a.ceiling.c_str());
  if (inf.wall_openings) {
    std::printf("wall openings: %zu points relabelled; regions:", r.opening_points);
    for (const auto& [k, count] : r.opening_regions)
      std::printf(" %s %d", data::RfsClassNames()[k], count);
    std::printf("\n");
  }
  if (!a.json.empty()) {
    std::ofstream f(a.json);
    if (!f) throw Error("cannot write '" + a.json + "'");
    nlohmann::json j = EvalJson(r, a.min_objects);
    j["clustering_passes"] = passes;
    j["nms_iou"] = inf.nms_iou;
    j["min_points"] = inf.min_points;
    j["rotations"] = inf.rotations;
    j["mirror"] = inf.mirror;
    j["vote_radius"] = inf.vote_radius;
    j["vote_min_points"] = inf.vote_min_points;
    j["class_bias"] = inf.class_bias;
    j["vote_exclude"] = pipeline::RfsClassListToString(inf.vote_exclude);
    j["inference"] = inf.ToString();
    j["ceiling"] = a.ceiling;
    j["ceiling_scenes"] = r.ceilings;
    j["ceiling_points"] = r.ceiling_points;
    if (inf.wall_openings) {
      nlohmann::json regions = nlohmann::json::object();
      for (const auto& [k, count] : r.opening_regions) regions[data::RfsClassNames()[k]] = count;
      j["wall_openings"] = {{"points_relabelled", r.opening_points}, {"regions", regions}};
    }
    f << j.dump(2) << "\n";
  }
  if (a.render > 0) {
    const std::string dir = a.render_dir.empty() ? "out/stage1_render" : a.render_dir;
    std::filesystem::create_directories(dir);
    for (int k = 0; k < std::min<int>(a.render, static_cast<int>(scenes.size())); ++k) {
      const std::string path = dir + "/" + scenes[k].name + "_gt_vs_pred.png";
      RenderComparison(scenes[k], r.predictions[k], path);
      std::printf("wrote %s\n", path.c_str());
    }
  }
  if (a.dump > 0) {
    const std::string dir = a.dump_dir.empty() ? "out/stage1_dump" : a.dump_dir;
    std::filesystem::create_directories(dir);
    for (int k = 0; k < std::min<int>(a.dump, static_cast<int>(scenes.size())); ++k) {
      const std::string path = dir + "/" + scenes[k].name + "_labels.ply";
      WriteLabelledCloud(scenes[k], r.pred_semantic[k], r.predictions[k], path);
      std::printf("wrote %s\n", path.c_str());
    }
  }
}

void SetupEval(CLI::App& app) {
  auto a = std::make_shared<EvalArgs>();
  AddInferenceFlags(app, &a->inference);
  AddSceneFlags(app, a.get());
  app.add_option("--json", a->json, "write the metrics as JSON");
  app.add_option("--render", a->render, "write GT-vs-prediction top-down PNGs of the first N");
  app.add_option("--render-dir", a->render_dir, "folder of the PNGs (default out/stage1_render)");
  app.add_option("--dump", a->dump,
                 "write the first N scenes as labelled PLY clouds for inspection: x y z, colour, "
                 "gt_label / pred_label (RFS-25 ids, -1 none), gt_instance / pred_instance")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--dump-dir", a->dump_dir, "folder of the clouds (default out/stage1_dump)");
  app.add_option("--min-objects", a->min_objects,
                 "also print the semantic mean over the classes with at least this many GT "
                 "objects (JSON miou_supported), a mean less moved by classes that rest on one "
                 "or two objects")
      ->check(CLI::NonNegativeNumber);
  AddCeilingFlag(app, &a->ceiling);
  app.callback([a]() { RunEval(*a); });
}

// ---------------------------------------------------------------- calibrate
struct CalibrateArgs {
  EvalArgs eval;
  pipeline::CalibrationOptions options;
  std::string json;
};

void RunCalibrate(const CalibrateArgs& c) {
  const EvalArgs& a = c.eval;
  c.options.Validate();
  std::string source;
  const pipeline::Stage1InferenceConfig inf = ResolveInference(a.inference, &source);
  const pipeline::Stage1Segmenter segmenter =
      pipeline::Stage1Segmenter::Load(a.inference.model, inf);
  const auto scenes = LoadSceneSets(a.scans, a.limit, a.threads);
  if (c.options.folds > static_cast<int>(scenes.size())) {
    throw InvalidArgument("--folds " + std::to_string(c.options.folds) + " exceeds the " +
                          std::to_string(scenes.size()) + " scenes");
  }
  std::printf("model %s, %zu scenes; inference %s (from %s and the flags)\n",
              a.inference.model.c_str(), scenes.size(), inf.ToString().c_str(), source.c_str());
  const auto t0 = Clock::now();
  std::vector<pipeline::Stage1Result> outs;
  for (const auto& s : scenes) outs.push_back(segmenter.RunNetwork(InputOf(s)));
  std::vector<pipeline::CalibrationScene> cal;
  for (std::size_t k = 0; k < scenes.size(); ++k) {
    cal.push_back({&scenes[k].points, &scenes[k].semantic, &outs[k]});
  }
  const auto t1 = Clock::now();
  const pipeline::CalibrationReport rep = pipeline::CalibrateStage1(cal, inf, c.options);
  const auto t2 = Clock::now();
  const pipeline::ClassBiasFit& fit = rep.fit;
  if (!rep.cross_validation.empty()) {
    std::printf("%d-fold cross-validation of the shrink factor (held-out mIoU with the vote):",
                c.options.folds);
    for (const auto& [f, m] : rep.cross_validation) std::printf(" %.2f: %.4f", f, m);
    std::printf(" -> %.2f\n", rep.shrink);
  }
  if (!rep.radii.empty()) {
    std::printf("vote radius (voted mIoU with the bias):");
    for (const auto& [r, m] : rep.radii) std::printf(" %.3g m: %.4f", r, m);
    std::printf(" -> %.3g m\n", rep.config.vote_radius);
  }
  const pipeline::ClassBiasFitOptions& fo = c.options.fit;
  std::printf("network %.1f s, fit %.1f s (%d sweeps, grid [%g, %g] step %g)\n", Seconds(t0, t1),
              Seconds(t1, t2), fit.sweeps, fo.min_bias, fo.max_bias, fo.step);
  std::printf(
      "\n| RFS class | bias | IoU argmax | with bias | IoU + vote | with bias |\n"
      "|---|---|---|---|---|---|\n");
  const auto& names = data::RfsClassNames();
  for (int k = 0; k < nn::kStage1Classes; ++k) {
    if (std::isnan(fit.iou_before[k]) && fit.bias[k] == 0.0f) continue;
    std::printf("| %s | %.2f | %s | %s | %s | %s |\n", names[k], fit.bias[k],
                Fmt(fit.iou_before[k]).c_str(), Fmt(fit.iou_after[k]).c_str(),
                Fmt(rep.iou_vote_before[k]).c_str(), Fmt(rep.iou_vote_after[k]).c_str());
  }
  const std::string exclude = pipeline::RfsClassListToString(rep.config.vote_exclude);
  std::printf(
      "\nmIoU (classes present): argmax %.4f -> %.4f with the bias; with the vote %.4f -> "
      "%.4f with the bias -> %.4f with the bias, vote radius %.3g m and vote_exclude=%s\n",
      fit.miou_before, fit.miou_after, rep.miou_vote_before, rep.miou_vote_configured,
      rep.miou_vote_after, rep.config.vote_radius, exclude.empty() ? "none" : exclude.c_str());
  std::printf("model card line:\nrecommended_inference: \"%s\"\n", rep.config.ToString().c_str());
  if (!c.json.empty()) {
    nlohmann::json j;
    auto num = [](double v) { return std::isnan(v) ? nlohmann::json(nullptr) : nlohmann::json(v); };
    j["model"] = a.inference.model;
    j["scans"] = a.scans;
    j["scenes"] = scenes.size();
    j["class_bias"] = fit.bias;
    j["class_bias_unshrunk"] = rep.raw_bias;
    j["shrink"] = rep.shrink;
    j["folds"] = c.options.folds;
    nlohmann::json jcv = nlohmann::json::array();
    for (const auto& [f, m] : rep.cross_validation)
      jcv.push_back({{"shrink", f}, {"heldout_miou", m}});
    j["cross_validation"] = jcv;
    j["miou_argmax"] = {{"before", fit.miou_before}, {"after", fit.miou_after}};
    j["miou_vote"] = {{"before", rep.miou_vote_before},
                      {"with_bias", rep.miou_vote_configured},
                      {"after", rep.miou_vote_after}};
    j["vote_exclude"] = exclude;
    j["vote_radius"] = rep.config.vote_radius;
    nlohmann::json per = nlohmann::json::object();
    for (int k = 0; k < nn::kStage1Classes; ++k) {
      per[names[k]] = {{"bias", fit.bias[k]},
                       {"iou_before", num(fit.iou_before[k])},
                       {"iou_after", num(fit.iou_after[k])},
                       {"iou_vote_before", num(rep.iou_vote_before[k])},
                       {"iou_vote_after", num(rep.iou_vote_after[k])}};
    }
    j["per_class"] = per;
    j["recommended_inference"] = rep.config.ToString();
    std::ofstream f(c.json);
    if (!f) throw Error("cannot write '" + c.json + "'");
    f << j.dump(2) << "\n";
  }
}

void SetupCalibrate(CLI::App& app) {
  auto c = std::make_shared<CalibrateArgs>();
  AddInferenceFlags(app, &c->eval.inference);
  AddSceneFlags(app, &c->eval);
  pipeline::CalibrationOptions& o = c->options;
  app.add_option("--min-bias", o.fit.min_bias, "search grid: smallest bias (log units, <= 0)");
  app.add_option("--max-bias", o.fit.max_bias, "search grid: largest bias (>= 0)");
  app.add_option("--step", o.fit.step, "search grid step");
  app.add_option("--sweeps", o.fit.max_sweeps, "coordinate-ascent sweeps at most");
  app.add_option("--folds", o.folds,
                 "cross-validation folds (over scenes) choosing the shrink factor of the bias; 0 = "
                 "use --shrink");
  app.add_option("--shrinks", o.shrinks, "candidate shrink factors in [0, 1]")->expected(1, -1);
  app.add_option("--shrink", o.shrink, "shrink factor with --folds 0")->check(CLI::Range(0.0, 1.0));
  app.add_option("--vote-radii", o.vote_radii,
                 "candidate semantic-vote radii (m), the best with the bias is kept (default: the "
                 "configured radius)")
      ->expected(1, -1)
      ->check(CLI::Range(0.0, 10.0));
  app.add_flag("!--keep-vote-exclude", o.choose_vote_exclude,
               "keep the card's / --vote-exclude's classes instead of choosing them greedily");
  app.add_option("--json", c->json, "write the fitted bias and the IoUs as JSON");
  app.callback([c]() { RunCalibrate(*c); });
}

// ---------------------------------------------------------------- bench
// Times exactly what `dimr stage1 eval` runs: the same Stage1Segmenter with the same settings
// (model card, --preset and the inference flags), on raw-density SynthScan rooms.
struct BenchArgs {
  InferenceArgs inference;
  std::string json;
  int rooms = 5, points = 100000, threads = 1, repeats = 3;
  std::uint64_t seed = 11;
  bool cluster_sse2 = false;
};

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// /proc/cpuinfo's model name ("unknown CPU" where there is none).
std::string CpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0 && line.find(':') != std::string::npos) {
      return line.substr(line.find(':') + 2);
    }
  }
  return "unknown CPU";
}

void RunBench(const BenchArgs& a) {
  std::string source;
  const pipeline::Stage1InferenceConfig inf = ResolveInference(a.inference, &source);
  const pipeline::Stage1Segmenter segmenter =
      pipeline::Stage1Segmenter::Load(a.inference.model, inf);
  // Rooms scanned at raw density (the accumulated cloud a robot gets), subsampled to exactly
  // `points` points.
  data::SynthConfig sc;
  sc.scanner.density = data::ScanDensity::kRaw;
  sc.scanner.threads = 2;
  std::vector<pipeline::PointCloudInput> rooms;
  for (int r = 0; r < a.rooms; ++r) {
    const auto g =
        data::GenerateScene(sc, data::SceneSeed(a.seed, "test", r), data::SceneName("test", r));
    const nn::Stage1Sample s = Stage1SampleFromScene(g.scene);
    std::mt19937_64 rng(a.seed + r);
    std::vector<int> idx(s.points.size());
    std::iota(idx.begin(), idx.end(), 0);
    std::shuffle(idx.begin(), idx.end(), rng);
    if (static_cast<int>(idx.size()) > a.points) idx.resize(a.points);
    pipeline::PointCloudInput sub;
    sub.name = s.name;
    for (int i : idx) {
      sub.points.push_back(s.points[i]);
      if (!s.colors.empty()) sub.colors.push_back(s.colors[i]);
    }
    rooms.push_back(std::move(sub));
  }
  // Rows: the named stages of Stage1Result::timings ("heads" = the rest of the network time:
  // batch build, heads, softmax, copy-out, TTA averaging).
  const std::vector<std::pair<std::string, std::string>> rows = {
      {"voxelize", "voxelise"},
      {"kernel_maps", "kernel maps (rulebooks)"},
      {"unet", "U-Net convolutions"},
      {"heads", "heads (+ batch build, softmax, copy-out, TTA averaging)"},
      {"class_bias", "class bias"},
      {"vote", "semantic vote"},
      {"wall_planes", "wall planes (structure prior)"},
      {"clustering", "clustering (" + std::to_string(inf.passes.size()) + " passes) + NMS"},
      {"total", "total"}};
  std::vector<std::vector<double>> ms(rows.size());
  std::vector<double> heads_per_unet;  // per run: both times under the same load
  long long npts = 0;
  for (int rep = 0; rep < a.repeats + 1; ++rep) {  // first round = warm-up
    for (const auto& room : rooms) {
      const pipeline::Stage1Result r = segmenter.Segment(room);
      if (rep == 0) continue;
      const Timings& t = r.timings;
      const double unet = t.ms("unet");
      const double heads = t.ms("network") - t.ms("voxelize") - t.ms("kernel_maps") - unet;
      for (std::size_t k = 0; k < rows.size(); ++k) {
        ms[k].push_back(rows[k].first == "heads" ? heads : t.ms(rows[k].first));
      }
      if (unet > 0) heads_per_unet.push_back(heads / unet);
      npts = static_cast<long long>(room.size());
    }
  }
  std::printf("stage-1 inference, %s, %d rooms x %d repeats, %lld points per room, %d thread(s)\n",
              segmenter.model_config().c_str(), a.rooms, a.repeats, npts, a.threads);
  std::printf("inference %s (from %s and the flags): %d network passes per room\n",
              inf.ToString().c_str(), source.c_str(), inf.network_passes());
  std::printf("CPU %s, sparse kernels %s, heads %s, clustering %s\n", CpuModel().c_str(),
              nn::SparseKernelsInUse().c_str(), nn::Stage1HeadsKernelsInUse().c_str(),
              pipeline::ClusteringSimdPath());
  std::printf("| step | median ms | min ms | max ms |\n|---|---|---|---|\n");
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const auto& v = ms[k];
    std::printf("| %s | %.1f | %.1f | %.1f |\n", rows[k].second.c_str(), Median(v),
                *std::min_element(v.begin(), v.end()), *std::max_element(v.begin(), v.end()));
  }
  if (!heads_per_unet.empty()) {
    std::printf(
        "heads / U-Net convolutions per run: median %.3f (min %.3f, max %.3f, %zu runs)\n",
        Median(heads_per_unet), *std::min_element(heads_per_unet.begin(), heads_per_unet.end()),
        *std::max_element(heads_per_unet.begin(), heads_per_unet.end()), heads_per_unet.size());
  }
  if (!a.json.empty()) {
    nlohmann::json j;
    j["model"] = a.inference.model;
    j["config"] = segmenter.model_config();
    j["inference"] = inf.ToString();
    j["rooms"] = a.rooms;
    j["repeats"] = a.repeats;
    j["points_per_room"] = a.points;
    j["threads"] = a.threads;
    j["rotations"] = inf.rotations;
    j["mirror"] = inf.mirror;
    j["vote_radius"] = inf.vote_radius;
    j["cpu"] = CpuModel();
    j["sparse_kernels"] = nn::SparseKernelsInUse();
    j["heads_kernels"] = nn::Stage1HeadsKernelsInUse();
    j["clustering_simd"] = pipeline::ClusteringSimdPath();
    nlohmann::json m;
    for (std::size_t k = 0; k < rows.size(); ++k) m[rows[k].first] = Median(ms[k]);
    j["median_ms"] = m;
    if (!heads_per_unet.empty()) j["median_heads_per_unet"] = Median(heads_per_unet);
    std::ofstream f(a.json);
    if (!f) throw Error("cannot write '" + a.json + "'");
    f << j.dump(2) << "\n";
  }
}

void SetupBench(CLI::App& app) {
  auto a = std::make_shared<BenchArgs>();
  AddInferenceFlags(app, &a->inference);
  app.add_option("--rooms", a->rooms, "rooms (SynthScan test split, raw density)")
      ->check(CLI::Range(1, 100));
  app.add_option("--points", a->points, "points per room")->check(CLI::Range(1000, 5000000));
  app.add_option("--repeats", a->repeats, "timed rounds (median)")->check(CLI::Range(1, 100));
  app.add_option("--threads", a->threads, "intra-op threads")->check(CLI::Range(1, 256));
  app.add_option("--seed", a->seed, "room seed");
  app.add_option("--json", a->json, "also write JSON");
  app.add_flag("--cluster-sse2", a->cluster_sse2,
               "clustering distance tests on the SSE2 path even where the CPU has AVX2");
  app.callback([a]() {
    nn::SetIntraOpThreads(a->threads);
    if (a->cluster_sse2) pipeline::SetClusteringAvx2(false);
    RunBench(*a);
  });
}

// ---------------------------------------------------------------- average
struct AverageArgs {
  std::vector<std::string> models;
  std::string out;
  bool fp32 = false;
};

void SetupAverage(CLI::App& app) {
  auto a = std::make_shared<AverageArgs>();
  app.add_option("--models", a->models,
                 "stage-1 weight files of one configuration (e.g. fine-tunes of one ancestor)")
      ->required()
      ->expected(1, -1);
  app.add_option("--out", a->out, "averaged weights")->required();
  app.add_flag("--fp32", a->fp32, "store float32 instead of float16");
  app.callback([a]() {
    const nn::Stage1Model mean = nn::Stage1Model::Average(a->models);
    if (const auto dir = std::filesystem::path(a->out).parent_path(); !dir.empty()) {
      std::filesystem::create_directories(dir);
    }
    mean.Save(a->out, !a->fp32);
    std::printf("averaged %zu models (%s) -> %s, sha256 %s\n", a->models.size(),
                mean.config().ToString().c_str(), a->out.c_str(), Sha256File(a->out).c_str());
  });
}

// ---------------------------------------------------------------- colour-stats
// The range of the training rooms' colour statistics that the per-scene colour standardisation
// maps a scene into (pipeline/colour_norm.h), printed as the model card's `colour_norm=` value.
void SetupColourStats(CLI::App& app) {
  struct Args {
    std::vector<std::string> scans;
    std::string json;
    int limit = 0, threads = 2;
  };
  auto a = std::make_shared<Args>();
  app.add_option("--scans", a->scans,
                 "scenes the model may be tuned on (training, validation; never test): scans "
                 "folders or `dimr stage1 prepare` caches, repeatable")
      ->required();
  app.add_option("--limit", a->limit, "first N scenes only");
  app.add_option("--threads", a->threads, "threads reading scene folders");
  app.add_option("--json", a->json, "write the per-room and average statistics as JSON");
  app.callback([a] {
    std::vector<nn::Stage1Sample> scenes;
    std::string sources;
    for (const std::string& path : a->scans) {
      auto part = LoadScenes(path, a->limit, a->threads);
      std::move(part.begin(), part.end(), std::back_inserter(scenes));
      sources += (sources.empty() ? "" : ", ") + path;
    }
    std::vector<pipeline::ColourStats> rooms;
    nlohmann::json j_rooms = nlohmann::json::array();
    for (const auto& s : scenes) {
      if (s.colors.empty()) throw InvalidArgument("scene '" + s.name + "' has no colours");
      rooms.push_back(pipeline::MeasureColourStats(s.colors));
      j_rooms.push_back(
          {{"scene", s.name},
           {"mean", {rooms.back().mean.x(), rooms.back().mean.y(), rooms.back().mean.z()}},
           {"std", {rooms.back().std.x(), rooms.back().std.y(), rooms.back().std.z()}}});
    }
    const pipeline::ColourRange range = pipeline::RangeOfRooms(rooms);
    Eigen::Vector3f avg_m = Eigen::Vector3f::Zero(), avg_s = Eigen::Vector3f::Zero();
    for (const auto& r : rooms) {
      avg_m += r.mean / static_cast<float>(rooms.size());
      avg_s += r.std / static_cast<float>(rooms.size());
    }
    std::printf("%zu rooms of %s ([0, 1] units)\n", rooms.size(), sources.c_str());
    std::printf("| per-room | r | g | b |\n|---|---|---|---|\n");
    std::printf(
        "| mean: min / average / max | %.3f / %.3f / %.3f | %.3f / %.3f / %.3f | %.3f / %.3f / "
        "%.3f |\n",
        range.mean_min.x(), avg_m.x(), range.mean_max.x(), range.mean_min.y(), avg_m.y(),
        range.mean_max.y(), range.mean_min.z(), avg_m.z(), range.mean_max.z());
    std::printf(
        "| std: min / average / max | %.3f / %.3f / %.3f | %.3f / %.3f / %.3f | %.3f / %.3f / %.3f "
        "|\n",
        range.std_min.x(), avg_s.x(), range.std_max.x(), range.std_min.y(), avg_s.y(),
        range.std_max.y(), range.std_min.z(), avg_s.z(), range.std_max.z());
    std::printf("colour_norm=%s\n", range.ToString().c_str());
    if (!a->json.empty()) {
      std::ofstream f(a->json);
      if (!f) throw Error("cannot write '" + a->json + "'");
      f << nlohmann::json{{"scans", a->scans},
                          {"colour_norm", range.ToString()},
                          {"rooms", j_rooms}}
               .dump(2)
        << "\n";
    }
  });
}

const Registrar kColourStats(
    "stage1", "colour-stats",
    "Range of the training rooms' colour mean / spread: the model card's colour_norm value "
    "(per-scene colour standardisation of real scans)",
    &SetupColourStats);
const Registrar kTrain("train", "stage1", "Train the stage-1 point-wise network", &SetupTrain);
const Registrar kEval("stage1", "eval",
                      "Stage-1 metrics: semantic mIoU (25 classes) and instance AP (8 CAD classes)",
                      &SetupEval);
const Registrar kCalibrate(
    "stage1", "calibrate",
    "Fit per-class prior corrections (log offsets) that maximise the semantic mIoU on labelled "
    "scenes (validation); prints the model-card line",
    &SetupCalibrate);
const Registrar kAverage(
    "stage1", "average",
    "Average the weights of stage-1 models (checkpoint averaging / model soup)", &SetupAverage);
const Registrar kBench("bench", "stage1",
                       "Stage-1 inference time per room: voxelise / U-Net / heads / clustering",
                       &SetupBench);

}  // namespace
}  // namespace dimr::tools
#endif
