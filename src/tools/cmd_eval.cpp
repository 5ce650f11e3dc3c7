// `dimr eval`: the DIMR evaluation protocol (mesh AP at IoU / CD / LFD thresholds, AP at
// PCR@0.5) over a prediction folder, reproducing the reference scripts' numbers by default.
// docs/evaluation.md explains the metrics, the reference quirks and `--protocol corrected`.
#ifdef DIMR_HAVE_EVAL
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "dimr/eval/evaluator.h"
#include "dimr/eval/inputs.h"
#include "dimr/eval/report.h"
#include "dimr/geometry/error.h"
#include "tools/command_registry.h"

namespace {

struct EvalArgs {
  std::string pred_dir;
  std::string gt_dir;
  std::string gt_points_dir;
  std::string scene_list;
  std::string metrics = "iou,cd,lfd";
  std::string protocol = "reference";
  std::string json_out;
  std::string markdown_out;
  std::string svg_dir;
  std::string lfd_cache;
  int threads = 0;
  bool per_object = false;
  unsigned long long seed = 0;
  bool quiet = false;
};

void RunEval(const EvalArgs& a) {
  dimr::eval::EvalOptions opt;
  opt.SetMetrics(a.metrics);
  opt.protocol = dimr::eval::ParseProtocol(a.protocol);
  opt.threads = a.threads;
  opt.seed = a.seed;
  opt.lfd_cache_dir = a.lfd_cache;
  opt.progress = !a.quiet;
  if (opt.pcr && a.gt_points_dir.empty()) {
    throw dimr::InvalidArgument(
        "--metrics pcr needs --gt-points DIR (per-scene point PLYs or <scene>/data.npz)");
  }
  dimr::eval::EvalInputs in;
  in.preds = dimr::eval::ListMeshFolder(a.pred_dir);
  if (opt.iou || opt.cd || opt.lfd) {
    if (a.gt_dir.empty()) throw dimr::InvalidArgument("--gt DIR is required for iou, cd, lfd");
    in.gt = dimr::eval::ListMeshFolder(a.gt_dir);
    if (in.gt.empty()) throw dimr::ParseError(a.gt_dir, "no GT meshes (*.ply) found");
  }
  if (opt.pcr) {
    in.pcr_gt = dimr::eval::LoadPcrGtFolder(a.gt_points_dir, &in.pcr_scenes, a.scene_list);
  }
  if (in.preds.empty()) {
    std::fprintf(stderr, "dimr eval: warning: no predictions in %s; every AP is 0\n",
                 a.pred_dir.c_str());
  }
  const dimr::eval::EvalReport rep = dimr::eval::Evaluate(in, opt);
  const std::string md = dimr::eval::FormatMarkdown(rep) +
                         (a.per_object ? "\n" + dimr::eval::FormatObjectsMarkdown(rep) : "");
  std::fputs(md.c_str(), stdout);
  for (const std::string& w : rep.warnings)
    std::fprintf(stderr, "dimr eval: warning: %s\n", w.c_str());
  if (!a.json_out.empty()) {
    std::ofstream out(a.json_out);
    if (!out) throw dimr::InvalidArgument("cannot write " + a.json_out);
    out << dimr::eval::FormatJson(rep) << "\n";
    std::fprintf(stderr, "dimr eval: JSON written to %s\n", a.json_out.c_str());
  }
  if (!a.markdown_out.empty()) {
    std::ofstream out(a.markdown_out);
    if (!out) throw dimr::InvalidArgument("cannot write " + a.markdown_out);
    out << md;
  }
  if (!a.svg_dir.empty()) {
    const int n = dimr::eval::WritePrCurvesSvg(rep, a.svg_dir);
    std::fprintf(stderr, "dimr eval: %d precision-recall SVG(s) written to %s\n", n,
                 a.svg_dir.c_str());
  }
}

void SetupEval(CLI::App& app) {
  auto args = std::make_shared<EvalArgs>();
  app.add_option("--pred", args->pred_dir,
                 "Prediction folder: {scene}_{k}_{class}_{score}.ply meshes and/or SceneResult "
                 "*.json files")
      ->required();
  app.add_option("--gt", args->gt_dir, "GT mesh folder: {scene}_{k}_{class}_1.ply");
  app.add_option("--scene-list", args->scene_list,
                 "PCR scenes, one per line (the reference's val.txt); default: all in --gt-points");
  app.add_option("--gt-points", args->gt_points_dir,
                 "PCR GT folder: {scene}.ply point files (semantic_label, instance_label) or the "
                 "reference's processed_data/{scene}/data.npz");
  app.add_option("--metrics", args->metrics, "Comma-separated subset of iou,cd,lfd,pcr (or all)")
      ->capture_default_str();
  app.add_option("--protocol", args->protocol,
                 "reference (the paper scripts' numbers, quirks included) or corrected")
      ->capture_default_str();
  app.add_option("--json", args->json_out, "Write every number as JSON here");
  app.add_option("--markdown", args->markdown_out, "Also write the Markdown tables here");
  app.add_option("--svg-dir", args->svg_dir, "Write precision-recall curves (SVG) here");
  app.add_option("--lfd-cache", args->lfd_cache,
                 "Folder for LFD descriptors keyed by mesh content hash (created if missing)");
  app.add_option("--threads", args->threads, "Worker threads (0 = all cores)")
      ->capture_default_str();
  app.add_option("--seed", args->seed, "Seed of the Chamfer surface sampling")
      ->capture_default_str();
  app.add_flag("--quiet", args->quiet, "No progress bars");
  app.add_flag("--per-object", args->per_object,
               "Also print, per GT mesh, its best IoU (and which prediction), CD and LFD over the "
               "predictions of its scene and class (always in --json)");
  app.callback([args]() {
    if (!args->lfd_cache.empty()) {
      std::error_code ec;
      std::filesystem::create_directories(args->lfd_cache, ec);
    }
    RunEval(*args);
  });
}

const dimr::tools::Registrar kReg(
    "", "eval",
    "Evaluate predicted instance meshes: mAP at IoU/CD/LFD thresholds and PCR@0.5 (DIMR protocol)",
    &SetupEval);

}  // namespace
#endif  // DIMR_HAVE_EVAL
