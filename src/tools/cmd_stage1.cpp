// Stage-1 commands: `dimr train stage1`, `dimr stage1 eval / calibrate / average`,
// `dimr bench stage1`.
// Torch-free: the network lives behind nn/stage1_model.h, clustering in pipeline.
#if defined(DIMR_HAVE_NN) && defined(DIMR_HAVE_PIPELINE)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "dimr/data/labels.h"
#include "dimr/data/synthscan.h"
#include "dimr/eval/seg_metrics.h"
#include "dimr/geometry/error.h"
#include "dimr/nn/stage1_model.h"
#include "dimr/pipeline/class_bias.h"
#include "dimr/pipeline/stage1_instances.h"
#include "tools/command_registry.h"
#include "tools/model_card.h"
#include "tools/render.h"
#include "tools/sha256.h"
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

nn::Stage1Config ConfigFromArg(const std::string& text) {
  if (text == "cpu") return nn::Stage1Config::CpuDefault();
  if (text == "reference") return nn::Stage1Config::Reference();
  return nn::Stage1Config::FromString(text);
}

std::vector<int> RfsToCadTable() {
  std::vector<int> t(data::kNumRfsClasses);
  for (int r = 0; r < data::kNumRfsClasses; ++r) t[r] = data::RfsToCad(r);
  return t;
}

// Every RFS class but wall and floor takes part in the instance-guided semantic vote.
std::vector<bool> ThingClasses() {
  std::vector<bool> t(data::kNumRfsClasses, true);
  t[data::kWall] = t[data::kFloor] = false;
  return t;
}

// ---------------------------------------------------------------- evaluation
struct Stage1Eval {
  eval::SemanticIouResult semantic;
  eval::InstanceApResult instances;
  double miou_present = 0;  // mean IoU over the classes with ground-truth points
  int classes_present = 0;
  // Per GT class: the most frequent wrong prediction and its share of the class's points.
  std::vector<int> confused_with;
  std::vector<double> confused_share;
  int scenes = 0;
  long long points = 0;
  double network_s = 0, cluster_s = 0;
  double heading_error_deg = 0;  // median |heading error| of matched CAD instances (IoU > 0.5)
  std::vector<std::vector<pipeline::ScoredInstance>> predictions;  // per scene (if kept)
};

// One scene through stage 1 as `dimr stage1 eval` and `dimr bench stage1` run it: the network
// (with test-time augmentation), the semantic vote, then clustering + NMS, each part timed.
struct SceneInference {
  nn::Stage1Output out;  // `semantic` after the vote
  std::vector<pipeline::ScoredInstance> instances;
  nn::Stage1Timing timing;  // the network's parts
  double network_ms = 0, vote_ms = 0, cluster_ms = 0;
};

SceneInference InferScene(const nn::Stage1Model& model, const nn::Stage1Sample& s,
                          const pipeline::Stage1InstanceConfig& cfg, int rotations, bool mirror) {
  static const std::vector<int> rfs_to_cad = RfsToCadTable();
  static const std::vector<bool> is_thing = ThingClasses();
  SceneInference r;
  const auto t0 = Clock::now();
  r.out = model.PredictAugmented(s, rotations, mirror, false, &r.timing);
  if (!cfg.class_bias.empty()) {
    r.out.semantic = pipeline::ApplyClassBias(cfg.class_bias, &r.out.semantic_prob,
                                              static_cast<int>(rfs_to_cad.size()));
  }
  const auto t1 = Clock::now();
  if (cfg.semantic_vote.radius > 0) {
    r.out.semantic = pipeline::VoteSemantics(s.points, r.out.offsets, r.out.semantic,
                                             r.out.semantic_prob, is_thing, cfg.semantic_vote);
  }
  const auto t2 = Clock::now();
  std::vector<int> cad(r.out.semantic.size());
  for (std::size_t i = 0; i < cad.size(); ++i) cad[i] = rfs_to_cad[r.out.semantic[i]];
  r.instances =
      pipeline::ExtractStage1Instances(s.points, r.out.offsets, cad, r.out.semantic_prob,
                                       r.out.heading_prob, r.out.heading_residual, rfs_to_cad, cfg);
  const auto t3 = Clock::now();
  r.network_ms = Seconds(t0, t1) * 1e3;
  r.vote_ms = Seconds(t1, t2) * 1e3;
  r.cluster_ms = Seconds(t2, t3) * 1e3;
  return r;
}

