// Per-scene colour standardisation into the training distribution (a test-time input
// normalisation for real scans, docs/real.md "Colour standardisation").
//
// Stage 1 uses xyz + rgb. SynthScan rooms and real RGB-D scans differ most in colour: the
// training rooms' per-room colour means lie in ~0.51-0.80 and their per-channel spreads in
// ~0.045-0.17 (0-1 units); a ScanNet room has ~0.44 and ~0.27 (darker, 2-3x the contrast,
// another white balance). Each channel of a scene is mapped affinely so that its mean and
// standard deviation move to the nearest values inside the range the training rooms span: a
// scene whose statistics already lie in that range (every training-like room) is left exactly
// as it is; an out-of-range one (exposure, white balance, contrast of another sensor) is
// brought to the edge of the training distribution. Mapping every room to the training average
// instead helps the real room a little more but costs SynthScan test mIoU 0.801 -> 0.768: the
// network uses a room's overall colour. The range is measured on the training rooms
// (`dimr stage1 colour-stats`) and stored in the model card
// (`recommended_inference: ... colour_norm=<12 values>`). LibTorch-free.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace dimr::pipeline {

struct ColourStats {
  Eigen::Vector3f mean = Eigen::Vector3f::Zero();  // per channel, [0, 1] units
  Eigen::Vector3f std = Eigen::Vector3f::Zero();   // per channel (population), >= 0
};

// The box of per-room statistics a model was trained on.
struct ColourRange {
  Eigen::Vector3f mean_min = Eigen::Vector3f::Zero(), mean_max = Eigen::Vector3f::Ones();
  Eigen::Vector3f std_min = Eigen::Vector3f::Zero(), std_max = Eigen::Vector3f::Ones();

  // The statistics inside the range nearest to `s` (per channel clamped).
  ColourStats Nearest(const ColourStats& s) const;
  // "mean_min r,g,b, mean_max r,g,b, std_min r,g,b, std_max r,g,b" (12 numbers, %.4f).
  std::string ToString() const;
  // Parses the text form; empty or "none" gives false (no normalisation). Throws
  // dimr::InvalidArgument for another count, a value that is not finite or outside [0, 1], a
  // minimum above its maximum, or a zero largest spread.
  static bool Parse(const std::string& text, ColourRange* out);
};

// Mean and standard deviation per channel of `colours`. Throws dimr::InvalidArgument for an
// empty list or a colour that is not finite.
ColourStats MeasureColourStats(const std::vector<Eigen::Vector3f>& colours);

// The range spanned by rooms' statistics (per channel min / max of their means and spreads).
// Throws dimr::InvalidArgument for an empty list.
ColourRange RangeOfRooms(const std::vector<ColourStats>& rooms);

// `colours` mapped per channel by c' = t.mean + (c - mean) * t.std / std with the scene's own
// mean / std and t = range.Nearest(own), clamped to [0, 1]. A channel whose spread is below
// 1e-4 (a flat colour, e.g. a grey cloud) is only shifted. `changed` (optional) tells whether
// any channel was mapped; when not, the colours come back unchanged (bit-identical). Empty in,
// empty out.
std::vector<Eigen::Vector3f> StandardiseColours(const std::vector<Eigen::Vector3f>& colours,
                                                const ColourRange& range, bool* changed = nullptr);

}  // namespace dimr::pipeline
