// `dimr reconstruct INPUT --out DIR`: labelled, complete instance meshes of every object in a
// point cloud (pipeline::Reconstructor). INPUT: a PLY / PCD cloud, a ScanNet scene folder, a
// folder of scene folders or a SynthScan split. Output layout: tools/reconstruct_io.h (the
// evaluation layout, so `dimr eval --pred DIR/meshes --gt ...` runs on it directly).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "dimr/data/labels.h"
#include "dimr/geometry/error.h"
#include "dimr/pipeline/ceiling.h"
#include "dimr/pipeline/cloud_io.h"
#include "dimr/pipeline/gravity.h"
#include "dimr/pipeline/reconstructor.h"
#include "dimr/pipeline/voxel_downsample.h"
#include "tools/command_registry.h"
#include "tools/reconstruct_io.h"
#include "tools/stage1_inference_args.h"

namespace {

namespace fs = std::filesystem;

struct ReconstructArgs {
  std::string input;
  std::string out;
  std::string mode = "generation";
  std::string preset = "accurate";
  int k = 1;
  int samples = 0;
  std::uint64_t seed = 0;
  dimr::pipeline::ReconstructorConfig config;
  std::string crop;  // xmin,ymin,zmin,xmax,ymax,zmax
  double scale = 1.0;
  std::string input_voxel = "auto";  // voxel-mean filter: auto | 0 (off) | size in metres
  std::string ceiling = "auto";      // ceiling removal (pipeline/ceiling.h): auto | off
  std::string up = "z";              // the input axis that points up (pipeline/gravity.h)
  bool level = false;                // level the cloud by its floor plane (pipeline/gravity.h)
  bool no_icp = false;
  std::string icp_backend = "own";
  std::string score = "combined";
  std::string icp_metric = "point_to_point";
  bool no_box_residual = false;
  bool single_scale = false;
  bool no_picture = false;
  int max_scenes = 0;
  std::string gt_meshes;
  bool quiet = false;
};

std::vector<double> ParseNumbers(const std::string& s, std::size_t n, const std::string& flag) {
  std::vector<double> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, ',')) {
    try {
      std::size_t used = 0;
      out.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw dimr::InvalidArgument(flag + ": '" + item + "' is not a number");
    }
  }
  if (out.size() != n) {
    throw dimr::InvalidArgument(flag + ": expected " + std::to_string(n) +
                                " comma-separated numbers");
  }
  return out;
}