Stage1Eval EvaluateStage1(const nn::Stage1Model& model, const std::vector<nn::Stage1Sample>& scenes,
                          const pipeline::Stage1InstanceConfig& cfg, bool keep_predictions,
                          int rotations = 1, bool mirror = false) {
  Stage1Eval r;
  std::vector<int> gt_sem, pred_sem;
  std::vector<eval::InstanceScene> inst_scenes;
  std::vector<double> heading_errors;
  for (const auto& s : scenes) {
    SceneInference si = InferScene(model, s, cfg, rotations, mirror);
    const nn::Stage1Output& out = si.out;
    auto& inst = si.instances;
    r.network_s += si.network_ms / 1e3;
    r.cluster_s += (si.vote_ms + si.cluster_ms) / 1e3;
    r.points += static_cast<long long>(s.points.size());
    gt_sem.insert(gt_sem.end(), s.semantic.begin(), s.semantic.end());
    pred_sem.insert(pred_sem.end(), out.semantic.begin(), out.semantic.end());
    eval::InstanceScene is;
    is.gt_label.resize(s.points.size(), -1);
    is.gt_instance.resize(s.points.size(), -1);
    std::vector<int> inst_size(s.instances.size(), 0);
    for (std::size_t i = 0; i < s.points.size(); ++i) {
      const int k = s.instance[i];
      if (k < 0 || s.instances[k].cad_class < 0) continue;
      is.gt_label[i] = s.instances[k].cad_class;
      is.gt_instance[i] = k;
      ++inst_size[k];
    }
    for (const auto& p : inst) {
      is.preds.push_back({p.cad_class, p.score, p.points});
      // Heading error against the GT instance holding most of its points (IoU > 0.5).
      std::vector<int> count(s.instances.size(), 0);
      for (int i : p.points) {
        if (s.instance[i] >= 0) ++count[s.instance[i]];
      }
      const int best =
          static_cast<int>(std::max_element(count.begin(), count.end()) - count.begin());
      if (count.empty() || !s.instances[best].has_heading) continue;
      const double iou = static_cast<double>(count[best]) /
                         (static_cast<double>(p.points.size()) + inst_size[best] - count[best]);
      if (iou <= 0.5) continue;
      double d = std::remainder(p.heading - s.instances[best].heading, 2 * M_PI);
      heading_errors.push_back(std::abs(d) * 180.0 / M_PI);
    }
    inst_scenes.push_back(std::move(is));
    if (keep_predictions) r.predictions.push_back(std::move(inst));
  }
  r.scenes = static_cast<int>(scenes.size());
  r.semantic = eval::SemanticIou(gt_sem, pred_sem, nn::kStage1Classes);
  double sum = 0;
  for (int c = 0; c < nn::kStage1Classes; ++c) {
    if (r.semantic.tp[c] + r.semantic.fn[c] > 0) {
      sum += r.semantic.iou[c];
      ++r.classes_present;
    }
  }
  r.miou_present = r.classes_present ? sum / r.classes_present : 0;
  {
    const int nc = nn::kStage1Classes;
    std::vector<long long> confusion(static_cast<std::size_t>(nc) * nc, 0);
    for (std::size_t i = 0; i < gt_sem.size(); ++i) {
      const int g = gt_sem[i], p = pred_sem[i];
      if (g >= 0 && g < nc && p >= 0 && p < nc) ++confusion[static_cast<std::size_t>(g) * nc + p];
    }
    r.confused_with.assign(nc, -1);
    r.confused_share.assign(nc, 0.0);
    for (int g = 0; g < nc; ++g) {
      long long total = 0, best = 0;
      for (int p = 0; p < nc; ++p) {
        const long long v = confusion[static_cast<std::size_t>(g) * nc + p];
        total += v;
        if (p != g && v > best) {
          best = v;
          r.confused_with[g] = p;
        }
      }
      if (total > 0) r.confused_share[g] = static_cast<double>(best) / static_cast<double>(total);
    }
  }
  r.instances = eval::InstanceAp(inst_scenes, data::kNumCadClasses);
  if (!heading_errors.empty()) {
    std::nth_element(heading_errors.begin(), heading_errors.begin() + heading_errors.size() / 2,
                     heading_errors.end());
    r.heading_error_deg = heading_errors[heading_errors.size() / 2];
  }
  return r;
}

std::string Fmt(double v) {
  if (std::isnan(v)) return "-";
  char b[32];
  std::snprintf(b, sizeof(b), "%.3f", v);
  return b;
}

void PrintEval(const Stage1Eval& r) {
  std::printf("%d scenes, %lld points; network %.1f s, clustering %.1f s\n", r.scenes, r.points,
              r.network_s, r.cluster_s);
  std::printf("\n| RFS class | IoU | GT points | most often taken for |\n|---|---|---|---|\n");
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
    std::printf("| %s | %s | %lld | %s |\n", names[c], Fmt(r.semantic.iou[c]).c_str(),
                r.semantic.tp[c] + r.semantic.fn[c], confused.c_str());
  }
  std::printf(
      "\nsemantic mIoU over the %d classes present: %.4f (all predicted/present: %.4f), "
      "accuracy %.4f\n",
      r.classes_present, r.miou_present, r.semantic.miou, r.semantic.accuracy);
  std::printf("\n| CAD class | AP | AP@50 | AP@25 |\n|---|---|---|---|\n");
  const auto& cad = data::CadClassNames();
  for (int c = 0; c < data::kNumCadClasses; ++c) {
    std::printf("| %s | %s | %s | %s |\n", cad[c], Fmt(r.instances.class_ap[c]).c_str(),
                Fmt(r.instances.class_ap50[c]).c_str(), Fmt(r.instances.class_ap25[c]).c_str());
  }
  std::printf("| **mean** | %s | %s | %s |\n", Fmt(r.instances.map).c_str(),
              Fmt(r.instances.map50).c_str(), Fmt(r.instances.map25).c_str());
  std::printf("\nmedian heading error of matched CAD instances: %.1f deg\n", r.heading_error_deg);
}

