// Checkpoints: every parameter and buffer of a module, by name, in a small self-checking
// binary format (magic, version, named tensors with dtype and shape, FNV-1a checksum).
// Loading checks names and shapes against the module and reports the offending key with
// both shapes; a corrupt or truncated file gives a dimr::ParseError, never a crash.
#pragma once

#include <ATen/ATen.h>
#include <torch/nn/module.h>

#include <string>
#include <utility>
#include <vector>

namespace dimr::nn {

using NamedTensors = std::vector<std::pair<std::string, at::Tensor>>;

// All parameters and buffers (recursive, dotted names as in named_parameters()).
NamedTensors ModuleState(const torch::nn::Module& module);

// half: store floating tensors as float16 (smaller files; loaded back into the module dtype).
void WriteCheckpoint(const NamedTensors& tensors, const std::string& path, bool half = false);
NamedTensors ReadCheckpoint(const std::string& path);

void SaveCheckpoint(const torch::nn::Module& module, const std::string& path, bool half = false);
// Throws dimr::ParseError naming the key on a missing / unexpected key or a shape mismatch.
void LoadCheckpoint(torch::nn::Module& module, const std::string& path);

}  // namespace dimr::nn
