// Turns a CAD mesh into a BSP-CVAE training sample (dimr-method.md 5.5, adapted): per-axis
// normalisation of the mesh bounds to [-s, s]^3 with s = 1 - 1/R, a fine filled voxelisation
// (geometry::VoxelizeFilled, closes the union of closed parts and any cavity-free interior)
// labels query points inside/outside; the encoder grid marks every R^3 cell that touches the
// solid, the IoU target grid every cell whose centre is inside.
#pragma once

#include <cstdint>
#include <string>

#include "dimr/geometry/types.h"
#include "dimr/nn/bsp_dataset.h"

namespace dimr::pipeline {

struct BspSampleOptions {
  int resolution = 32;             // R, the encoder grid
  int fine_factor = 4;             // fine labelling grid = fine_factor * R cells per axis
  int surface_points = 3000;       // near-surface query points (surface samples + Gaussian noise)
  int uniform_points = 2000;       // uniform query points in [-1, 1]^3
  double surface_sigma = 0.03;     // noise of the near-surface points (normalised units)
  int max_points_per_side = 1024;  // cap of the inside / outside pools
};

// `mesh` in any frame (its bounds are normalised per axis). Throws dimr::InvalidArgument for
// an empty or degenerate mesh (zero extent on an axis).
nn::BspSample MakeBspSample(const geometry::TriangleMesh& mesh, int cad_class,
                            const std::string& model_id, const BspSampleOptions& options,
                            std::uint64_t seed);

// Per-axis normalisation used by MakeBspSample: v -> (2 (v - min) / (max - min) - 1) * s.
geometry::TriangleMesh NormalizeForBsp(const geometry::TriangleMesh& mesh, int resolution);

}  // namespace dimr::pipeline
