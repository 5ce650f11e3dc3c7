// Turns a CAD mesh into a BSP-CVAE training sample (dimr-method.md 5.5, adapted): per-axis
// normalisation of the mesh bounds to [-s, s]^3 with s = 1 - 1/R, a fine filled voxelisation
// (geometry::VoxelizeFilled, closes the union of closed parts and any cavity-free interior)
// labels query points inside/outside; the encoder grid marks every R^3 cell that touches the
// solid (BspCellOccupancy), `iou_grid` every cell whose centre is inside (the centre IoU).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "dimr/geometry/types.h"
#include "dimr/nn/bsp_dataset.h"
#include "dimr/pipeline/bsp_mesher.h"

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

// The R^3 cells a solid touches: the filled voxelisation (geometry::VoxelizeFilled) of a mesh in
// the box-normalised frame [-1, 1]^3 at fine_factor * R cells per axis, max-pooled to R (a cell
// is set if any of its fine cells is). This is MakeBspSample's encoder grid; applied to a
// decoded BSP mesh (closed convex polytopes) it gives the prediction of the cell IoU, so both
// sides of that IoU are built by the same operator (docs/bsp.md "IoU targets"). Parts thinner
// than a cell (legs, single-sided panels of real models) count as the cells they pass through,
// as in IM-NET / BSP-Net's max-pooled voxel models, instead of being hit or missed by a cell
// centre. An empty mesh gives an empty grid; throws dimr::InvalidArgument for resolution < 1
// or fine_factor < 1.
std::vector<std::uint8_t> BspCellOccupancy(const geometry::TriangleMesh& normalized_mesh,
                                           int resolution, int fine_factor = 4);
// The same for a decoded BSP shape, whose solid is exactly the union of its convex polytopes:
// each kept convex (the triangles of `decoded.face_convex`) is filled on its own and the union
// max-pooled, so a cavity the convexes enclose without filling (a hollow bin under a lid)
// stays empty, as the decoded occupancy has it; filling the concatenated mesh would close it.
std::vector<std::uint8_t> BspCellOccupancy(const BspMeshResult& decoded, int resolution,
                                           int fine_factor = 4);

// The left-right mirror image of a mesh in the canonical frame (x forward, y left, z up):
// y -> -y with every face's winding reversed, so a closed outward-oriented mesh stays
// outward-oriented (signed volume kept). Forward and up are unchanged, so it is a valid
// furniture shape of the same class (a training augmentation: real models are few).
geometry::TriangleMesh MirrorLeftRight(const geometry::TriangleMesh& mesh);

// Per-axis normalisation used by MakeBspSample: v -> (2 (v - min) / (max - min) - 1) * s.
geometry::TriangleMesh NormalizeForBsp(const geometry::TriangleMesh& mesh, int resolution);

}  // namespace dimr::pipeline
