// Voxelisation of triangle meshes: surface voxels, filled (solid) voxels, and the
// reference-compatible voxel set used by the DIMR/RfD-Net mesh-IoU protocol
// (docs/evaluation.md; spec ../shared/reference/dimr-metrics.md section 3).
#pragma once

#include <cstdint>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::geometry {

// A dense boolean grid of n.x * n.y * n.z cells of edge `voxel_size`, cell (i,j,k) covering
// [origin + (i,j,k)*voxel_size, origin + (i+1,j+1,k+1)*voxel_size).
struct VoxelGrid {
  Vec3 origin = Vec3::Zero();
  double voxel_size = 1.0;
  Vec3i dims = Vec3i::Zero();
  std::vector<std::uint8_t> occupied;  // x fastest: index = i + dims.x*(j + dims.y*k)

  std::size_t Index(int i, int j, int k) const {
    return static_cast<std::size_t>(i) +
           static_cast<std::size_t>(dims.x()) *
               (static_cast<std::size_t>(j) + static_cast<std::size_t>(dims.y()) * k);
  }
  bool At(int i, int j, int k) const { return occupied[Index(i, j, k)] != 0; }
  std::size_t Count() const;
  Vec3 CellCenter(int i, int j, int k) const {
    return origin + (Vec3(i, j, k).array() + 0.5).matrix() * voxel_size;
  }
};

// Grid of `voxel_size` covering the mesh bounds plus `padding` cells on every side.
VoxelGrid MakeGrid(const AABB& bounds, double voxel_size, int padding = 1);

// Cells intersected by any triangle (separating-axis triangle/box test).
void VoxelizeSurface(const TriangleMesh& mesh, VoxelGrid* grid);
// Surface cells plus every cell not reachable from the grid border through empty cells
// (solid fill; closes enclosed cavities). The grid needs >= 1 cell of padding.
void VoxelizeFilled(const TriangleMesh& mesh, VoxelGrid* grid);

// The reference mesh-IoU voxel set (binvox via trimesh, reproduced): per mesh its own cubic
// grid with origin t = min over ALL vertices, E = max extent, d = max(2, int(E / pitch)),
// d^3 cells of side E/d covering [t, t + E]^3.
//   S = cells overlapping any triangle (separating-axis test, cell half-size x 1.02);
//   C = cells whose centre lies between the first and last intersection of the lines
//       through it parallel to x, y and z (all three) with the mesh (3-axis carving);
//   U = S union C.
// A mesh without faces or with zero extent gives d = 0 and empty sets.
struct ReferenceVoxels {
  Vec3 t = Vec3::Zero();
  double extent = 0;  // E
  int d = 0;
  bool exact_pitch = false;  // as passed to VoxelizeReference (the sets do not depend on it)
  std::vector<std::uint8_t> surface;  // S: exact surface cells (half-size enlarged by 2%)
  std::vector<std::uint8_t> united;   // U = S union C (3-axis carving set)
  std::size_t Index(int i, int j, int k) const {
    return static_cast<std::size_t>(i) +
           static_cast<std::size_t>(d) *
               (static_cast<std::size_t>(j) + static_cast<std::size_t>(d) * k);
  }
  // trimesh's (buggy) cell point: t + index * E / (d - 1).
  Vec3 CellPoint(int i, int j, int k) const;
  // The true cell centre t + (index + 0.5) * E / d.
  Vec3 CellCentre(int i, int j, int k) const;
  // trimesh is_filled: indices round((p - t) * (d - 1) / E), half to even; all in [0, d) and
  // the cell in U.
  bool IsFilled(const Vec3& p) const;
  // Corrected lookup: indices floor((p - t) * d / E), all in [0, d), the cell in U.
  bool IsFilledExact(const Vec3& p) const;
  std::size_t SurfaceCount() const;
  std::size_t UnitedCount() const;
};

// `exact_pitch` = false reproduces the reference (cell side E/d, points at E/(d-1));
// true uses cell centres t + (idx + 0.5) * E / d for points and lookups (the corrected protocol).
// The voxel sets are the same either way; the flag is recorded in the result. Throws
// InvalidArgument for pitch <= 0, an invalid mesh, or more than 1024 cells per axis.
ReferenceVoxels VoxelizeReference(const TriangleMesh& mesh, double pitch = 0.047,
                                  bool exact_pitch = false);

// The reference mesh IoU of two voxelised meshes (metrics spec 3.3): with n_A = |U_A| and
// h_A = #cells of U_A whose CellPoint is IsFilled in B (likewise B), alpha1 = h_A/n_A,
// alpha2 = h_B/n_B, IoU = alpha1*alpha2 / (alpha1 + alpha2 - alpha1*alpha2); 0 if S_A or S_B
// is empty or h_A or h_B is 0. `exact_pitch` = true uses CellCentre and IsFilledExact.
double ReferenceMeshIoU(const ReferenceVoxels& a, const ReferenceVoxels& b,
                        bool exact_pitch = false);

}  // namespace dimr::geometry
