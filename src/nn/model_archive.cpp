#include "dimr/nn/model_archive.h"

#include <torch/serialize.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "dimr/geometry/error.h"

namespace dimr::nn {

void SaveModelArchive(const torch::nn::Module& module, const std::string& path,
                      const std::string& kind, const std::string& config, bool half,
                      const std::map<std::string, std::int64_t>& ints) {
  torch::serialize::OutputArchive archive;
  archive.write("dimr_kind", c10::IValue(kind));
  archive.write("dimr_config", c10::IValue(config));
  for (const auto& [key, value] : ints) archive.write("dimr_" + key, c10::IValue(value));
  for (const auto& item : module.named_parameters()) {
    auto t = item.value().detach().to(torch::kCPU);
    archive.write("param/" + item.key(), half ? t.to(torch::kHalf) : t, /*is_buffer=*/true);
  }
  for (const auto& item : module.named_buffers()) {
    auto t = item.value().detach().to(torch::kCPU);
    if (half && t.is_floating_point()) t = t.to(torch::kHalf);
    archive.write("buffer/" + item.key(), t, /*is_buffer=*/true);
  }
  try {
    archive.save_to(path);
  } catch (const c10::Error& e) {
    throw Error("cannot write model '" + path + "': " + e.what_without_backtrace());
  }
}

struct ModelArchiveReader::Archive {
  mutable torch::serialize::InputArchive in;
};

ModelArchiveReader::ModelArchiveReader(const std::string& path, const std::string& kind,
                                       const std::string& what,
                                       const std::vector<std::string>& int_keys)
    : path_(path), archive_(std::make_unique<Archive>()) {
  if (!std::filesystem::exists(path)) throw ParseError(path, "file does not exist");
  try {
    archive_->in.load_from(path);
    c10::IValue v;
    if (!archive_->in.try_read("dimr_kind", v) || !v.isString() || v.toStringRef() != kind) {
      throw ParseError(path, "not a dimr " + what + " model (missing or wrong 'dimr_kind')");
    }
    if (!archive_->in.try_read("dimr_config", v) || !v.isString()) {
      throw ParseError(path, "missing 'dimr_config'");
    }
    config_ = v.toStringRef();
    for (const auto& key : int_keys) {
      if (!archive_->in.try_read("dimr_" + key, v) || !v.isInt()) {
        throw ParseError(path, "missing 'dimr_" + key + "'");
      }
      ints_[key] = v.toInt();
    }
  } catch (const c10::Error& e) {
    throw ParseError(
        path, std::string("corrupt or unreadable model archive: ") + e.what_without_backtrace());
  }
}

ModelArchiveReader::~ModelArchiveReader() = default;

void ModelArchiveReader::LoadInto(torch::nn::Module& module) const {
  torch::NoGradGuard no_grad;
  auto load_into = [&](const std::string& key, torch::Tensor& dst) {
    torch::Tensor t;
    bool found = false;
    try {
      found = archive_->in.try_read(key, t, /*is_buffer=*/true);
    } catch (const c10::Error& e) {
      throw ParseError(path_, "tensor '" + key + "' unreadable: " + e.what_without_backtrace());
    }
    if (!found) throw ParseError(path_, "missing tensor '" + key + "'");
    if (t.sizes() != dst.sizes()) {
      std::ostringstream msg;
      msg << "tensor '" << key << "' has shape " << t.sizes() << ", the model expects "
          << dst.sizes();
      throw ParseError(path_, msg.str());
    }
    if (t.is_floating_point() && !torch::isfinite(t).all().item<bool>()) {
      throw ParseError(path_, "tensor '" + key + "' holds NaN or infinite values");
    }
    dst.copy_(t.to(dst.dtype()));
  };
  for (auto& item : module.named_parameters()) load_into("param/" + item.key(), item.value());
  for (auto& item : module.named_buffers()) load_into("buffer/" + item.key(), item.value());
}

void SaveTrainingCheckpoint(const torch::nn::Module& module, torch::optim::Optimizer& optimizer,
                            const std::string& path, const std::string& kind,
                            const std::string& config, const std::vector<std::int64_t>& state,
                            const std::map<std::string, std::int64_t>& ints) {
  SaveModelArchive(module, path + ".tmp", kind, config, /*half=*/false, ints);
  std::filesystem::rename(path + ".tmp", path);
  torch::save(optimizer, path + ".optim.tmp");
  std::filesystem::rename(path + ".optim.tmp", path + ".optim");
  {
    std::ofstream f(path + ".state.tmp");
    for (std::size_t i = 0; i < state.size(); ++i) f << (i ? " " : "") << state[i];
    f << "\n";
    if (!f) throw Error("cannot write training state '" + path + ".state'");
  }
  std::filesystem::rename(path + ".state.tmp", path + ".state");
}

std::vector<std::int64_t> ResumeTrainingCheckpoint(torch::nn::Module& module,
                                                   torch::optim::Optimizer& optimizer,
                                                   const std::string& path, const std::string& kind,
                                                   const std::string& what,
                                                   const std::string& config,
                                                   std::size_t state_size) {
  const std::string state_path = path + ".state";
  if (path.empty() || !std::filesystem::exists(path) || !std::filesystem::exists(state_path)) {
    return {};
  }
  const ModelArchiveReader archive(path, kind, what);
  if (archive.config() != config) {
    throw InvalidArgument("checkpoint '" + path + "' has a different configuration: " +
                          archive.config() + " (this run: " + config + ")");
  }
  archive.LoadInto(module);
  std::vector<std::int64_t> state;
  std::ifstream f(state_path);
  for (std::int64_t v; f >> v;) state.push_back(v);
  if (state.size() < state_size) {
    throw ParseError(state_path, "expected " + std::to_string(state_size) +
                                     " integers (the trainer's position), found " +
                                     std::to_string(state.size()));
  }
  const std::string optim_path = path + ".optim";
  if (std::filesystem::exists(optim_path)) {
    try {
      torch::load(optimizer, optim_path);
    } catch (const c10::Error&) {
      std::fprintf(stderr, "warning: optimizer state '%s' unreadable, restarting the optimizer\n",
                   optim_path.c_str());
    }
  }
  return state;
}

}  // namespace dimr::nn
