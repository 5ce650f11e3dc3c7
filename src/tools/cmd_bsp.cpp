// BSP-CVAE commands: `dimr bsp prepare|eval|decode|interpolate`, `dimr train bsp`,
// `dimr encode-pool`, `dimr bench bsp`. Needs the nn and pipeline layers (LibTorch).
#if defined(DIMR_HAVE_NN) && defined(DIMR_HAVE_PIPELINE)
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include "dimr/core/labels.h"
#include "dimr/core/timing.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/ply_io.h"
#include "dimr/nn/bsp_model.h"
#include "dimr/pipeline/bsp_data.h"
#include "dimr/pipeline/bsp_decoder.h"
#include "dimr/pipeline/bsp_mesher.h"
#include "dimr/pipeline/shape_pool.h"
#include "tools/bsp_options.h"
#include "tools/command_registry.h"
#include "tools/sha256.h"

namespace dimr::tools {
namespace {

// The decoder of a command: the model's weights, decoded with the requested dilations (a
// negative one: the model card's).
pipeline::BspDecoder LoadDecoder(const std::string& model_path, const BspDilation& dilation) {
  return pipeline::BspDecoder::Load(model_path, {dilation.plane, dilation.distance});
}

// ---------------------------------------------------------------- train
struct TrainArgs {
  std::vector<std::string> train;  // FILE or FILE@N (repeated N times), concatenated
  std::string val, out, config = "cpu", epochs = "60,30,0", device = "cpu";
  std::string init;  // start from these weights (fine-tuning); their configuration is used
  bool config_given = false;
  int batch = 16, points = 1024, threads = 0, checkpoint_every = 5;
  double lr = 1e-4, kl = 0.01, max_minutes = 0, phase0_minutes = 0;
  int lr_step = 200;
  int kl_warmup = -1;      // epochs of linear KL annealing; < 0: the whole run, 0: constant
  bool keep_best = false;  // ship the epoch with the best validation IoU, not the last
  std::uint64_t seed = 1;
  bool fp16 = true;
  bool fp32 = false;
  bool freeze_decoder = false;
  bool no_sampling = false;
  double loss_dilation = 0.0;
  std::string latent_targets;  // pool file (dimr encode-pool) whose mu are distillation targets
  double latent_weight = 1.0, recon_weight = 1.0;
  // Decoding of the logged validation IoU; < 0: the --init model card's values (else 0).
  BspDilation val_dilation;
};

// One target mu per training sample, looked up by model id in a pool file; every sample must
// have one (named in the error otherwise) and the latent sizes must match.
Eigen::MatrixXf LatentTargets(const std::string& pool_path, const nn::BspDataset& train,
                              int latent_dim) {
  const pipeline::ShapePool pool = pipeline::ShapePool::Load(pool_path);
  if (pool.latent_dim() != latent_dim) {
    throw InvalidArgument("--latent-targets '" + pool_path + "' holds " +
                          std::to_string(pool.latent_dim()) + "-d codes, the model has " +
                          std::to_string(latent_dim));
  }
  std::unordered_map<std::string, std::size_t> by_id;
  for (std::size_t i = 0; i < pool.size(); ++i) by_id[pool.entries()[i].model_id] = i;
  Eigen::MatrixXf targets(static_cast<Eigen::Index>(train.samples.size()), latent_dim);
  for (std::size_t s = 0; s < train.samples.size(); ++s) {
    const auto& sample = train.samples[s];
    const auto it = by_id.find(sample.model_id);
    if (it == by_id.end()) {
      throw InvalidArgument("--latent-targets '" + pool_path +
                            "' has no code for training model '" + sample.model_id + "' (sample " +
                            std::to_string(s) + ")");
    }
    const auto& entry = pool.entries()[it->second];
    if (entry.cad_class != sample.cad_class) {
      throw InvalidArgument("--latent-targets '" + pool_path + "': model '" + sample.model_id +
                            "' has class " + std::to_string(entry.cad_class) + " in the pool, " +
                            std::to_string(sample.cad_class) + " in the training set");
    }
    targets.row(static_cast<Eigen::Index>(s)) = entry.code.head(latent_dim).transpose();
  }
  return targets;
}

nn::BspConfig ConfigFromArg(const std::string& text) {
  if (text == "cpu") return nn::BspConfig::CpuDefault();
  if (text == "reference") return nn::BspConfig::Reference();
  return nn::BspConfig::FromString(text);
}

void WriteModelCard(const std::string& dir, const nn::BspModel& model, const TrainArgs& a,
                    const std::string& command, const std::vector<nn::BspEpochLog>& logs,
                    int best_epoch, double val_iou, double val_dilation,
                    double val_distance_dilation, const std::string& weights) {
  std::ofstream y(dir + "/model.yaml");
  y << "name: bsp_cvae\n";
  y << "description: BSP-CVAE shape autoencoder (class-conditioned), dimr-method.md sections 5-6\n";
  y << "architecture: \"" << model.config().ToString() << "\"\n";
  y << "parameters: " << model.NumParameters() << "\n";
  y << "phase: " << model.phase() << "\n";
  y << "label_set: [";
  for (int c = 0; c < labels::kNumCadClasses; ++c)
    y << (c ? ", " : "") << labels::CadClassNames()[c];
  y << "]\n";
  y << "training:\n";
  y << "  command: \"" << command << "\"\n";
  y << "  seed: " << a.seed << "\n";
  y << "  train_data: \"";
  for (std::size_t i = 0; i < a.train.size(); ++i) y << (i ? " + " : "") << a.train[i];
  y << "\"\n";
  y << "  val_data: \"" << a.val << "\"\n";
  if (!a.init.empty()) y << "  initialised_from: \"" << a.init << "\"\n";
  if (a.freeze_decoder) y << "  frozen: decoder and convex/union weights (encoder trained)\n";
  if (a.no_sampling) y << "  latent_in_loss: mu (no sampling)\n";
  if (a.loss_dilation > 0) y << "  loss_dilation: " << a.loss_dilation << "\n";
  if (!a.latent_targets.empty()) {
    y << "  latent_targets: \"" << a.latent_targets << "\"   # weight " << a.latent_weight
      << ", reconstruction weight " << a.recon_weight << "\n";
  }
  y << "  epochs_completed: " << (logs.empty() ? 0 : logs.back().epoch) << "\n";
  if (a.kl_warmup >= 0) y << "  kl_warmup_epochs: " << a.kl_warmup << "\n";
  if (best_epoch > 0) {
    y << "  selected_epoch: " << best_epoch << "   # --keep-best: best validation IoU\n";
  }
  y << "  device: " << a.device << "\n";
  y << "metrics:\n";
  y << "  val_volumetric_iou_32: " << val_iou << "   # decoding dilation " << val_dilation
    << ", distance dilation " << val_distance_dilation << "\n";
  if (!logs.empty()) y << "  final_recon_loss: " << logs.back().recon_loss << "\n";
  if (val_dilation > 0 || val_distance_dilation > 0) {
    y << "# decoding of the validation IoU (--val-dilation or the --init card), read by dimr bsp\n";
    y << "recommended_dilation: " << val_dilation << "\n";
    y << "recommended_distance_dilation: " << val_distance_dilation << "\n";
  }
  y << "weights:\n";
  y << "  file: " << std::filesystem::path(weights).filename().string() << "\n";
  y << "  dtype: " << (a.fp16 ? "float16" : "float32") << "\n";
  y << "  sha256: " << Sha256File(weights) << "\n";
}

void RunTrain(const TrainArgs& a, const std::string& command) {
  const nn::BspConfig config = ConfigFromArg(a.config);
  nn::BspTrainOptions opt;
  {
    std::istringstream in(a.epochs);
    std::string tok;
    std::vector<int> e;
    while (std::getline(in, tok, ',')) e.push_back(std::stoi(tok));
    if (e.size() != 3 || *std::min_element(e.begin(), e.end()) < 0) {
      throw InvalidArgument("--epochs must be three non-negative numbers 'phase0,phase1,phase2'");
    }
    opt.epochs_phase0 = e[0];
    opt.epochs_phase1 = e[1];
    opt.epochs_phase2 = e[2];
  }
  opt.batch_size = a.batch;
  opt.points_per_sample = a.points;
  opt.learning_rate = a.lr;
  opt.kl_weight = a.kl;
  opt.kl_warmup_epochs = a.kl_warmup;
  opt.seed = a.seed;
  opt.threads = a.threads;
  opt.device = a.device;
  opt.max_minutes = a.max_minutes;
  opt.phase0_minutes = a.phase0_minutes;
  opt.lr_step_epochs = a.lr_step;
  opt.checkpoint_every = a.checkpoint_every;
  opt.freeze_decoder = a.freeze_decoder;
  opt.sample_latent = !a.no_sampling;
  opt.loss_dilation = a.loss_dilation;
  if (a.freeze_decoder && a.init.empty()) {
    throw InvalidArgument("--freeze-decoder needs --init (a trained decoder to keep)");
  }
  std::filesystem::create_directories(a.out);
  opt.checkpoint_path = a.out + "/checkpoint.pt";
  if (a.keep_best) {
    if (a.val.empty()) throw InvalidArgument("--keep-best needs --val (the selection data)");
    opt.best_path = a.out + "/best.pt";
  }
  const nn::BspDataset train = LoadBspTrainingSets(a.train);
  const nn::BspDataset val = a.val.empty() ? nn::BspDataset() : nn::BspDataset::Load(a.val);
  nn::BspModel model = a.init.empty() ? nn::BspModel(config, a.seed) : nn::BspModel::Load(a.init);
  {
    pipeline::BspMeshOptions val_decoding;
    if (!a.init.empty()) {
      ApplyBspDilation(a.init, a.val_dilation, &val_decoding);
    } else {
      val_decoding.dilation = std::max(0.0f, a.val_dilation.plane);
      val_decoding.distance_dilation = std::max(0.0f, a.val_dilation.distance);
    }
    opt.val_dilation = val_decoding.dilation;
    opt.val_distance_dilation = val_decoding.distance_dilation;
  }
  opt.latent_target_weight = a.latent_weight;
  opt.recon_weight = a.recon_weight;
  if (!a.latent_targets.empty()) {
    opt.latent_targets = LatentTargets(a.latent_targets, train, model.config().latent_dim);
  } else if (a.recon_weight == 0) {
    throw InvalidArgument("--recon-weight 0 needs --latent-targets (nothing else would train)");
  }
  if (!a.init.empty()) {
    if (a.config_given && model.config().ToString() != config.ToString()) {
      throw InvalidArgument("--init '" + a.init + "' holds a model of configuration '" +
                            model.config().ToString() + "', not the --config '" +
                            config.ToString() + "'");
    }
    std::printf("initialised from %s (trained through phase %d)\n", a.init.c_str(), model.phase());
    if (model.phase() > 0 && opt.epochs_phase0 > 0) {
      std::printf("note: --init is a phase-%d model; --epochs starts with %d continuous epochs\n",
                  model.phase(), opt.epochs_phase0);
    }
  }
  std::printf("BSP-CVAE %s, %lld parameters, %zu training shapes, %zu validation shapes\n",
              config.ToString().c_str(), static_cast<long long>(model.NumParameters()),
              train.samples.size(), val.samples.size());
  std::ofstream csv(a.out + "/train_log.csv", std::ios::app);
  csv << "epoch,phase,recon_loss,kl,latent_mse,beta,val_iou,seconds\n";
  const auto logs = model.Train(train, val, opt, [&](const nn::BspEpochLog& e) {
    std::printf(
        "epoch %4d phase %d  recon %.5f  kl %.4f  latent_mse %.5f  beta %.4f  val_iou %s  %.1f s\n",
        e.epoch, e.phase, e.recon_loss, e.kl, e.latent_mse, e.beta,
        e.val_iou < 0 ? "-" : std::to_string(e.val_iou).c_str(), e.seconds);
    std::fflush(stdout);
    csv << e.epoch << "," << e.phase << "," << e.recon_loss << "," << e.kl << "," << e.latent_mse
        << "," << e.beta << "," << e.val_iou << "," << e.seconds << "\n";
    csv.flush();
  });
  int best_epoch = 0;
  double best = -1.0;
  const bool kept = !opt.best_path.empty() && nn::ReadKeptEpoch(opt.best_path, &best_epoch, &best);
  if (kept) {
    model = nn::BspModel::Load(opt.best_path);
    std::printf("kept epoch %d (best validation IoU %.4f of the run)\n", best_epoch, best);
  }
  // The kept epoch's validation IoU is on record; otherwise evaluate the final weights.
  const double val_iou =
      kept ? best
           : (val.samples.empty()
                  ? -1.0
                  : model.EvaluateIoU(val, opt.val_dilation, opt.val_distance_dilation));
  const std::string weights = a.out + "/bsp.pt";
  model.Save(weights, a.fp16);
  WriteModelCard(a.out, model, a, command, logs, best_epoch, val_iou, opt.val_dilation,
                 opt.val_distance_dilation, weights);
  std::printf("saved %s (val IoU %.4f), model card %s/model.yaml\n", weights.c_str(), val_iou,
              a.out.c_str());
}

// ---------------------------------------------------------------- eval / decode
struct EvalArgs {
  std::string model, data, mesh_dir;
  int limit = 0;
  BspDilation dilation;  // < 0: the model card's recommended values
  int refine_steps = 0;  // latent refinement on the shape's own occupancy (0 = encoder only)
  double refine_lr = 0.01;
};

void RunEval(const EvalArgs& a) {
  const pipeline::BspDecoder decoder = LoadDecoder(a.model, a.dilation);
  const nn::BspModel& model = decoder.model();
  nn::BspDataset data = nn::BspDataset::Load(a.data);
  if (a.limit > 0 && data.samples.size() > static_cast<std::size_t>(a.limit)) {
    data.samples.resize(static_cast<std::size_t>(a.limit));
  }
  const Eigen::MatrixXf codes = model.EncodeAll(data);
  std::printf("dilation %.3g, distance dilation %.3g\n", decoder.mesh_options().dilation,
              decoder.mesh_options().distance_dilation);
  const int R = data.resolution;
  const Eigen::MatrixX3f centers = pipeline::BspGridCenters(R);
  std::vector<double> iou_sum(8, 0.0), cell_sum(8, 0.0), faces_sum(8, 0.0), convex_sum(8, 0.0);
  std::vector<int> n(8, 0);
  if (!a.mesh_dir.empty()) std::filesystem::create_directories(a.mesh_dir);
  for (std::size_t s = 0; s < data.samples.size(); ++s) {
    const auto& sample = data.samples[s];
    Eigen::VectorXf mu = codes.row(static_cast<Eigen::Index>(s)).head(model.config().latent_dim);
    if (a.refine_steps > 0) mu = model.RefineLatent(mu, sample, a.refine_steps, a.refine_lr).mu;
    const Eigen::MatrixXf planes = decoder.Planes(mu, sample.cad_class);
    const auto occ = decoder.OccupancyFromPlanes(planes, centers);
    const auto& target = sample.iou_grid.empty() ? sample.grid : sample.iou_grid;
    const pipeline::BspMeshResult mesh = decoder.MeshFromPlanes(planes);
    const int c = sample.cad_class;
    iou_sum[c] += pipeline::OccupancyIoU(occ, target);
    cell_sum[c] += pipeline::OccupancyIoU(pipeline::BspCellOccupancy(mesh, R), sample.grid);
    faces_sum[c] += static_cast<double>(mesh.mesh.faces.size());
    convex_sum[c] += static_cast<double>(mesh.kept_convexes.size());
    ++n[c];
    if (!a.mesh_dir.empty()) {
      geometry::WritePly(a.mesh_dir + "/" + std::to_string(s) + "_" + labels::CadClassNames()[c] +
                             "_" + sample.model_id + ".ply",
                         mesh.mesh);
    }
    std::fprintf(stderr, "\reval: %zu/%zu", s + 1, data.samples.size());
  }
  std::fprintf(stderr, "\n");
  // IoU@32^3 = cell centres (decoded occupancy at the centres vs iou_grid); cell IoU = the
  // occupied cells of the decoded mesh vs of the original (pipeline::BspCellOccupancy).
  std::printf(
      "| class | shapes | IoU@32^3 (centres) | cell IoU@32^3 | kept convexes | triangles "
      "|\n|---|---|---|---|---|---|\n");
  double total = 0, total_cell = 0;
  int count = 0;
  for (int c = 0; c < 8; ++c) {
    if (!n[c]) continue;
    std::printf("| %s | %d | %.4f | %.4f | %.1f | %.0f |\n", labels::CadClassNames()[c], n[c],
                iou_sum[c] / n[c], cell_sum[c] / n[c], convex_sum[c] / n[c], faces_sum[c] / n[c]);
    total += iou_sum[c];
    total_cell += cell_sum[c];
    count += n[c];
  }
  std::printf("| **all** | %d | **%.4f** | **%.4f** | | |\n", count, count ? total / count : 0.0,
              count ? total_cell / count : 0.0);
}

// ---------------------------------------------------------------- encode-pool
struct PoolArgs {
  std::string model, data, out;
  std::string shapenet, split = "all";  // a ShapeNet-format tree instead of --data
  int refine_steps = 0;  // latent refinement of each mu on the model's own occupancy samples
  double refine_lr = 0.01;
  std::string append;  // an existing pool whose entries come first
};

void RunEncodePool(const PoolArgs& a) {
  if (a.data.empty() == a.shapenet.empty()) {
    throw InvalidArgument(
        "encode-pool: give either --data (dimr bsp prepare) or --shapenet (a tree)");
  }
  const nn::BspModel model = nn::BspModel::Load(a.model);
  nn::BspDataset data;
  if (!a.data.empty()) {
    data = nn::BspDataset::Load(a.data);
  } else {
    ShapeNetSelection sel;
    sel.split = a.split;
    sel.resolution = model.config().resolution;
    sel.jobs = 0;
    data = ShapeNetBspDataset(a.shapenet, sel);
  }
  const Eigen::MatrixXf codes = model.EncodeAll(data);
  const int L = model.config().latent_dim;
  pipeline::ShapePool pool(L);
  if (!a.append.empty()) {
    // The existing entries (codes, classes, mesh paths) first, then the new ones; a pool of
    // another latent size or a model id already in it is an error naming it.
    pool = pipeline::ShapePool::Load(a.append);
    if (pool.latent_dim() != L) {
      throw InvalidArgument("encode-pool --append " + a.append + ": latent size " +
                            std::to_string(pool.latent_dim()) + ", the model's is " +
                            std::to_string(L));
    }
  }
  const std::size_t first_new = pool.size();
  for (std::size_t s = 0; s < data.samples.size(); ++s) {
    Eigen::VectorXf code = codes.row(static_cast<Eigen::Index>(s)).transpose();
    if (a.refine_steps > 0) {
      code.head(L) = model.RefineLatent(code, data.samples[s], a.refine_steps, a.refine_lr).mu;
      std::fprintf(stderr, "\rrefine: %zu/%zu", s + 1, data.samples.size());
    }
    try {
      pool.Add({data.samples[s].model_id, data.samples[s].cad_class, code});
    } catch (const InvalidArgument& e) {
      throw InvalidArgument("encode-pool: model " + data.samples[s].model_id + ": " + e.what());
    }
  }
  if (a.refine_steps > 0) std::fprintf(stderr, "\n");
  if (!a.shapenet.empty()) {
    // Retrieval needs each model's mesh: the tree's own files (absolute paths; entries of an
    // appended pool that the tree does not hold keep theirs).
    pool.AttachMeshTree(std::filesystem::absolute(a.shapenet).string());
  }
  pool.Save(a.out);
  std::printf("encoded %zu CAD models into %s (content hash %s)%s\n", pool.size() - first_new,
              a.out.c_str(), pool.ContentHash().c_str(),
              a.append.empty() ? ""
                               : (", after the " + std::to_string(first_new) + " entries of " +
                                  a.append + ": " + std::to_string(pool.size()) + " in all")
                                     .c_str());
}

// ---------------------------------------------------------------- interpolate
struct InterpArgs {
  std::string model, data, out_dir;
  int a = 0, b = 1, steps = 5;
  BspDilation dilation;
};

void RunInterpolate(const InterpArgs& a) {
  const pipeline::BspDecoder decoder = LoadDecoder(a.model, a.dilation);
  const int L = decoder.latent_dim();
  const nn::BspDataset data = nn::BspDataset::Load(a.data);
  if (a.a < 0 || a.b < 0 || static_cast<std::size_t>(std::max(a.a, a.b)) >= data.samples.size()) {
    throw InvalidArgument("--a/--b out of range (dataset has " +
                          std::to_string(data.samples.size()) + " samples)");
  }
  const auto& sa = data.samples[static_cast<std::size_t>(a.a)];
  const auto& sb = data.samples[static_cast<std::size_t>(a.b)];
  if (sa.cad_class != sb.cad_class) throw InvalidArgument("--a and --b must be of the same class");
  const Eigen::VectorXf za = decoder.Encode(sa.grid, sa.cad_class).head(L);
  const Eigen::VectorXf zb = decoder.Encode(sb.grid, sb.cad_class).head(L);
  std::filesystem::create_directories(a.out_dir);
  for (int i = 0; i < a.steps; ++i) {
    const double t = a.steps == 1 ? 0.0 : static_cast<double>(i) / (a.steps - 1);
    const Eigen::VectorXf z = pipeline::InterpolateCodes(za, zb, t);
    const pipeline::BspMeshResult mesh = decoder.Decode(z, sa.cad_class);
    const std::string path = a.out_dir + "/interp_" + std::to_string(i) + ".ply";
    geometry::WritePly(path, mesh.mesh);
    std::printf("t=%.2f  %zu triangles  %s\n", t, mesh.mesh.faces.size(), path.c_str());
  }
}

// ---------------------------------------------------------------- bench
struct BenchArgs {
  std::string model, data, json;
  int count = 20;
  BspDilation dilation;
};

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

void RunBench(const BenchArgs& a) {
  const pipeline::BspDecoder decoder = LoadDecoder(a.model, a.dilation);
  const nn::BspModel& model = decoder.model();
  nn::BspDataset data = nn::BspDataset::Load(a.data);
  if (data.samples.size() > static_cast<std::size_t>(a.count)) data.samples.resize(a.count);
  if (data.samples.empty()) throw InvalidArgument("bench: empty dataset");
  const Stopwatch encode_clock;
  const Eigen::MatrixXf codes = model.EncodeAll(data);
  const double encode_s = encode_clock.ElapsedSeconds();
  std::vector<double> decode_ms, mesh_ms, total_ms, tris;
  for (std::size_t s = 0; s < data.samples.size(); ++s) {
    const Eigen::VectorXf mu = codes.row(static_cast<Eigen::Index>(s)).head(decoder.latent_dim());
    Timings t;
    Eigen::MatrixXf planes;
    pipeline::BspMeshResult mesh;
    {
      ScopedTimer timer(&t, "decoder");
      planes = decoder.Planes(mu, data.samples[s].cad_class);
    }
    {
      ScopedTimer timer(&t, "mesh");
      mesh = decoder.MeshFromPlanes(planes);
    }
    decode_ms.push_back(t.ms("decoder"));
    mesh_ms.push_back(t.ms("mesh"));
    total_ms.push_back(t.total_ms());
    tris.push_back(static_cast<double>(mesh.mesh.faces.size()));
  }
  std::printf("BSP decode + mesh extraction, %zu objects, model %s\n", data.samples.size(),
              model.config().ToString().c_str());
  std::printf("| step | median ms |\n|---|---|\n");
  std::printf("| decoder (latent -> planes) | %.2f |\n", Median(decode_ms));
  std::printf("| mesh extraction (grid, selection, polytopes) | %.2f |\n", Median(mesh_ms));
  std::printf("| total per object | %.2f |\n", Median(total_ms));
  std::printf("| triangles per object (median) | %.0f |\n", Median(tris));
  std::printf("encoding throughput: %.1f shapes/s (%zu shapes in %.2f s)\n",
              data.samples.size() / encode_s, data.samples.size(), encode_s);
  if (!a.json.empty()) {
    std::ofstream j(a.json);
    j << "{\"objects\": " << data.samples.size() << ", \"decode_ms_median\": " << Median(decode_ms)
      << ", \"mesh_ms_median\": " << Median(mesh_ms)
      << ", \"total_ms_median\": " << Median(total_ms) << ", \"triangles_median\": " << Median(tris)
      << ", \"encode_shapes_per_s\": " << data.samples.size() / encode_s << "}\n";
  }
}

// ---------------------------------------------------------------- registration
void SetupTrain(CLI::App& app) {
  auto a = std::make_shared<TrainArgs>();
  app.add_option("--train", a->train,
                 "training dataset (dimr bsp prepare); several are concatenated, FILE@N "
                 "repeats one N times (oversampling)")
      ->required();
  app.add_option("--val", a->val, "validation dataset");
  app.add_option("--out", a->out, "output model directory")->required();
  auto* config_opt = app.add_option("--config", a->config, "cpu | reference | 'key=value ...'");
  app.add_option("--init", a->init,
                 "start from this model's weights (e.g. --epochs 0,N,0 continues the discrete "
                 "phase); --config, if given, must match it");
  app.add_option("--epochs", a->epochs, "epochs of phases 0,1,2");
  app.add_option("--batch", a->batch)->check(CLI::Range(2, 4096));
  app.add_option("--points", a->points, "query points per shape and step")
      ->check(CLI::Range(2, 1 << 20));
  app.add_option("--lr", a->lr);
  app.add_option("--kl", a->kl, "final KL weight (linear annealing)");
  app.add_option("--kl-warmup", a->kl_warmup,
                 "epochs over which the KL weight rises linearly to --kl (default: the whole "
                 "run; 0 = constant, e.g. when fine-tuning a model trained with that weight)");
  app.add_flag("--keep-best", a->keep_best,
               "save the epoch with the best validation IoU of this run (evaluated every "
               "--checkpoint-every epochs) instead of the last one; needs --val");
  app.add_option("--seed", a->seed);
  app.add_option("--threads", a->threads, "intra-op threads (0 = default)");
  app.add_option("--device", a->device, "cpu | cuda")->check(CLI::IsMember({"cpu", "cuda"}));
  app.add_option("--max-minutes", a->max_minutes, "stop after this many minutes (checkpointed)");
  app.add_option("--phase0-minutes", a->phase0_minutes,
                 "end the continuous phase after this many minutes (fixed-budget training)");
  app.add_option("--lr-step", a->lr_step, "halve the learning rate every this many epochs")
      ->check(CLI::Range(1, 1000000));
  app.add_option("--checkpoint-every", a->checkpoint_every);
  app.add_flag("--fp32", a->fp32, "store the final weights in fp32 instead of fp16");
  app.add_flag("--no-sampling", a->no_sampling,
               "decode mu itself in the reconstruction loss instead of a sample mu + eps * sigma "
               "(the code inference decodes; with --freeze-decoder: amortised refinement)");
  app.add_option("--loss-dilation", a->loss_dilation,
                 "move every plane outwards by this much in the reconstruction loss (the "
                 "decoding rule of the card's recommended_dilation); 0 = reference")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--freeze-decoder", a->freeze_decoder,
               "train the encoder only (with --init): the decoder and the convex/union weights "
               "stay as they are, so the encoder learns codes the decoder turns into the shapes");
  app.add_option("--latent-targets", a->latent_targets,
                 "pool file (dimr encode-pool, e.g. --refine-steps 30) whose mu are regression "
                 "targets for the encoder, matched by model id (latent distillation)");
  app.add_option("--latent-weight", a->latent_weight,
                 "weight of mean((mu - target)^2) with --latent-targets")
      ->check(CLI::PositiveNumber);
  app.add_option("--recon-weight", a->recon_weight,
                 "weight of the reconstruction loss; 0 (with --latent-targets and "
                 "--freeze-decoder) trains the encoder by regression alone, without decoding")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--val-dilation", a->val_dilation.plane,
                 "plane dilation of the logged validation IoU (default: the --init model "
                 "card's recommended_dilation, else 0)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--val-distance-dilation", a->val_dilation.distance,
                 "distance dilation of the logged validation IoU (default: the --init model "
                 "card's recommended_distance_dilation, else 0)")
      ->check(CLI::NonNegativeNumber);
  app.callback([a, &app, config_opt]() {
    a->fp16 = !a->fp32;
    a->config_given = config_opt->count() > 0;
    RunTrain(*a, CommandLine(app));
  });
}

