#include "dimr/pipeline/stage1_segmenter.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>

#include "dimr/core/labels.h"
#include "dimr/geometry/error.h"
#include "dimr/nn/stage1_model.h"
#include "dimr/pipeline/class_bias.h"
#include "dimr/pipeline/model_card.h"
#include "dimr/pipeline/wall_planes.h"

namespace dimr::pipeline {

// ---------------------------------------------------------------- classes
static_assert(kStage1RfsClasses == labels::kNumRfsClasses);

const std::vector<std::string>& Stage1RfsClassNames() {
  static const std::vector<std::string> names(labels::RfsClassNames().begin(),
                                              labels::RfsClassNames().end());
  return names;
}

const std::vector<int>& Stage1RfsToCad() {
  static const std::vector<int> table = [] {
    std::vector<int> t(labels::kNumRfsClasses);
    for (int r = 0; r < labels::kNumRfsClasses; ++r) t[r] = labels::RfsToCad(r);
    return t;
  }();
  return table;
}

std::vector<int> ParseRfsClassList(const std::string& text) {
  const auto& names = Stage1RfsClassNames();
  std::vector<int> r;
  for (const std::string& item : config::SplitList(text, /*none_is_empty=*/true)) {
    const auto it = std::find(names.begin(), names.end(), item);
    if (it == names.end()) throw InvalidArgument("'" + item + "' is not an RFS class name");
    r.push_back(static_cast<int>(it - names.begin()));
  }
  std::sort(r.begin(), r.end());
  r.erase(std::unique(r.begin(), r.end()), r.end());
  return r;
}

std::string RfsClassListToString(const std::vector<int>& classes) {
  const auto& names = Stage1RfsClassNames();
  std::string r;
  for (int c : classes) {
    r += (r.empty() ? "" : ",") +
         (c >= 0 && c < static_cast<int>(names.size()) ? names[c] : std::to_string(c));
  }
  return r;
}

std::vector<double> ParseRfsClassValues(const std::string& text) {
  const auto& names = Stage1RfsClassNames();
  const std::vector<std::string> items = config::SplitList(text, /*none_is_empty=*/true);
  if (items.empty()) return {};
  std::vector<double> r(names.size(), 0.0);
  for (const std::string& item : items) {
    const std::size_t colon = item.find(':');
    if (colon == std::string::npos) {
      throw InvalidArgument("'" + item + "' is not CLASS:VALUE (e.g. sofa:0.8)");
    }
    const std::string name = item.substr(0, colon);
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end()) throw InvalidArgument("'" + name + "' is not an RFS class name");
    const std::string number = item.substr(colon + 1);
    double v = 0;
    std::size_t used = 0;
    try {
      v = std::stod(number, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != number.size() || !std::isfinite(v) || v < 0) {
      throw InvalidArgument("'" + item + "': the value must be a finite number >= 0");
    }
    r[it - names.begin()] = v;
  }
  return r;
}

std::string RfsClassValuesToString(const std::vector<double>& values) {
  const auto& names = Stage1RfsClassNames();
  std::string r;
  for (std::size_t c = 0; c < values.size(); ++c) {
    if (values[c] == 0.0) continue;
    char num[32];
    std::snprintf(num, sizeof(num), "%g", values[c]);
    r += (r.empty() ? "" : ",") + (c < names.size() ? names[c] : std::to_string(c)) + ":" + num;
  }
  return r;
}

const config::EnumNames<Stage1Preset>& Stage1PresetNames() {
  static const config::EnumNames<Stage1Preset> names(
      "stage1 preset", {{Stage1Preset::kFast, "fast"}, {Stage1Preset::kAccurate, "accurate"}});
  return names;
}

// ---------------------------------------------------------------- passes
std::vector<ClusterPass> ParseClusterPasses(const std::string& text) {
  std::vector<ClusterPass> passes;
  for (const std::string& item : config::SplitList(text)) {
    ClusterPass p;
    double r = 0;
    if (item.size() < 2 || (item[0] != 'o' && item[0] != 's') ||
        !config::ParseDouble(item.substr(1), &r) || !(r > 0)) {
      throw InvalidArgument("bad pass '" + item +
                            "' (expected o<radius> or s<radius>, e.g. s0.03)");
    }
    p.shifted = item[0] == 's';
    p.radius = r;
    passes.push_back(p);
  }
  if (passes.empty()) throw InvalidArgument("no clustering pass given");
  return passes;
}

std::string ClusterPassesToString(const std::vector<ClusterPass>& passes) {
  std::string r;
  for (const auto& p : passes) {
    r += (r.empty() ? "" : ",") + std::string(p.shifted ? "s" : "o") +
         config::FormatDouble(p.radius);
  }
  return r;
}

// ---------------------------------------------------------------- config
namespace {

// "" when `parse` succeeds, else the message of the dimr::InvalidArgument it throws (a config
// field's setter reports a bad value this way).
template <typename F>
std::string ErrorOf(F&& parse) {
  try {
    parse();
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "";
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

std::string ParseBias(const std::string& text, std::vector<float>* out) {
  const std::vector<std::string> items = config::SplitList(text, /*none_is_empty=*/true);
  std::vector<float> r;
  for (const std::string& item : items) {
    double v = 0;
    if (!config::ParseDouble(item, &v)) return "'" + item + "' is not a finite number";
    r.push_back(static_cast<float>(v));
  }
  if (!r.empty() && r.size() != static_cast<std::size_t>(kStage1RfsClasses)) {
    return std::to_string(r.size()) + " values, expected " + std::to_string(kStage1RfsClasses) +
           " (one per class) or 'none'";
  }
  *out = std::move(r);
  return "";
}

}  // namespace

const config::Fields<Stage1InferenceConfig>& Stage1InferenceConfig::Fields() {
  using C = Stage1InferenceConfig;
  static const C d;
  static const config::Fields<C> fields =
      config::Fields<C>("stage1 inference")
          .Add({"passes", "m",
                "clustering passes (o = original, s = shifted coordinates, radius in metres)",
                false, [](const C& c) { return ClusterPassesToString(c.passes); },
                [](C& c, const std::string& v) -> std::string {
                  try {
                    c.passes = ParseClusterPasses(v);
                  } catch (const InvalidArgument& e) {
                    return e.what();
                  }
                  return "";
                },
                [](const C& c) -> std::string {
                  if (c.passes.empty()) return "no pass";
                  for (const auto& p : c.passes) {
                    if (!(p.radius > 0 && std::isfinite(p.radius))) return "a radius is not > 0";
                  }
                  return "";
                },
                [](const C& c) {
                  return ClusterPassesToString(c.passes) != ClusterPassesToString(d.passes);
                }})
          .Number(
              "rotations", [](C& c) -> int& { return c.rotations; }, "",
              "test-time augmentation: network passes over rotations about the vertical axis "
              "(1, 2, 3, 4, 6 or 12)",
              1, 12)
          .Check([](const C& c) -> std::string {
            return kStage1HeadingBins % c.rotations != 0 ? "must divide 12 (1, 2, 3, 4, 6, 12)"
                                                         : "";
          })
          .Flag(
              "mirror", [](C& c) -> bool& { return c.mirror; },
              "test-time augmentation: also the mirrored scene (doubles the passes)")
          .Number(
              "vote_radius", [](C& c) -> double& { return c.vote_radius; }, "m",
              "instance-guided semantic vote: BFS radius on the shifted thing points, 0 = "
              "per-point argmax",
              0.0, 10.0)
          .Number(
              "vote_min_points", [](C& c) -> int& { return c.vote_min_points; }, "points",
              "smallest cluster that votes (smaller ones keep per-point labels)", 1, 1000000000)
          .Add({"class_bias", "log",
                "per-class prior correction: 25 comma-separated log offsets (dimr stage1 "
                "calibrate fits them), or none",
                false, [](const C& c) { return BiasToString(c.class_bias); },
                [](C& c, const std::string& v) { return ParseBias(v, &c.class_bias); },
                [](const C& c) -> std::string {
                  if (!c.class_bias.empty() &&
                      c.class_bias.size() != static_cast<std::size_t>(kStage1RfsClasses)) {
                    return "needs 25 values or none";
                  }
                  for (float b : c.class_bias) {
                    if (!std::isfinite(b)) return "a value is not finite";
                  }
                  return "";
                },
                [](const C& c) { return !c.class_bias.empty(); }})
          .Add({"colour_norm", "",
                "per-scene colour standardisation into the training rooms' range: mean min r,g,b, "
                "mean max r,g,b, std min r,g,b, std max r,g,b in [0, 1] units (dimr stage1 "
                "colour-stats), or none",
                false,
                [](const C& c) { return c.colour_norm ? c.colour_range.ToString() : "none"; },
                [](C& c, const std::string& v) {
                  return ErrorOf([&] { c.colour_norm = ColourRange::Parse(v, &c.colour_range); });
                },
                nullptr,  // Parse checks every value
                [](const C& c) { return c.colour_norm; }})
          .Flag(
              "wall_planes", [](C& c) -> bool& { return c.wall_planes; },
              "structure prior: points on large vertical planes that bound the scan, labelled "
              "as a class that never forms one (chair, curtain, ...), become wall")
          .WrittenIf([](const C& c) { return c.wall_planes != d.wall_planes; })
          .Number(
              "wall_plane_area", [](C& c) -> double& { return c.wall_plane_area; }, "m2",
              "smallest wall plane of the structure prior", 0.1, 1000.0)
          .WrittenIf([](const C& c) { return c.wall_plane_area != d.wall_plane_area; })
          .Number(
              "wall_plane_distance", [](C& c) -> double& { return c.wall_plane_distance; }, "m",
              "points this close to a wall plane are on it", 0.005, 0.5)
          .WrittenIf([](const C& c) { return c.wall_plane_distance != d.wall_plane_distance; })
          .Flag(
              "wall_openings", [](C& c) -> bool& { return c.wall_openings; },
              "structure prior: compact regions of a wall plane still labelled wall that differ "
              "from it (colour contrast or recess; or door / window / curtain / picture "
              "probability) become door or window by shape (wall_opening_shape) or the class "
              "of their largest probability")
          .WrittenIf([](const C& c) { return c.wall_openings != d.wall_openings; })
          .Number(
              "wall_opening_prob", [](C& c) -> double& { return c.wall_opening_prob; }, "",
              "wall openings: opening probability that alone puts a cell in an opening", 0.01, 1.0)
          .WrittenIf([](const C& c) { return c.wall_opening_prob != d.wall_opening_prob; })
          .Number(
              "wall_opening_weak", [](C& c) -> double& { return c.wall_opening_weak; }, "",
              "wall openings: opening probability that counts with colour contrast or recess", 0.0,
              1.0)
          .WrittenIf([](const C& c) { return c.wall_opening_weak != d.wall_opening_weak; })
          .Number(
              "wall_opening_contrast", [](C& c) -> double& { return c.wall_opening_contrast; }, "",
              "wall openings: colour contrast (robust z-score against the wall's colour)", 0.1,
              100.0)
          .WrittenIf([](const C& c) { return c.wall_opening_contrast != d.wall_opening_contrast; })
          .Number(
              "wall_opening_area", [](C& c) -> double& { return c.wall_opening_area; }, "m2",
              "wall openings: smallest opening", 0.0, 100.0)
          .WrittenIf([](const C& c) { return c.wall_opening_area != d.wall_opening_area; })
          .Flag(
              "wall_opening_shape", [](C& c) -> bool& { return c.wall_opening_shape; },
              "wall openings: the class by shape (from the wall's foot and tall: door; above "
              "it: window) instead of the network's probabilities")
          .WrittenIf([](const C& c) { return c.wall_opening_shape != d.wall_opening_shape; })
          .Number(
              "scene_norm", [](C& c) -> double& { return c.scene_norm; }, "",
              "test-time adaptation: the U-Net's BatchNorm layers normalise with this blend of "
              "the training statistics (0) and each pass's own (1)",
              0.0, 1.0)
          .WrittenIf([](const C& c) { return c.scene_norm != d.scene_norm; })
          .Add({"vote_exclude", "",
                "RFS classes kept out of the semantic vote (comma-separated names, e.g. "
                "picture,display), or none",
                false, [](const C& c) { return RfsClassListToString(c.vote_exclude); },
                [](C& c, const std::string& v) {
                  return ErrorOf([&] { c.vote_exclude = ParseRfsClassList(v); });
                },
                [](const C& c) -> std::string {
                  for (int k : c.vote_exclude) {
                    if (k < 0 || k >= kStage1RfsClasses) return "a class is not in 0..24";
                  }
                  return "";
                },
                [](const C& c) { return !c.vote_exclude.empty(); }})
          .Add({"vote_min_extent", "m",
                "size plausibility in the semantic vote: a cluster whose footprint long side is "
                "below CLASS's value cannot take CLASS (comma-separated CLASS:metres, e.g. "
                "sofa:0.8), or none",
                false, [](const C& c) { return RfsClassValuesToString(c.vote_min_extent); },
                [](C& c, const std::string& v) {
                  return ErrorOf([&] { c.vote_min_extent = ParseRfsClassValues(v); });
                },
                [](const C& c) -> std::string {
                  if (!c.vote_min_extent.empty() &&
                      c.vote_min_extent.size() != static_cast<std::size_t>(kStage1RfsClasses)) {
                    return "needs 25 values or none";
                  }
                  for (double v : c.vote_min_extent) {
                    if (!std::isfinite(v) || v < 0) return "a value is not a finite number >= 0";
                  }
                  return "";
                },
                [](const C& c) { return !c.vote_min_extent.empty(); }})
          .Number(
              "vote_max_extent", [](C& c) -> double& { return c.vote_max_extent; }, "m",
              "longest plausible object in the vote: a cluster whose footprint is longer is "
              "several objects and is split by clustering it again at half the radius (at most "
              "three times; what stays too long keeps its per-point labels); 0 = no limit",
              0.0, 100.0)
          .WrittenIf([](const C& c) { return c.vote_max_extent != d.vote_max_extent; })
          .Number(
              "cluster_min_points", [](C& c) -> int& { return c.cluster_min_points; }, "points",
              "smallest cluster a pass keeps", 1, 1000000000)
          .WrittenIf([](const C& c) { return c.cluster_min_points != d.cluster_min_points; })
          .Flag(
              "cluster_cap", [](C& c) -> bool& { return c.cluster_cap; },
              "the reference's 1000-neighbour ball-query cap in the clustering passes and the "
              "vote (exact BFS); 0 = approximate mode: connected components without the cap "
              "(3-8x faster on dense rooms, docs/benchmarks.md)")
          .WrittenIf([](const C& c) { return c.cluster_cap != d.cluster_cap; })
          .Number(
              "nms", [](C& c) -> double& { return c.nms_iou; }, "", "point-IoU NMS threshold", 0.0,
              1.0)
          .WrittenIf([](const C& c) { return c.nms_iou != d.nms_iou; })
          .Number(
              "min_points", [](C& c) -> int& { return c.min_points; }, "points",
              "keep instances with more points than this", 0, 1000000000)
          .WrittenIf([](const C& c) { return c.min_points != d.min_points; })
          .Number(
              "max_extent", [](C& c) -> double& { return c.max_extent; }, "m",
              "reject clouds spanning more than this (not metres?)", 1.0, 100000.0)
          .WrittenIf([](const C& c) { return c.max_extent != d.max_extent; });
  return fields;
}

void Stage1InferenceConfig::Validate() const { Fields().Validate(*this); }

std::string Stage1InferenceConfig::ToString() const { return Fields().Format(*this); }

Stage1InferenceConfig Stage1InferenceConfig::FromString(const std::string& text) {
  return FromString(text, Stage1InferenceConfig());
}

Stage1InferenceConfig Stage1InferenceConfig::FromString(const std::string& text,
                                                        const Stage1InferenceConfig& base) {
  const Stage1InferenceConfig c = Fields().Parse(text, base);
  c.Validate();
  return c;
}

Stage1InferenceConfig Stage1InferenceConfig::WithPreset(Stage1Preset preset) const {
  Stage1InferenceConfig c = *this;
  if (preset == Stage1Preset::kFast) {
    c.rotations = 1;
    c.mirror = false;
  }
  return c;
}

Stage1InferenceConfig Stage1InferenceConfig::FromModelCard(const ModelCard& card,
                                                           Stage1Preset preset) {
  const std::string line = card.GetString("recommended_inference", "");
  Stage1InferenceConfig c;
  try {
    c = FromString(line);
  } catch (const InvalidArgument& e) {
    throw ParseError(card.path(), std::string("recommended_inference: ") + e.what());
  }
  // The same keys as a YAML mapping override single values of the line:
  //   stage1_inference: {rotations: 2, vote_radius: 0.05}
  for (const auto& f : Fields().fields()) {
    const std::string key = "stage1_inference." + f.name;
    if (!card.has(key)) continue;
    try {
      Fields().Set(c, f.name, card.GetString(key));
    } catch (const InvalidArgument& e) {
      throw ParseError(card.path(), key + ": " + e.what());
    }
  }
  try {
    c.Validate();
  } catch (const InvalidArgument& e) {
    throw ParseError(card.path(), e.what());
  }
  return c.WithPreset(preset);
}

Stage1InstanceConfig Stage1InferenceConfig::InstanceConfig() const {
  Stage1InstanceConfig cfg;
  cfg.clustering.passes = passes;
  cfg.clustering.min_points = cluster_min_points;
  cfg.clustering.neighbour_cap = cluster_cap;
  cfg.semantic_vote.neighbour_cap = cluster_cap;
  cfg.nms_iou = nms_iou;
  cfg.min_points = min_points;
  cfg.semantic_vote.radius = vote_radius;
  cfg.semantic_vote.min_points = vote_min_points;
  cfg.semantic_vote.excluded_classes = vote_exclude;
  cfg.semantic_vote.min_extent = vote_min_extent;
  cfg.semantic_vote.max_extent = vote_max_extent;
  cfg.class_bias = class_bias;
  return cfg;
}

// ---------------------------------------------------------------- segmenter
struct Stage1Segmenter::Impl {
  std::unique_ptr<nn::Stage1Model> owned;
  const nn::Stage1Model* model = nullptr;
  Stage1InferenceConfig config;
};

Stage1Segmenter::Stage1Segmenter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Stage1Segmenter::~Stage1Segmenter() = default;
Stage1Segmenter::Stage1Segmenter(Stage1Segmenter&&) noexcept = default;
Stage1Segmenter& Stage1Segmenter::operator=(Stage1Segmenter&&) noexcept = default;

Stage1Segmenter Stage1Segmenter::Load(const std::string& model_path,
                                      const Stage1InferenceConfig& config) {
  config.Validate();
  auto impl = std::make_unique<Impl>();
  impl->owned = std::make_unique<nn::Stage1Model>(nn::Stage1Model::Load(model_path));
  impl->model = impl->owned.get();
  impl->config = config;
  if (impl->model->config().num_classes != kStage1RfsClasses) {
    throw ParseError(model_path, "a stage-1 model of " +
                                     std::to_string(impl->model->config().num_classes) +
                                     " classes, the segmenter needs the 25 RFS classes");
  }
  return Stage1Segmenter(std::move(impl));
}

Stage1Segmenter Stage1Segmenter::Load(const std::string& model_path, Stage1Preset preset) {
  const std::optional<ModelCard> card = ModelCard::LoadIfExists(model_path);
  const Stage1InferenceConfig config =
      card ? Stage1InferenceConfig::FromModelCard(*card, preset) : Stage1InferenceConfig();
  return Load(model_path, config);
}

Stage1Segmenter Stage1Segmenter::Borrow(const nn::Stage1Model& model,
                                        const Stage1InferenceConfig& config) {
  config.Validate();
  if (model.config().num_classes != kStage1RfsClasses) {
    throw InvalidArgument("Stage1Segmenter: the model has " +
                          std::to_string(model.config().num_classes) +
                          " classes, the segmenter needs the 25 RFS classes");
  }
  auto impl = std::make_unique<Impl>();
  impl->model = &model;
  impl->config = config;
  return Stage1Segmenter(std::move(impl));
}

const Stage1InferenceConfig& Stage1Segmenter::config() const { return impl_->config; }
void Stage1Segmenter::set_config(const Stage1InferenceConfig& config) {
  config.Validate();
  impl_->config = config;
}
std::string Stage1Segmenter::model_config() const { return impl_->model->config().ToString(); }
int Stage1Segmenter::feature_dim() const {
  return static_cast<int>(impl_->model->config().widths.at(0));
}
bool Stage1Segmenter::uses_color() const { return impl_->model->config().input.use_rgb; }

Stage1Result Stage1Segmenter::RunNetwork(const PointCloudInput& input, bool with_features) const {
  const std::string who = "point cloud" + (input.name.empty() ? "" : " '" + input.name + "'");
  input.Validate();
  if (uses_color() && !input.has_colors()) {
    throw InvalidArgument(who + ": the stage-1 model uses colour but the cloud has none");
  }
  Eigen::Vector3f lo = input.points[0], hi = input.points[0];
  for (const auto& p : input.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const float extent = (hi - lo).maxCoeff();
  if (extent > impl_->config.max_extent) {
    char buf[200];
    std::snprintf(buf, sizeof(buf),
                  ": spans %.1f m, more than max_extent = %g m; points must be in metres (is the "
                  "cloud in millimetres?)",
                  extent, impl_->config.max_extent);
    throw InvalidArgument(who + buf);
  }
  Stage1Result r;
  ScopedTimer total(&r.timings, "network");
  nn::Stage1Timing t;
  // Colour standardisation (colour_norm.h) on a copy; the caller's colours stay as they are.
  std::vector<Eigen::Vector3f> standardised;
  if (uses_color() && impl_->config.colour_norm) {
    standardised = StandardiseColours(input.colors, impl_->config.colour_range);
  }
  const std::vector<Eigen::Vector3f>* colours =
      !uses_color() ? nullptr : (impl_->config.colour_norm ? &standardised : &input.colors);
  const nn::ScenePoints view(input.points, colours, input.name);
  nn::Stage1Output out =
      impl_->model->PredictAugmented(view, impl_->config.rotations, impl_->config.mirror,
                                     with_features, &t, impl_->config.scene_norm);
  total.Stop();
  r.timings.Add("voxelize", t.voxelize_ms);
  r.timings.Add("kernel_maps", t.kernel_map_ms);
  r.timings.Add("unet", t.unet_ms);
  r.timings.Add("heads", t.heads_ms);
  r.semantic = std::move(out.semantic);
  static_cast<nn::Stage1PointRows&>(r) = std::move(static_cast<nn::Stage1PointRows&>(out));
  r.offsets = std::move(out.offsets);
  r.features = std::move(out.features);
  r.feature_dim = with_features ? feature_dim() : 0;
  r.network_origin = out.frame.origin;
  return r;
}

void Stage1Segmenter::FinishLabels(const std::vector<Eigen::Vector3f>& points,
                                   const Stage1InferenceConfig& config, Stage1Result* r,
                                   const std::vector<Eigen::Vector3f>* colours) {
  config.Validate();
  r->CheckShape("Stage1Segmenter::Finish", points.size(), kStage1RfsClasses);
  const std::vector<int>& rfs_to_cad = Stage1RfsToCad();
  static const std::vector<bool> is_thing = [] {
    std::vector<bool> t(kStage1RfsClasses, true);
    t[labels::kWall] = t[labels::kFloor] = false;
    return t;
  }();
  {
    ScopedTimer t(&r->timings, "class_bias");
    if (!config.class_bias.empty()) {
      // Per row (a voxel's points share it), then spread to the points.
      r->semantic = r->PerPoint(
          ApplyClassBias(config.class_bias, &r->semantic_prob, kStage1RfsClasses), points.size());
    }
  }
  {
    ScopedTimer t(&r->timings, "vote");
    if (config.vote_radius > 0) {
      r->semantic = VoteSemantics(points, r->offsets, r->semantic, r->semantic_prob, is_thing,
                                  config.InstanceConfig().semantic_vote, r->point_row);
    }
  }
  if (config.wall_planes || config.wall_openings) {
    ScopedTimer t(&r->timings, "wall_planes");
    WallPlaneConfig wall;
    wall.min_area = config.wall_plane_area;
    wall.distance = config.wall_plane_distance;
    // Without wall_planes the planes are found on a copy: the labels keep their classes.
    std::vector<int> copy;
    if (!config.wall_planes) copy = r->semantic;
    const WallPlaneResult planes =
        ApplyWallPlanes(points, wall, config.wall_planes ? &r->semantic : &copy);
    if (config.wall_openings) {
      WallOpeningConfig open;
      open.seed_prob = config.wall_opening_prob;
      open.weak_prob = config.wall_opening_weak;
      open.contrast = config.wall_opening_contrast;
      open.min_area = config.wall_opening_area;
      open.shape_class = config.wall_opening_shape;
      r->wall_openings = ApplyWallOpenings(points, colours, planes, *r, open, &r->semantic);
    }
  }
  r->cad_label.resize(r->semantic.size());
  for (std::size_t i = 0; i < r->semantic.size(); ++i) r->cad_label[i] = rfs_to_cad[r->semantic[i]];
}

void Stage1Segmenter::Finish(const std::vector<Eigen::Vector3f>& points,
                             const Stage1InferenceConfig& config, Stage1Result* r,
                             const std::vector<Eigen::Vector3f>* colours) {
  FinishLabels(points, config, r, colours);
  ScopedTimer t(&r->timings, "clustering");
  r->instances = ExtractStage1Instances(points, r->offsets, r->cad_label, r->semantic_prob,
                                        r->heading_prob, r->heading_residual, Stage1RfsToCad(),
                                        config.InstanceConfig(), r->point_row);
}

Stage1Result Stage1Segmenter::Segment(const PointCloudInput& input, bool with_features) const {
  Stopwatch clock;
  Stage1Result r = RunNetwork(input, with_features);
  Finish(input.points, impl_->config, &r, input.has_colors() ? &input.colors : nullptr);
  r.timings.Add("total", clock.ElapsedMs());
  return r;
}

}  // namespace dimr::pipeline
