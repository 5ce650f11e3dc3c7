// Ceiling removal: real room scans often hold part of the ceiling (ScanNet's fused meshes,
// a robot's map), which no training room of stage 1 has (SynthScan's ceiling is an occluder
// only). The networks then label a large horizontal surface at 2.5 m as something — a table,
// a bed — and the reconstructor builds furniture on the ceiling. `RemoveCeiling` finds the
// ceiling as the topmost large horizontal layer of the cloud and drops it (and anything above
// it) before stage 1; callers map results back with `kept` (docs/real.md "Ceilings").
//
// The rule (gravity-aligned cloud, z up):
//   1. floor level = the `floor_quantile` quantile of z;
//   2. among points higher than floor + min_height, the densest z layer of `bin` thickness
//      (summed with its two neighbours) is the candidate; its height z_c is the mean z of the
//      points within one bin of it;
//   3. it is a ceiling only if (a) it is the top of the cloud: the `top_quantile` quantile of z
//      lies within `top_margin` above z_c, and (b) it is horizontal and large: the x-y cells of
//      `cell` edge in which the layer's points (|z - z_c| <= band) have a z standard deviation
//      under `max_cell_z_std` and at most 10 % of them lower than z_c - edge (a wall crossing
//      the layer spreads over its whole thickness) cover at least `min_area` m² and
//      `min_area_fraction` of the cloud's x-y footprint;
//   4. then the layer's points in those flat cells, every point higher than z_c - edge
//      (the ceiling's rim where it meets the walls, whose points stay) and everything above
//      the layer are removed.
// A scan that stops below floor + min_height (scene0470_00: 1.37 m) or a sloped ceiling is
// left unchanged.
#pragma once

#include <cstddef>
#include <vector>

#include "dimr/pipeline/point_cloud_input.h"

namespace dimr::pipeline {

struct CeilingConfig {
  bool enabled = true;
  double min_height = 2.0;  // m above the floor level
  double floor_quantile = 0.01;
  double bin = 0.02;   // m, z histogram
  double band = 0.08;  // m, half thickness of the ceiling layer (noise, drift, fixtures)
  double edge = 0.03;  // m, outside flat cells only points this close below z_c are ceiling
  double top_quantile = 0.998;
  double top_margin = 0.15;  // m
  double cell = 0.1;         // m, x-y cells of the area test
  double max_cell_z_std = 0.02;
  double min_area = 1.5;  // m²
  double min_area_fraction = 0.1;

  // Throws dimr::InvalidArgument naming the field.
  void Validate() const;
};

struct CeilingRemoval {
  bool found = false;
  double floor_z = 0;    // the floor level used (m)
  double ceiling_z = 0;  // z_c when found
  double area = 0;  // m² of horizontal cells in the layer (the last candidate's when not found)
  PointCloudInput cloud;    // the input without the ceiling (all of it when not found)
  std::vector<int> kept;    // per point of `cloud`: its index in the input
  std::size_t removed = 0;  // input points dropped
};

// Validates `config` and the input's shape (PointCloudInput::ValidateShape: counts, finite
// coordinates; dimr::InvalidArgument naming the cloud and the bad point; an empty cloud is
// returned as it is). Deterministic; O(n log n) for the quantiles. With config.enabled false
// the cloud is returned unchanged.
CeilingRemoval RemoveCeiling(const PointCloudInput& input, const CeilingConfig& config);
// The same on a cloud the caller gives away: the result's cloud is `input` itself, compacted
// in place when a ceiling is found, moved unchanged when not (no copy either way). On an
// exception `input` is left as it was.
CeilingRemoval RemoveCeiling(PointCloudInput&& input, const CeilingConfig& config);

// Per-point values of the kept cloud back on the input: out[kept[j]] = values[j], `fill`
// elsewhere (the removed points). Throws dimr::InvalidArgument for sizes that do not match or
// an index out of range.
std::vector<int> ExpandKeptLabels(const std::vector<int>& values, const std::vector<int>& kept,
                                  std::size_t input_size, int fill);
// Indices into the kept cloud -> indices into the input.
std::vector<int> ExpandKeptPoints(const std::vector<int>& points, const std::vector<int>& kept);

}  // namespace dimr::pipeline
