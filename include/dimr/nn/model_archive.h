// Model files shared by the dimr networks (BSP-CVAE, stage 1): a torch::serialize archive with
// a kind tag ("dimr_kind"), the configuration string ("dimr_config"), optional integer metadata
// and every parameter ("param/<name>") and buffer ("buffer/<name>") of a module. Loading checks
// the kind, every name and shape, and that floating tensors are finite; any problem is a
// dimr::ParseError naming the file (and the tensor). nn-internal (LibTorch) header.
#pragma once

#include <torch/nn/module.h>
#include <torch/optim/optimizer.h>

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace dimr::nn {

// `half` stores floating tensors as float16 (loaded back into the module's dtype).
void SaveModelArchive(const torch::nn::Module& module, const std::string& path,
                      const std::string& kind, const std::string& config, bool half,
                      const std::map<std::string, std::int64_t>& ints = {});

class ModelArchiveReader {
 public:
  // Opens `path` and checks that it is a model of `kind` (`what` names it in messages, e.g.
  // "BSP-CVAE") holding a config string and every key of `int_keys`.
  ModelArchiveReader(const std::string& path, const std::string& kind, const std::string& what,
                     const std::vector<std::string>& int_keys = {});
  ~ModelArchiveReader();

  const std::string& config() const { return config_; }
  std::int64_t Int(const std::string& key) const { return ints_.at(key); }
  // Copies every parameter and buffer of `module` from the archive.
  void LoadInto(torch::nn::Module& module) const;

 private:
  std::string path_, config_;
  std::map<std::string, std::int64_t> ints_;
  struct Archive;
  std::unique_ptr<Archive> archive_;
};

// Training checkpoints of the trainers: `path` (a model archive), `path.optim` (optimizer state)
// and `path.state` (one line of integers: the trainer's position, e.g. the step). Each file is
// written to a temporary name and renamed, so an interrupted write never corrupts a checkpoint.
void SaveTrainingCheckpoint(const torch::nn::Module& module, torch::optim::Optimizer& optimizer,
                            const std::string& path, const std::string& kind,
                            const std::string& config, const std::vector<std::int64_t>& state,
                            const std::map<std::string, std::int64_t>& ints = {});
// If `path` and `path.state` exist: checks the kind and that the stored config equals `config`
// (dimr::InvalidArgument otherwise), loads the weights into `module` and the optimizer state
// (a warning and a fresh optimizer if that file is unreadable) and returns the state integers
// (dimr::ParseError if there are fewer than `state_size`). Returns {} when there is nothing to
// resume.
std::vector<std::int64_t> ResumeTrainingCheckpoint(torch::nn::Module& module,
                                                   torch::optim::Optimizer& optimizer,
                                                   const std::string& path, const std::string& kind,
                                                   const std::string& what,
                                                   const std::string& config,
                                                   std::size_t state_size);

}  // namespace dimr::nn