nlohmann::json EvalJson(const Stage1Eval& r) {
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
  const auto& names = data::RfsClassNames();
  for (int c = 0; c < nn::kStage1Classes; ++c) j["semantic_iou"][names[c]] = num(r.semantic.iou[c]);
  const auto& cad = data::CadClassNames();
  for (int c = 0; c < data::kNumCadClasses; ++c) {
    j["instance"][cad[c]] = {{"ap", num(r.instances.class_ap[c])},
                             {"ap50", num(r.instances.class_ap50[c])},
                             {"ap25", num(r.instances.class_ap25[c])}};
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

// ---------------------------------------------------------------- train
struct TrainArgs {
  std::string train, val, out = "models/stage1", config = "cpu", device = "cpu";
  int epochs = 40, batch = 4, threads = 0, loader_threads = 1, checkpoint_every = 200;
  int limit_train = 0, val_scenes = 20, val_every = 1, data_threads = 2;
  double lr = 1e-3, lr_decay = 0.1, max_minutes = 0;
  std::uint64_t seed = 123;
  bool no_augment = false, no_elastic = false, rgb = false, fp32 = false, quiet = false;
  bool lr_by_time = false;
  std::string class_weights = "none";
  std::string init;  // start from these weights (fine-tuning), same configuration
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
                    double minutes, const Stage1Eval* val, const std::string& weights) {
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
  y << "  train_data: \"" << a.train << "\"\n";
  y << "  train_scenes: " << train_scenes << "\n";
  y << "  val_data: \"" << a.val << "\"\n";
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
  y << "  class_weights: " << a.class_weights << "\n";
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
  opt.device = a.device;
  opt.max_minutes = a.max_minutes;
  opt.lr_by_time = a.lr_by_time;
  opt.checkpoint_every_steps = a.checkpoint_every;
  opt.validate_every_epochs = a.val_every;
  opt.progress = !a.quiet;
  opt.augment.enabled = !a.no_augment;
  opt.augment.elastic = !a.no_elastic;
  std::filesystem::create_directories(a.out + "/checkpoint");
  opt.checkpoint_path = a.out + "/checkpoint/stage1.pt";

  const auto train = LoadScenes(a.train, a.limit_train, a.data_threads);
  std::vector<nn::Stage1Sample> val;
  if (!a.val.empty()) val = LoadScenes(a.val, a.val_scenes, a.data_threads);
  if (a.class_weights == "sqrt-inverse" || a.class_weights == "inverse") {
    const bool sq = a.class_weights == "sqrt-inverse";
    opt.class_weights = sq ? nn::SemanticClassWeights(train, config.num_classes)
                           : nn::SemanticClassWeights(train, config.num_classes, 0.1, 10.0, 1.0);
    std::printf("class weights (%s frequency):",
                sq ? "sqrt inverse" : "inverse, clamped to [0.1, 10]");
    for (float w : opt.class_weights) std::printf(" %.2f", w);
    std::printf("\n");
  } else if (a.class_weights != "none") {
    throw InvalidArgument("--class-weights must be none, sqrt-inverse or inverse, got '" +
                          a.class_weights + "'");
  }
  nn::Stage1Model model =
      a.init.empty() ? nn::Stage1Model(config, a.seed) : nn::Stage1Model::Load(a.init);
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
  std::unique_ptr<Stage1Eval> last_val;
  const pipeline::Stage1InstanceConfig icfg;
  auto on_epoch = [&](int epoch, const nn::Stage1Model& m) -> std::map<std::string, double> {
    if (val.empty()) return {};
    auto r = std::make_unique<Stage1Eval>(EvaluateStage1(m, val, icfg, false));
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
                 "training scenes: scans folder or `dimr stage1 prepare` cache")
      ->required();
  app.add_option("--val", a->val, "validation scenes (scans folder or cache); empty = none");
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
  app.add_flag("--rgb", a->rgb, "also feed colours");
  app.add_option(
      "--class-weights", a->class_weights,
      "semantic loss weights: none (reference) | sqrt-inverse | inverse (of class frequency)");
  app.add_option("--init", a->init,
                 "start from these stage-1 weights (fine-tuning; same --config; a checkpoint "
                 "in --out still takes precedence)");
  app.add_flag("--lr-by-time", a->lr_by_time,
               "with --max-minutes: decay the learning rate over the time budget rather than "
               "the epochs (hosts of unknown speed)");
  app.add_flag("--fp32", a->fp32, "store the final weights as float32 (default float16)");
  app.add_flag("--quiet", a->quiet, "no progress bar");
  app.callback([a, &app]() { RunTrain(*a, CommandLine(app)); });
}

// ---------------------------------------------------------------- eval
// "o0.03,s0.01,s0.03,s0.05": clustering passes on original (o) or shifted (s) coordinates.
std::vector<pipeline::ClusterPass> ParsePasses(const std::string& text) {
  std::vector<pipeline::ClusterPass> passes;
  std::istringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    pipeline::ClusterPass p;
    std::size_t used = 0;
    try {
      if (item.size() < 2 || (item[0] != 'o' && item[0] != 's')) throw std::invalid_argument(item);
      p.shifted = item[0] == 's';
      p.radius = std::stod(item.substr(1), &used);
    } catch (const std::logic_error&) {
      used = 0;
    }
    if (used == 0 || used + 1 != item.size() || !(p.radius > 0)) {
      throw InvalidArgument("--passes: bad pass '" + item +
                            "' (expected o<radius> or s<radius>, e.g. s0.03)");
    }
    passes.push_back(p);
  }
  if (passes.empty()) throw InvalidArgument("--passes: no pass given");
  return passes;
}

std::string BiasToString(const std::vector<float>& bias) {
  std::string r;
  for (float b : bias) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.2f", b);
    r += (r.empty() ? "" : ",") + std::string(std::string(buf) == "-0.00" ? "0.00" : buf);
  }
  return r;
}

// The comma-separated items of a card value or flag; "" and "none" have none.
std::vector<std::string> CommaItems(const std::string& text) {
  std::vector<std::string> items;
  if (text.empty() || text == "none") return items;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) items.push_back(item);
  return items;
}

