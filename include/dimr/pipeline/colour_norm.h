// Per-scene colour standardisation to the training distribution (a test-time input
// normalisation for real scans, docs/real.md "Colour standardisation").
//
// Stage 1 uses xyz + rgb. SynthScan rooms and real RGB-D scans differ most in colour: the
// training rooms have a per-room mean of ~0.69 and a per-channel spread of ~0.11 (0-1 units),
// a ScanNet room ~0.44 and ~0.27 (darker, 2.5x more contrast, another white balance). Mapping
// each channel of a scene affinely so that its mean and standard deviation become the training
// rooms' averages removes exposure, white balance and contrast differences before the network
// sees the colours; on a training-like room it is close to the identity. The targets are
// measured on the training rooms (`dimr stage1 colour-stats`) and stored in the model card
// (`recommended_inference: ... colour_norm=m_r,m_g,m_b,s_r,s_g,s_b`). LibTorch-free.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace dimr::pipeline {

struct ColourStats {
  Eigen::Vector3f mean = Eigen::Vector3f::Zero();  // per channel, [0, 1] units
  Eigen::Vector3f std = Eigen::Vector3f::Zero();   // per channel (population), >= 0

  // "m_r,m_g,m_b,s_r,s_g,s_b" (6 numbers, %.4f).
  std::string ToString() const;
  // Parses the text form; empty or "none" gives false (no normalisation). Throws
  // dimr::InvalidArgument for another count, a value that is not finite, a mean outside [0, 1]
  // or a standard deviation outside (0, 1].
  static bool Parse(const std::string& text, ColourStats* out);
};

// Mean and standard deviation per channel of `colours`. Throws dimr::InvalidArgument for an
// empty list or a colour that is not finite.
ColourStats MeasureColourStats(const std::vector<Eigen::Vector3f>& colours);

// The training target of a set of rooms: the average of their per-room means and of their
// per-room standard deviations (a scene is standardised per room, so per-room statistics are
// what it must match). Throws dimr::InvalidArgument for an empty list.
ColourStats AverageRoomColourStats(const std::vector<ColourStats>& rooms);

// `colours` mapped per channel by c' = target.mean + (c - mean) * target.std / std, with the
// scene's own mean and std, clamped to [0, 1]. A channel whose spread is below 1e-4 (a flat
// colour, e.g. a grey cloud) is only shifted to the target mean. Empty in, empty out.
std::vector<Eigen::Vector3f> StandardiseColours(const std::vector<Eigen::Vector3f>& colours,
                                                const ColourStats& target);

}  // namespace dimr::pipeline