void RunReconstruct(ReconstructArgs& a) {
  const bool auto_voxel = a.input_voxel == "auto";
  const double voxel = auto_voxel ? dimr::pipeline::kTrainingVoxelSize
                                  : ParseNumbers(a.input_voxel, 1, "--input-voxel")[0];
  if (!(voxel >= 0) || !std::isfinite(voxel)) {
    throw dimr::InvalidArgument("--input-voxel: expected auto, 0 or a size in metres, got '" +
                                a.input_voxel + "'");
  }
  const dimr::pipeline::CeilingConfig ceiling = dimr::tools::CeilingFromFlag(a.ceiling);
  const Eigen::Matrix3d up = dimr::pipeline::UpAxisRotation(a.up).cast<double>();
  const bool rotate = !up.isIdentity(0.0);
  dimr::pipeline::ReconstructorConfig& cfg = a.config;
  // One mode, or several (comma-separated): the networks run once per scene, the other modes
  // re-mesh that result (Reconstructor::Remesh) into DIR/<mode>/.
  std::vector<dimr::pipeline::ReconstructionMode> modes;
  {
    std::stringstream in(a.mode);
    std::string m;
    while (std::getline(in, m, ',')) modes.push_back(dimr::pipeline::ParseReconstructionMode(m));
    if (modes.empty()) throw dimr::InvalidArgument("--mode: no mode given");
  }
  cfg.mode = modes.front();
  cfg.box_residual = !a.no_box_residual;
  cfg.multi_scale = !a.single_scale;
  cfg.preset = dimr::pipeline::ParseReconstructionPreset(a.preset);
  cfg.k = a.k;
  cfg.samples = a.samples;
  cfg.seed = a.seed;
  cfg.icp.enabled = !a.no_icp;
  cfg.icp.backend = dimr::pipeline::ParseIcpBackend(a.icp_backend);
  cfg.score = dimr::pipeline::ParseScoreRanking(a.score);
  cfg.icp.metric = dimr::pipeline::ParseIcpMetric(a.icp_metric);
  if (!a.crop.empty()) {
    const auto v = ParseNumbers(a.crop, 6, "--crop");
    cfg.crop = true;
    cfg.crop_min = dimr::geometry::Vec3(v[0], v[1], v[2]);
    cfg.crop_max = dimr::geometry::Vec3(v[3], v[4], v[5]);
  }
  if (!(a.scale > 0) || !std::isfinite(a.scale)) throw dimr::InvalidArgument("--scale must be > 0");
  std::vector<dimr::tools::InputScene> scenes = dimr::tools::ListInputScenes(a.input);
  if (a.max_scenes > 0 && static_cast<int>(scenes.size()) > a.max_scenes)
    scenes.resize(a.max_scenes);
  const auto t_load = std::chrono::steady_clock::now();
  dimr::pipeline::Reconstructor rec(cfg);
  const double load_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_load).count();
  if (!a.quiet) {
    std::printf("models loaded in %.1f s; mode %s, preset %s, %zu scene(s)\n", load_s,
                a.mode.c_str(), a.preset.c_str(), scenes.size());
  }
  nlohmann::json summary = nlohmann::json::array();
  int failed = 0;
  for (auto& s : scenes) {
    try {
      dimr::tools::LoadInputScene(&s);
      // As the Reconstructor and the node do (before the ceiling and density steps, which
      // refuse them): organised clouds mark pixels without a return by NaN.
      const std::size_t dropped = dimr::pipeline::DropNonFinitePoints(&s.cloud);
      if (dropped > 0 && !a.quiet) {
        std::printf(
            "%s: %zu of %zu points have no finite coordinates (NaN / Inf: no return "
            "in an organised cloud) and are dropped\n",
            s.name.c_str(), dropped, dropped + s.cloud.points.size());
      }
      if (a.scale != 1.0) {
        for (auto& p : s.cloud.points) p *= a.scale;
      }
      if (rotate) s.cloud.Transform(up);
      auto input = dimr::pipeline::PointCloudInput::FromPointCloud(s.cloud, s.name);
      if (a.level && !input.empty()) {
        const dimr::pipeline::FloorPlane floor = dimr::pipeline::FindFloorPlane(input);
        if (floor.found) {
          const Eigen::Matrix3f level = dimr::pipeline::LevellingRotation(floor.normal);
          input.Rotate(level);
          s.cloud.Transform(level.cast<double>());  // the picture's cloud, in the same frame
          if (!a.quiet) {
            std::printf(
                "%s: levelled by its floor plane (tilt %.1f deg, %.0f %% of the points "
                "on it)\n",
                s.name.c_str(), floor.tilt_deg, 100.0 * floor.inliers);
          }
        } else {
          std::fprintf(stderr,
                       "warning: %s: --level found no floor plane within 40 deg of up; the "
                       "cloud is left as it is\n",
                       s.name.c_str());
        }
      }
      if (ceiling.enabled) {
        dimr::pipeline::CeilingRemoval cut =
            dimr::pipeline::RemoveCeiling(std::move(input), ceiling);
        input = std::move(cut.cloud);  // the input itself when no ceiling is found
        if (cut.found) {
          if (!a.quiet) {
            std::printf("%s: ceiling at z = %.2f m removed (%zu points, %.1f m² flat)\n",
                        s.name.c_str(), cut.ceiling_z, cut.removed, cut.area);
          }
        }
      }
      if (voxel > 0) {
        const std::size_t before = input.points.size();
        // auto: only clouds denser than the training density; a size: always.
        auto d = dimr::pipeline::NormaliseDensity(
            input, voxel, auto_voxel ? dimr::pipeline::kDenserThanTrainingPointsPerCell : 1.0);
        if (d.applied) {
          input = std::move(d.cloud);
          if (!a.quiet) {
            std::printf("%s: %zu points (%.1f per %.3f m cell) -> %zu voxel means\n",
                        s.name.c_str(), before, d.points_per_cell, voxel, input.points.size());
          }
        }
      }
      const auto t_scene = std::chrono::steady_clock::now();
      const dimr::pipeline::SceneResult r = rec.Reconstruct(input);
      // Wall time: the stage timings overlap when the per-object shape work runs on threads.
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t_scene).count();
      auto out_of = [&](dimr::pipeline::ReconstructionMode m) {
        return modes.size() == 1
                   ? a.out
                   : (fs::path(a.out) / dimr::pipeline::ReconstructionModeName(m)).string();
      };
      std::vector<dimr::geometry::TriangleMesh> gt;
      if (!a.gt_meshes.empty() && !a.no_picture)
        gt = dimr::tools::ReadSceneGtMeshes(a.gt_meshes, s.name);
      const auto* gtp = a.gt_meshes.empty() ? nullptr : &gt;
      const auto written =
          dimr::tools::WriteSceneOutputs(out_of(modes[0]), s, r, !a.no_picture, gtp);
      for (std::size_t m = 1; m < modes.size(); ++m) {
        dimr::pipeline::SceneResult rm = rec.Remesh(r, input, modes[m], cfg.k);
        dimr::tools::WriteSceneOutputs(out_of(modes[m]), s, rm, !a.no_picture, gtp);
      }
      std::string classes;
      for (const auto& inst : r.instances) {
        if (!classes.empty()) classes += " ";
        classes += dimr::data::CadClassNames()[inst.cad_class];
      }
      if (!a.quiet) {
        std::printf("%s: %zu points -> %zu instances in %.2f s (%s)\n", s.name.c_str(),
                    r.input_points, r.instances.size(), seconds, classes.c_str());
        for (const auto& w : r.warnings) std::printf("  warning: %s\n", w.c_str());
      }
      nlohmann::json js;
      js["scene"] = s.name;
      js["points"] = r.input_points;
      js["instances"] = r.instances.size();
      js["seconds"] = seconds;
      js["json"] = written.json;
      summary.push_back(js);
    } catch (const dimr::Error& e) {
      ++failed;
      std::fprintf(stderr, "dimr reconstruct: %s: %s\n", s.name.c_str(), e.what());
      summary.push_back({{"scene", s.name}, {"error", e.what()}});
    }
  }
  std::error_code ec;
  // Under vis/: every *.json at the top level is read by `dimr eval --pred DIR` as a scene.
  fs::create_directories(fs::path(a.out) / "vis", ec);
  std::ofstream(fs::path(a.out) / "vis" / "summary.json") << summary.dump(1) << "\n";
  if (failed > 0) {
    throw dimr::Error(std::to_string(failed) + " of " + std::to_string(scenes.size()) +
                      " scene(s) failed (see above)");
  }
}