void SetupEval(CLI::App& app) {
  auto a = std::make_shared<EvalArgs>();
  app.add_option("--model", a->model)->required();
  app.add_option("--data", a->data)->required();
  app.add_option("--mesh-dir", a->mesh_dir, "write the decoded meshes here");
  app.add_option("--limit", a->limit, "evaluate at most this many shapes");
  app.add_option("--refine-steps", a->refine_steps,
                 "refine each code by this many Adam steps on the shape's own inside/outside "
                 "points (auto-decoder style; 0 = the encoder's mu)")
      ->check(CLI::Range(0, 10000));
  app.add_option("--refine-lr", a->refine_lr, "learning rate of the latent refinement");
  tools::AddBspDilationOption(app, &a->dilation);
  app.callback([a]() { RunEval(*a); });
}

void SetupPool(CLI::App& app) {
  auto a = std::make_shared<PoolArgs>();
  app.add_option("--model", a->model)->required();
  app.add_option("--data", a->data, "dataset of the CAD models to encode (dimr bsp prepare)");
  app.add_option("--shapenet", a->shapenet,
                 "encode every CAD model of this ShapeNet-format tree instead (dimr cad generate "
                 "or ShapeNetCore v2)");
  app.add_option("--split", a->split, "with --shapenet: all | train | val | test (as bsp prepare)")
      ->check(CLI::IsMember({"all", "train", "val", "test"}));
  app.add_option("--out", a->out)->required();
  app.add_option("--refine-steps", a->refine_steps,
                 "refine each mu by this many Adam steps on the model's own inside/outside "
                 "points (0 = the encoder's mu; logvar is kept)")
      ->check(CLI::Range(0, 10000));
  app.add_option("--refine-lr", a->refine_lr, "learning rate of the latent refinement");
  app.add_option("--append", a->append,
                 "start from this pool (its entries and mesh paths first), e.g. the shipped pool "
                 "plus real furniture (dimr cad import)");
  app.callback([a]() { RunEncodePool(*a); });
}