// "none" / "" = no bias, else exactly kStage1Classes comma-separated finite numbers. Throws
// dimr::InvalidArgument naming the bad item.
std::vector<float> ParseClassBias(const std::string& text) {
  const std::vector<std::string> items = CommaItems(text);
  if (items.empty()) return {};
  std::vector<float> r;
  for (const std::string& item : items) {
    std::size_t used = 0;
    float v = 0;
    try {
      v = std::stof(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != item.size() || !std::isfinite(v)) {
      throw InvalidArgument("class_bias: '" + item + "' is not a finite number");
    }
    r.push_back(v);
  }
  if (r.size() != static_cast<std::size_t>(nn::kStage1Classes)) {
    throw InvalidArgument("class_bias: " + std::to_string(r.size()) + " values, expected " +
                          std::to_string(nn::kStage1Classes) + " (one per class) or 'none'");
  }
  return r;
}

std::string ClassListToString(const std::vector<int>& classes) {
  std::string r;
  for (int c : classes) r += (r.empty() ? "" : ",") + std::string(data::RfsClassNames()[c]);
  return r;
}

// "none" / "" = no class, else comma-separated RFS class names (sorted by id on return).
// Throws dimr::InvalidArgument naming an unknown name.
std::vector<int> ParseClassList(const std::string& text) {
  std::vector<int> r;
  const auto& names = data::RfsClassNames();
  for (const std::string& item : CommaItems(text)) {
    const auto it =
        std::find_if(names.begin(), names.end(), [&](const char* n) { return item == n; });
    if (it == names.end()) {
      throw InvalidArgument("vote_exclude: '" + item + "' is not an RFS class name");
    }
    r.push_back(static_cast<int>(it - names.begin()));
  }
  std::sort(r.begin(), r.end());
  r.erase(std::unique(r.begin(), r.end()), r.end());
  return r;
}

// Inference settings of `dimr stage1 eval`: clustering passes, test-time augmentation and the
// instance-guided semantic vote. A model card may recommend them in one line,
//   recommended_inference: "passes=s0.12,s0.2,s0.3 rotations=6 mirror=1 vote_radius=0.05"
// (keys optional; vote_min_points, class_bias=b0,...,b24 and vote_exclude=picture,display too,
// the last two written by `dimr stage1 calibrate`); flags given on the command line override
// it.
struct Stage1Inference {
  std::string passes;  // empty = the reference's o0.03,s0.01,s0.03,s0.05
  int rotations = 1;
  bool mirror = false;
  double vote_radius = 0;
  int vote_min_points = 20;
  std::vector<float> class_bias;  // empty = none
  std::vector<int> vote_exclude;  // RFS classes kept out of the semantic vote

  std::string ToString() const {
    std::ostringstream o;
    if (!passes.empty()) o << "passes=" << passes << " ";
    o << "rotations=" << rotations << " mirror=" << (mirror ? 1 : 0)
      << " vote_radius=" << vote_radius << " vote_min_points=" << vote_min_points;
    if (!class_bias.empty()) o << " class_bias=" << BiasToString(class_bias);
    if (!vote_exclude.empty()) o << " vote_exclude=" << ClassListToString(vote_exclude);
    return o.str();
  }
};

// Throws dimr::ParseError naming `where` for an unknown key or a bad value.
Stage1Inference ParseStage1Inference(const std::string& text, const std::string& where) {
  Stage1Inference r;
  std::istringstream in(text);
  std::string item;
  while (in >> item) {
    const std::size_t eq = item.find('=');
    const std::string key = item.substr(0, eq);
    const std::string value = eq == std::string::npos ? "" : item.substr(eq + 1);
    auto bad = [&](const std::string& why) {
      return ParseError(where, "recommended_inference: '" + item + "': " + why);
    };
    try {
      std::size_t used = 0;
      if (key == "passes") {
        try {
          ParsePasses(value);  // validates
        } catch (const InvalidArgument& e) {
          throw bad(e.what());
        }
        r.passes = value;
        continue;
      } else if (key == "rotations") {
        r.rotations = std::stoi(value, &used);
      } else if (key == "mirror") {
        if (value != "0" && value != "1") throw bad("expected 0 or 1");
        r.mirror = value == "1";
        continue;
      } else if (key == "vote_radius") {
        r.vote_radius = std::stod(value, &used);
      } else if (key == "vote_min_points") {
        r.vote_min_points = std::stoi(value, &used);
      } else if (key == "class_bias" || key == "vote_exclude") {
        try {
          if (key == "class_bias") {
            r.class_bias = ParseClassBias(value);
          } else {
            r.vote_exclude = ParseClassList(value);
          }
        } catch (const InvalidArgument& e) {
          throw bad(e.what());
        }
        continue;
      } else {
        throw bad(
            "unknown key (passes, rotations, mirror, vote_radius, vote_min_points, class_bias, "
            "vote_exclude)");
      }
      if (used != value.size()) throw bad("trailing text");
    } catch (const ParseError&) {
      throw;
    } catch (const std::exception&) {
      throw bad("not a number");
    }
  }
  return r;
}

struct EvalArgs {
  std::string model = "models/stage1/stage1.pt", scans, json, render_dir, scene_list;
  int limit = 0, render = 0, threads = 2;
  double nms = 0.3;
  int min_points = 100;
  Stage1Inference flags;                 // the values of the flags below, applied where given
  std::string class_bias, vote_exclude;  // --class-bias, --vote-exclude text
  CLI::Option *passes = nullptr, *rotations = nullptr, *mirror = nullptr, *vote_radius = nullptr,
              *vote_min_points = nullptr, *class_bias_opt = nullptr, *vote_exclude_opt = nullptr;
};

// The model card's recommended_inference overridden by the flags given; `source` names where
// the settings came from.
Stage1Inference ResolveInference(const EvalArgs& a, std::string* source) {
  Stage1Inference inf;
  *source = "defaults (reference passes, no test-time augmentation)";
  if (const auto card = ReadModelCardValue(a.model, "recommended_inference")) {
    inf = ParseStage1Inference(*card, ModelCardPath(a.model));
    *source = ModelCardPath(a.model);
  }
  if (a.passes->count()) inf.passes = a.flags.passes;
  if (a.rotations->count()) inf.rotations = a.flags.rotations;
  if (a.mirror->count()) inf.mirror = a.flags.mirror;
  if (a.vote_radius->count()) inf.vote_radius = a.flags.vote_radius;
  if (a.vote_min_points->count()) inf.vote_min_points = a.flags.vote_min_points;
  if (a.class_bias_opt->count()) inf.class_bias = ParseClassBias(a.class_bias);
  if (a.vote_exclude_opt->count()) inf.vote_exclude = ParseClassList(a.vote_exclude);
  if (inf.rotations < 1 || nn::kHeadingBins % inf.rotations != 0) {
    throw InvalidArgument("--rotations must be 1, 2, 3, 4, 6 or 12, got " +
                          std::to_string(inf.rotations));
  }
  return inf;
}

pipeline::Stage1InstanceConfig InstanceConfig(const EvalArgs& a, const Stage1Inference& inf) {
  pipeline::Stage1InstanceConfig cfg;
  cfg.nms_iou = a.nms;
  cfg.min_points = a.min_points;
  cfg.semantic_vote.radius = inf.vote_radius;
  cfg.semantic_vote.min_points = inf.vote_min_points;
  cfg.class_bias = inf.class_bias;
  cfg.semantic_vote.excluded_classes = inf.vote_exclude;
  if (!inf.passes.empty()) cfg.clustering.passes = ParsePasses(inf.passes);
  cfg.Validate();
  return cfg;
}

void RunEval(const EvalArgs& a) {
  const nn::Stage1Model model = nn::Stage1Model::Load(a.model);
  std::string source;
  const Stage1Inference inf = ResolveInference(a, &source);
  const pipeline::Stage1InstanceConfig cfg = InstanceConfig(a, inf);
  auto scenes = LoadScenes(a.scans, a.limit, a.threads);
  std::printf("model %s (%s), %zu scenes\n", a.model.c_str(), model.config().ToString().c_str(),
              scenes.size());
  std::string passes;
  for (const auto& p : cfg.clustering.passes) {
    passes += (passes.empty() ? "" : ",") + std::string(p.shifted ? "s" : "o") + Fmt(p.radius);
  }
  std::printf("inference %s (from %s and the flags)\n", inf.ToString().c_str(), source.c_str());
  std::printf("clustering passes %s, min %d points per cluster, NMS %.2f, keep > %d points\n",
              passes.c_str(), cfg.clustering.min_points, cfg.nms_iou, cfg.min_points);
  const Stage1Eval r = EvaluateStage1(model, scenes, cfg, a.render > 0, inf.rotations, inf.mirror);
  PrintEval(r);
  if (!a.json.empty()) {
    std::ofstream f(a.json);
    if (!f) throw Error("cannot write '" + a.json + "'");
    nlohmann::json j = EvalJson(r);
    j["clustering_passes"] = passes;
    j["nms_iou"] = cfg.nms_iou;
    j["min_points"] = cfg.min_points;
    j["rotations"] = inf.rotations;
    j["mirror"] = inf.mirror;
    j["vote_radius"] = inf.vote_radius;
    j["vote_min_points"] = inf.vote_min_points;
    j["class_bias"] = inf.class_bias;
    j["vote_exclude"] = ClassListToString(inf.vote_exclude);
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
}

// The flags `dimr stage1 eval` and `dimr stage1 calibrate` share.
void AddInferenceFlags(CLI::App& app, const std::shared_ptr<EvalArgs>& a) {
  app.add_option("--model", a->model, "stage-1 weights (dimr train stage1)");
  app.add_option("--scans", a->scans, "scenes: scans folder or `dimr stage1 prepare` cache")
      ->required();
  app.add_option("--limit", a->limit, "first N scenes only");
  app.add_option("--threads", a->threads, "threads reading scene folders");
  app.add_option("--nms", a->nms, "point-IoU NMS threshold");
  app.add_option("--min-points", a->min_points, "keep instances with more points than this");
  a->passes = app.add_option(
      "--passes", a->flags.passes,
      "clustering passes (o = original, s = shifted coordinates, radius in metres); default: "
      "the model card's recommended_inference, else the reference's o0.03,s0.01,s0.03,s0.05");
  a->rotations = app.add_option(
      "--rotations", a->flags.rotations,
      "test-time augmentation: average the network over this many rotations about the "
      "vertical axis (1, 2, 3, 4, 6 or 12); default: the model card's, else 1");
  a->mirror = app.add_flag("--mirror", a->flags.mirror,
                           "test-time augmentation: also average over the mirrored scene "
                           "(doubles the passes; --mirror=false turns the card's off)");
  a->vote_radius = app.add_option(
      "--vote-radius", a->flags.vote_radius,
      "instance-guided semantic vote: BFS radius (m) on the shifted thing points, 0 = "
      "per-point argmax; default: the model card's, else 0");
  a->vote_min_points = app.add_option(
      "--vote-min-points", a->flags.vote_min_points,
      "smallest cluster that votes (smaller ones keep per-point labels); default: the card's, "
      "else 20");
  a->class_bias_opt = app.add_option(
      "--class-bias", a->class_bias,
      "per-class prior correction: 25 comma-separated log offsets added to the network's "
      "log-probabilities (dimr stage1 calibrate fits them), or 'none'; default: the card's");
  a->vote_exclude_opt = app.add_option(
      "--vote-exclude", a->vote_exclude,
      "RFS classes kept out of the semantic vote (comma-separated names, e.g. picture,display), "
      "or 'none'; default: the card's");
}

void SetupEval(CLI::App& app) {
  auto a = std::make_shared<EvalArgs>();
  AddInferenceFlags(app, a);
  app.add_option("--json", a->json, "write the metrics as JSON");
  app.add_option("--render", a->render, "write GT-vs-prediction top-down PNGs of the first N");
  app.add_option("--render-dir", a->render_dir, "folder of the PNGs (default out/stage1_render)");
  app.callback([a]() { RunEval(*a); });
}

// ---------------------------------------------------------------- calibrate
struct CalibrateArgs {
  std::shared_ptr<EvalArgs> eval = std::make_shared<EvalArgs>();
  pipeline::ClassBiasFitOptions fit;
  bool choose_vote_exclude = true;
  int folds = 2;        // cross-validation folds choosing the shrink factor (0 = use `shrink`)
  double shrink = 1.0;  // factor on the fitted bias when folds = 0
  std::vector<double> shrinks{0.0, 0.25, 0.5, 0.75, 1.0};
  std::vector<double> vote_radii;  // candidate vote radii (empty = keep the configured one)
  std::string json;
};

// Labels and predictions (bias, then the semantic vote) of the scenes `idx`, appended.
void VotedLabels(const std::vector<nn::Stage1Sample>& scenes,
                 const std::vector<nn::Stage1Output>& outs, const std::vector<int>& idx,
                 const std::vector<float>& bias, const pipeline::SemanticVoteConfig& vote,
                 std::vector<int>* gt, std::vector<int>* pred) {
  static const std::vector<bool> is_thing = ThingClasses();
  for (int k : idx) {
    std::vector<float> prob = outs[k].semantic_prob;
    std::vector<int> sem = pipeline::ApplyClassBias(bias, &prob, nn::kStage1Classes);
    if (vote.radius > 0) {
      sem = pipeline::VoteSemantics(scenes[k].points, outs[k].offsets, sem, prob, is_thing, vote);
    }
    gt->insert(gt->end(), scenes[k].semantic.begin(), scenes[k].semantic.end());
    pred->insert(pred->end(), sem.begin(), sem.end());
  }
}

std::vector<int> AllScenes(std::size_t n) {
  std::vector<int> idx(n);
  std::iota(idx.begin(), idx.end(), 0);
  return idx;
}

// Mean IoU (classes present) of all scenes after bias + the semantic vote.
double VotedMiou(const std::vector<nn::Stage1Sample>& scenes,
                 const std::vector<nn::Stage1Output>& outs, const std::vector<float>& bias,
                 const pipeline::SemanticVoteConfig& vote, std::vector<double>* per_class) {
  std::vector<int> gt, pred;
  VotedLabels(scenes, outs, AllScenes(scenes.size()), bias, vote, &gt, &pred);
  return pipeline::MeanIouPresent(gt, pred, nn::kStage1Classes, per_class);
}

// Fits the bias on the scenes `idx` (biased argmax, no vote).
pipeline::ClassBiasFit FitOn(const std::vector<nn::Stage1Sample>& scenes,
                             const std::vector<nn::Stage1Output>& outs, const std::vector<int>& idx,
                             const pipeline::ClassBiasFitOptions& options) {
  std::vector<int> labels;
  std::vector<float> prob;
  for (int k : idx) {
    labels.insert(labels.end(), scenes[k].semantic.begin(), scenes[k].semantic.end());
    prob.insert(prob.end(), outs[k].semantic_prob.begin(), outs[k].semantic_prob.end());
  }
  return pipeline::FitClassBias(labels, prob, nn::kStage1Classes, options);
}

std::vector<float> Scaled(std::vector<float> bias, double factor) {
  for (float& b : bias) b = static_cast<float>(std::round(b * factor / 0.05) * 0.05);
  return bias;
}

void RunCalibrate(const CalibrateArgs& c) {
  const EvalArgs& a = *c.eval;
  if (c.folds == 1 || c.folds < 0) throw InvalidArgument("--folds must be 0 or >= 2");
  for (double f : c.shrinks) {
    if (!(f >= 0.0 && f <= 1.0)) {
      throw InvalidArgument("--shrinks: " + std::to_string(f) + " is not in [0, 1]");
    }
  }
  const nn::Stage1Model model = nn::Stage1Model::Load(a.model);
  std::string source;
  Stage1Inference inf = ResolveInference(a, &source);
  const pipeline::Stage1InstanceConfig cfg = InstanceConfig(a, inf);
  const auto scenes = LoadScenes(a.scans, a.limit, a.threads);
  if (c.folds > static_cast<int>(scenes.size())) {
    throw InvalidArgument("--folds " + std::to_string(c.folds) + " exceeds the " +
                          std::to_string(scenes.size()) + " scenes");
  }
  std::printf("model %s, %zu scenes; inference %s (from %s and the flags)\n", a.model.c_str(),
              scenes.size(), inf.ToString().c_str(), source.c_str());
  const auto t0 = Clock::now();
  std::vector<nn::Stage1Output> outs;
  for (const auto& s : scenes) outs.push_back(model.PredictAugmented(s, inf.rotations, inf.mirror));
  const auto t1 = Clock::now();
  // Shrinkage of the fitted bias towards 0, chosen by cross-validation over scenes (fold k holds
  // the scenes i with i % folds == k): each fold's bias is fitted on the other folds, and the
  // held-out predictions of all folds (bias x factor, the configured vote) are pooled into one
  // mIoU per factor. A fit on few rooms over-corrects; the factor says by how much.
  double shrink = c.shrink;
  std::vector<std::pair<double, double>> cv;  // factor, pooled held-out mIoU
  if (c.folds >= 2) {
    std::vector<std::vector<int>> gt(c.shrinks.size()), pred(c.shrinks.size());
    for (int f = 0; f < c.folds; ++f) {
      std::vector<int> train, held;
      for (int k = 0; k < static_cast<int>(scenes.size()); ++k) {
        (k % c.folds == f ? held : train).push_back(k);
      }
      const pipeline::ClassBiasFit fold_fit = FitOn(scenes, outs, train, c.fit);
      for (std::size_t s = 0; s < c.shrinks.size(); ++s) {
        VotedLabels(scenes, outs, held, Scaled(fold_fit.bias, c.shrinks[s]), cfg.semantic_vote,
                    &gt[s], &pred[s]);
      }
    }
    double best = -1;
    for (std::size_t s = 0; s < c.shrinks.size(); ++s) {
      const double m = pipeline::MeanIouPresent(gt[s], pred[s], nn::kStage1Classes);
      cv.emplace_back(c.shrinks[s], m);
      if (m > best + 1e-9) {
        best = m;
        shrink = c.shrinks[s];
      }
    }
    std::printf("%d-fold cross-validation of the shrink factor (held-out mIoU with the vote):",
                c.folds);
    for (const auto& [f, m] : cv) std::printf(" %.2f: %.4f", f, m);
    std::printf(" -> %.2f\n", shrink);
  }
  pipeline::ClassBiasFit fit = FitOn(scenes, outs, AllScenes(scenes.size()), c.fit);
  const std::vector<float> raw_bias = fit.bias;
  if (shrink != 1.0) {
    fit.bias = Scaled(fit.bias, shrink);
    // Re-score the argmax with the shrunk bias so that the table shows what is shipped.
    std::vector<int> gt, pred;
    VotedLabels(scenes, outs, AllScenes(scenes.size()), fit.bias, pipeline::SemanticVoteConfig(),
                &gt, &pred);  // default config: radius 0, no vote
    fit.miou_after = pipeline::MeanIouPresent(gt, pred, nn::kStage1Classes, &fit.iou_after);
  }
  const auto t2 = Clock::now();
  // The vote as configured (card / flags), without and with the bias.
  std::vector<double> voted_before, voted_after;
  pipeline::SemanticVoteConfig vote = cfg.semantic_vote;
  const double mv_before = VotedMiou(scenes, outs, {}, vote, &voted_before);
  double mv_after = VotedMiou(scenes, outs, fit.bias, vote, &voted_after);
  const double mv_configured = mv_after;
  // The vote radius from --vote-radii (largest voted mIoU with the bias), if given.
  std::vector<std::pair<double, double>> radii;  // radius, voted mIoU
  for (double r : c.vote_radii) {
    pipeline::SemanticVoteConfig trial = vote;
    trial.radius = r;
    std::vector<double> per;
    const double m = VotedMiou(scenes, outs, fit.bias, trial, &per);
    radii.emplace_back(r, m);
    if (m > mv_after + 1e-9) {
      vote = trial;
      mv_after = m;
      voted_after = per;
    }
  }
  if (!radii.empty()) {
    std::printf("vote radius (voted mIoU with the bias):");
    for (const auto& [r, m] : radii) std::printf(" %.3g m: %.4f", r, m);
    std::printf(" -> %.3g m\n", vote.radius);
  }
  // Then which thing classes should stay out of the vote: greedy toggles, kept when the voted
  // mIoU rises by more than 1e-4 (a vote merges small objects into their larger neighbours).
  if (vote.radius > 0 && c.choose_vote_exclude) {
    const std::vector<bool> is_thing = ThingClasses();
    for (int round = 0; round < 3; ++round) {
      bool changed = false;
      for (int k = 0; k < nn::kStage1Classes; ++k) {
        if (!is_thing[k] || std::isnan(fit.iou_before[k])) continue;
        pipeline::SemanticVoteConfig trial = vote;
        auto& ex = trial.excluded_classes;
        const auto it = std::find(ex.begin(), ex.end(), k);
        if (it == ex.end()) {
          ex.push_back(k);
        } else {
          ex.erase(it);
        }
        std::sort(ex.begin(), ex.end());
        std::vector<double> per;
        const double m = VotedMiou(scenes, outs, fit.bias, trial, &per);
        if (m > mv_after + 1e-4) {
          vote = trial;
          mv_after = m;
          voted_after = per;
          changed = true;
        }
      }
      if (!changed) break;
    }
  }
  std::printf("network %.1f s, fit %.1f s (%d sweeps, grid [%g, %g] step %g)\n", Seconds(t0, t1),
              Seconds(t1, t2), fit.sweeps, c.fit.min_bias, c.fit.max_bias, c.fit.step);
  std::printf(
      "\n| RFS class | bias | IoU argmax | with bias | IoU + vote | with bias |\n"
      "|---|---|---|---|---|---|\n");
  const auto& names = data::RfsClassNames();
  for (int k = 0; k < nn::kStage1Classes; ++k) {
    if (std::isnan(fit.iou_before[k]) && fit.bias[k] == 0.0f) continue;
    std::printf("| %s | %.2f | %s | %s | %s | %s |\n", names[k], fit.bias[k],
                Fmt(fit.iou_before[k]).c_str(), Fmt(fit.iou_after[k]).c_str(),
                Fmt(voted_before[k]).c_str(), Fmt(voted_after[k]).c_str());
  }
  std::printf(
      "\nmIoU (classes present): argmax %.4f -> %.4f with the bias; with the vote %.4f -> "
      "%.4f with the bias -> %.4f with the bias, vote radius %.3g m and vote_exclude=%s\n",
      fit.miou_before, fit.miou_after, mv_before, mv_configured, mv_after, vote.radius,
      vote.excluded_classes.empty() ? "none" : ClassListToString(vote.excluded_classes).c_str());
  inf.class_bias = fit.bias;
  inf.vote_exclude = vote.excluded_classes;
  inf.vote_radius = vote.radius;
  std::printf("model card line:\nrecommended_inference: \"%s\"\n", inf.ToString().c_str());
  if (!c.json.empty()) {
    nlohmann::json j;
    auto num = [](double v) { return std::isnan(v) ? nlohmann::json(nullptr) : nlohmann::json(v); };
    j["model"] = a.model;
    j["scans"] = a.scans;
    j["scenes"] = scenes.size();
    j["class_bias"] = fit.bias;
    j["class_bias_unshrunk"] = raw_bias;
    j["shrink"] = shrink;
    j["folds"] = c.folds;
    nlohmann::json jcv = nlohmann::json::array();
    for (const auto& [f, m] : cv) jcv.push_back({{"shrink", f}, {"heldout_miou", m}});
    j["cross_validation"] = jcv;
    j["miou_argmax"] = {{"before", fit.miou_before}, {"after", fit.miou_after}};
    j["miou_vote"] = {{"before", mv_before}, {"with_bias", mv_configured}, {"after", mv_after}};
    j["vote_exclude"] = ClassListToString(vote.excluded_classes);
    j["vote_radius"] = vote.radius;
    nlohmann::json per = nlohmann::json::object();
    for (int k = 0; k < nn::kStage1Classes; ++k) {
      per[names[k]] = {{"bias", fit.bias[k]},
                       {"iou_before", num(fit.iou_before[k])},
                       {"iou_after", num(fit.iou_after[k])},
                       {"iou_vote_before", num(voted_before[k])},
                       {"iou_vote_after", num(voted_after[k])}};
    }
    j["per_class"] = per;
    j["recommended_inference"] = inf.ToString();
    std::ofstream f(c.json);
    if (!f) throw Error("cannot write '" + c.json + "'");
    f << j.dump(2) << "\n";
  }
}

void SetupCalibrate(CLI::App& app) {
  auto c = std::make_shared<CalibrateArgs>();
  AddInferenceFlags(app, c->eval);
  app.add_option("--min-bias", c->fit.min_bias, "search grid: smallest bias (log units, <= 0)");
  app.add_option("--max-bias", c->fit.max_bias, "search grid: largest bias (>= 0)");
  app.add_option("--step", c->fit.step, "search grid step");
  app.add_option("--sweeps", c->fit.max_sweeps, "coordinate-ascent sweeps at most");
  app.add_option("--folds", c->folds,
                 "cross-validation folds (over scenes) choosing the shrink factor of the bias; 0 = "
                 "use --shrink");
  app.add_option("--shrinks", c->shrinks, "candidate shrink factors in [0, 1]")->expected(1, -1);
  app.add_option("--shrink", c->shrink, "shrink factor with --folds 0")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--vote-radii", c->vote_radii,
                 "candidate semantic-vote radii (m), the best with the bias is kept (default: the "
                 "configured radius)")
      ->expected(1, -1)
      ->check(CLI::Range(0.0, 10.0));
  app.add_flag("!--keep-vote-exclude", c->choose_vote_exclude,
               "keep the card's / --vote-exclude's classes instead of choosing them greedily");
  app.add_option("--json", c->json, "write the fitted bias and the IoUs as JSON");
  app.callback([c]() { RunCalibrate(*c); });
}

// ---------------------------------------------------------------- bench
struct BenchArgs {
  std::string model = "models/stage1/stage1.pt", json;
  int rooms = 5, points = 100000, threads = 1, repeats = 3;
  std::uint64_t seed = 11;
  int rotations = 1;  // test-time augmentation, as `dimr stage1 eval`
  bool mirror = false;
  double vote_radius = 0;
};

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

void RunBench(const BenchArgs& a) {
  const nn::Stage1Model model = nn::Stage1Model::Load(a.model);
  // Rooms scanned at raw density (the accumulated cloud a robot gets), subsampled to exactly
  // `points` points.
  data::SynthConfig sc;
  sc.scanner.density = data::ScanDensity::kRaw;
  sc.scanner.threads = 2;
  std::vector<nn::Stage1Sample> rooms;
  for (int r = 0; r < a.rooms; ++r) {
    const auto g =
        data::GenerateScene(sc, data::SceneSeed(a.seed, "test", r), data::SceneName("test", r));
    nn::Stage1Sample s = Stage1SampleFromScene(g.scene);
    std::mt19937_64 rng(a.seed + r);
    std::vector<int> idx(s.points.size());
    std::iota(idx.begin(), idx.end(), 0);
    std::shuffle(idx.begin(), idx.end(), rng);
    if (static_cast<int>(idx.size()) > a.points) idx.resize(a.points);
    nn::Stage1Sample sub;
    sub.name = s.name;
    for (int i : idx) {
      sub.points.push_back(s.points[i]);
      sub.semantic.push_back(s.semantic[i]);
      sub.instance.push_back(s.instance[i]);
      if (!s.colors.empty()) sub.colors.push_back(s.colors[i]);
    }
    sub.instances = s.instances;
    rooms.push_back(std::move(sub));
  }
  pipeline::Stage1InstanceConfig cfg;
  cfg.semantic_vote.radius = a.vote_radius;
  cfg.semantic_vote.min_points = 5;
  cfg.Validate();
  std::vector<double> vox, kmap, unet, heads, vote, clus, total;
  std::vector<long long> npts;
  for (int rep = 0; rep < a.repeats + 1; ++rep) {  // first round = warm-up
    for (const auto& s : rooms) {
      const SceneInference si = InferScene(model, s, cfg, a.rotations, a.mirror);
      if (rep == 0) continue;
      const nn::Stage1Timing& t = si.timing;
      vox.push_back(t.voxelize_ms);
      kmap.push_back(t.kernel_map_ms);
      unet.push_back(t.unet_ms);
      heads.push_back(si.network_ms - t.voxelize_ms - t.kernel_map_ms - t.unet_ms);
      vote.push_back(si.vote_ms);
      clus.push_back(si.cluster_ms);
      total.push_back(si.network_ms + si.vote_ms + si.cluster_ms);
      npts.push_back(static_cast<long long>(s.points.size()));
    }
  }
  std::printf("stage-1 inference, %s, %d rooms x %d repeats, %lld points per room, %d thread(s)\n",
              model.config().ToString().c_str(), a.rooms, a.repeats, npts.empty() ? 0 : npts[0],
              a.threads);
  std::printf("network passes per room: %d (rotations %d%s), semantic vote radius %.3g m\n",
              a.rotations * (a.mirror ? 2 : 1), a.rotations, a.mirror ? " x mirror" : "",
              a.vote_radius);
  std::printf("| step | median ms | min ms | max ms |\n|---|---|---|---|\n");
  auto row = [](const char* name, const std::vector<double>& v) {
    std::printf("| %s | %.1f | %.1f | %.1f |\n", name, Median(v),
                *std::min_element(v.begin(), v.end()), *std::max_element(v.begin(), v.end()));
  };
  row("voxelise", vox);
  row("kernel maps (rulebooks)", kmap);
  row("U-Net convolutions", unet);
  row("heads (+ batch build, softmax, copy-out, TTA averaging)", heads);
  row("semantic vote", vote);
  row("clustering (4 passes) + NMS", clus);
  row("total", total);
  if (!a.json.empty()) {
    nlohmann::json j;
    j["model"] = a.model;
    j["config"] = model.config().ToString();
    j["rooms"] = a.rooms;
    j["repeats"] = a.repeats;
    j["points_per_room"] = a.points;
    j["threads"] = a.threads;
    j["rotations"] = a.rotations;
    j["mirror"] = a.mirror;
    j["vote_radius"] = a.vote_radius;
    j["median_ms"] = {{"voxelize", Median(vox)}, {"kernel_maps", Median(kmap)},
                      {"unet", Median(unet)},    {"heads", Median(heads)},
                      {"vote", Median(vote)},    {"clustering", Median(clus)},
                      {"total", Median(total)}};
    std::ofstream f(a.json);
    if (!f) throw Error("cannot write '" + a.json + "'");
    f << j.dump(2) << "\n";
  }
}

void SetupBench(CLI::App& app) {
  auto a = std::make_shared<BenchArgs>();
  app.add_option("--model", a->model, "stage-1 weights");
  app.add_option("--rooms", a->rooms, "rooms (SynthScan test split, raw density)")
      ->check(CLI::Range(1, 100));
  app.add_option("--points", a->points, "points per room")->check(CLI::Range(1000, 5000000));
  app.add_option("--repeats", a->repeats, "timed rounds (median)")->check(CLI::Range(1, 100));
  app.add_option("--threads", a->threads, "intra-op threads")->check(CLI::Range(1, 256));
  app.add_option("--seed", a->seed, "room seed");
  app.add_option("--rotations", a->rotations,
                 "test-time augmentation: network passes over rotations (1, 2, 3, 4, 6, 12)");
  app.add_flag("--mirror", a->mirror, "test-time augmentation: also the mirrored scene");
  app.add_option("--vote-radius", a->vote_radius, "semantic vote radius (m), 0 = none");
  app.add_option("--json", a->json, "also write JSON");
  app.callback([a]() {
    nn::SetIntraOpThreads(a->threads);
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