void SetupReconstruct(CLI::App& app) {
  auto a = std::make_shared<ReconstructArgs>();
  app.add_option("input", a->input,
                 "PLY/PCD cloud, ScanNet scene folder, folder of scene folders or SynthScan split")
      ->required();
  app.add_option("--out", a->out, "output folder (meshes/, {scene}.json, vis/)")->required();
  app.add_option("--mode", a->mode,
                 "generation | projection | retrieval, or a comma list (each into DIR/<mode>/; "
                 "the networks run once)")
      ->capture_default_str();
  app.add_option("--preset", a->preset,
                 "accurate (the stage-1 card's test-time augmentation) | fast")
      ->capture_default_str();
  app.add_option("--k", a->k, "projection: pool neighbours")->capture_default_str();
  app.add_option("--samples", a->samples, "alternative shapes per object sampled from sigma")
      ->capture_default_str();
  app.add_option("--seed", a->seed, "sampling seed")->capture_default_str();
  auto& c = a->config;
  app.add_option("--stage1", c.stage1_model, "stage-1 weights")->capture_default_str();
  app.add_option("--stage2", c.stage2_model, "stage-2 weights")->capture_default_str();
  app.add_option("--bsp", c.bsp_model, "BSP decoder weights")->capture_default_str();
  app.add_option("--pool", c.pool, "latent CAD pool (projection, retrieval)")
      ->capture_default_str();
  app.add_option(
      "--pool-meshes", c.pool_meshes,
      "retrieval: ShapeNet-style tree of the pool's CAD models (dimr export pool-meshes)");
  app.add_option("--score-threshold", c.score_threshold, "keep sigmoid(score) > this")
      ->capture_default_str();
  app.add_option("--min-points", c.min_points, "keep proposals with more points")
      ->capture_default_str();
  app.add_option("--nms", c.nms_iou, "point-IoU NMS threshold")->capture_default_str();
  app.add_option("--score", a->score,
                 "detection score: combined (sqrt(stage-1 x stage-2)) or stage2 (the reference)")
      ->capture_default_str();
  app.add_option("--decoded-mesh-scale", c.decoded_mesh_scale,
                 "decoded meshes span size/2 x this (1 = reference; 1.032 = fill the box)")
      ->capture_default_str();
  app.add_option("--max-points", c.max_points, "refuse larger clouds")->capture_default_str();
  app.add_option("--crop", a->crop, "keep points in xmin,ymin,zmin,xmax,ymax,zmax (input frame)");
  app.add_option("--input-voxel", a->input_voxel,
                 "replace the input by its voxel means first: auto = at 0.045 m when the cloud "
                 "holds more than 1.5 points per 0.045 m cell (raw accumulated clouds, real "
                 "scans; SynthScan mesh density ~1 is left as it is), 0 = off, or a size in m "
                 "(always; docs/results.md 'Input density')")
      ->capture_default_str();
  dimr::tools::AddCeilingFlag(app, &a->ceiling);
  app.add_option("--up", a->up,
                 "the input axis that points up: z (gravity aligned, the default), -y (a depth "
                 "camera's optical frame), y (y-up mesh exports), x, -x, -z; the cloud is "
                 "rotated to z up first and every output is in that rotated frame")
      ->capture_default_str();
  app.add_flag("--level", a->level,
               "after --up: rotate the cloud so that its floor plane (RANSAC, within 40 deg of "
               "up, nothing below it) is level - a pitched depth camera, a hand-held scan; "
               "outputs are in the levelled frame");
  app.add_option("--scale", a->scale, "multiply coordinates first (0.001 for millimetres)")
      ->capture_default_str();
  app.add_option("--threads", c.threads, "network threads (0 = default)")->capture_default_str();
  app.add_flag("--no-icp", a->no_icp, "skip the ICP refinement (ablation)");
  app.add_option("--icp-backend", a->icp_backend, "ICP: own (kd-tree, early stop) or pcl")
      ->capture_default_str();
  app.add_option("--icp-metric", a->icp_metric, "ICP (own): point_to_point or point_to_plane")
      ->capture_default_str();
  app.add_option("--icp-iterations", c.icp.max_iterations, "ICP: at most this many iterations")
      ->capture_default_str();
  app.add_option("--icp-samples", c.icp.samples, "ICP: surface samples of the mesh (source)")
      ->capture_default_str();
  app.add_flag("--no-box-residual", a->no_box_residual,
               "place by the proposal box, without stage 2's box residual (ablation)");
  app.add_flag("--single-scale", a->single_scale,
               "one clustering pass (shifted, 3 cm) instead of multi-scale (ablation)");
  app.add_flag("--no-picture", a->no_picture, "do not render vis/{scene}.png");
  app.add_option("--max-scenes", a->max_scenes, "only the first N scenes of INPUT");
  app.add_option(
      "--gt-meshes", a->gt_meshes,
      "evaluation GT folder (dimr export gt .../meshes): adds a GT panel to the pictures");
  app.add_flag("--quiet", a->quiet, "print errors only");
  app.callback([a]() { RunReconstruct(*a); });
}

const dimr::tools::Registrar kReg(
    "", "reconstruct",
    "Instance meshes of every object in a point cloud (generation / projection / retrieval)",
    &SetupReconstruct);

}  // namespace