void SetupInterp(CLI::App& app) {
  auto a = std::make_shared<InterpArgs>();
  app.add_option("--model", a->model)->required();
  app.add_option("--data", a->data)->required();
  app.add_option("--a", a->a);
  app.add_option("--b", a->b);
  app.add_option("--steps", a->steps)->check(CLI::Range(1, 100));
  app.add_option("--out-dir", a->out_dir)->required();
  tools::AddBspDilationOption(app, &a->dilation);
  app.callback([a]() { RunInterpolate(*a); });
}

void SetupBench(CLI::App& app) {
  auto a = std::make_shared<BenchArgs>();
  app.add_option("--model", a->model)->required();
  app.add_option("--data", a->data)->required();
  app.add_option("--count", a->count)->check(CLI::Range(1, 100000));
  app.add_option("--json", a->json);
  tools::AddBspDilationOption(app, &a->dilation);
  app.callback([a]() { RunBench(*a); });
}

const Registrar kEval("bsp", "eval", "Volumetric IoU of decoded vs. original shapes", &SetupEval);
const Registrar kInterp("bsp", "interpolate", "Decode meshes along a latent interpolation",
                        &SetupInterp);
const Registrar kTrain("train", "bsp", "Train the BSP-CVAE shape autoencoder", &SetupTrain);
const Registrar kPool("", "encode-pool", "Encode CAD models into the latent shape pool",
                      &SetupPool);
const Registrar kBench("bench", "bsp", "Decode + mesh extraction time per object", &SetupBench);

}  // namespace
}  // namespace dimr::tools

#endif  // DIMR_HAVE_NN && DIMR_HAVE_PIPELINE
