// Triangle-mesh cleaning and quadric-error edge-collapse decimation (Garland & Heckbert 1997),
// for the ScanNet-faithful reconstruction of SynthScan v2 (data/tsdf_fusion.cpp): a marching-
// cubes mesh of a room (millions of triangles) is cleaned of small floating components and
// decimated to ScanNet's vertex density.
//
// Why our own: Open3D 0.16's TriangleMesh::ClusterConnectedTriangles and
// SimplifyQuadricDecimation keep their adjacency in hash maps keyed by Eigen vectors and took
// 75 % of a v2 room's generation time (6 s + 33 s of ~52 s, `dimr bench synth --density
// scannet`). These use flat arrays (a vertex -> face table, a binary heap of edge candidates
// invalidated by per-vertex stamps) and follow the same cost model, so the meshes have the same
// character (docs/synthscan.md, "Decimation").
#pragma once

#include <cstddef>
#include <limits>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::geometry {

// Triangles joined through shared edges (two faces touching only at a vertex are not joined).
struct FaceComponents {
  std::vector<int> component;     // per face: 0 .. size.size()-1, numbered by first face
  std::vector<std::size_t> size;  // faces per component
};

// Throws dimr::InvalidArgument naming the face when an index is outside [0, num_vertices).
FaceComponents EdgeConnectedComponents(const std::vector<Vec3i>& faces, std::size_t num_vertices);

struct CleanStats {
  std::size_t removed_components = 0;  // components below the threshold
  std::size_t removed_faces = 0;       // in those components, plus degenerate faces
  std::size_t removed_vertices = 0;    // no longer referenced afterwards
};

// In place: removes the faces of every edge-connected component with fewer than
// `min_component_faces` faces (0 keeps all), then faces with a repeated vertex index, then the
// vertices no face references. Kept faces and vertices keep their order; vertex_colors and
// vertex_normals (when one per vertex) and attributes follow the vertices.
// Throws dimr::InvalidArgument for a bad index or a negative threshold.
CleanStats RemoveSmallComponents(TriangleMesh* mesh, int min_component_faces);

struct QuadricDecimationConfig {
  // Stop when at most this many faces are left (or no collapse is possible).
  std::size_t target_faces = 0;
  // Stop before a collapse whose quadric error exceeds this (squared metres x area).
  double max_error = std::numeric_limits<double>::infinity();
  // Weight of the plane through each boundary edge, perpendicular to its face (holds borders).
  double boundary_weight = 1.0;
  // The optimal position -A^-1 b is used only when |det A| exceeds this; otherwise the best of
  // the two endpoints and the midpoint (ties: midpoint, then the lower index). 1e-4 is Open3D
  // 0.16's absolute threshold: with area-weighted planes of a 1 cm mesh (areas ~1e-4 m^2) it
  // is practically never exceeded, so vertices stay at marching-cubes positions or midpoints,
  // which is what SynthScan v2's realism statistics were tuned with. 0 = always solve when
  // the determinant is non-zero.
  double invertible_determinant = 1e-4;
  // Throws dimr::InvalidArgument naming the field.
  void Validate() const;
};

struct DecimationStats {
  std::size_t collapses = 0;
  std::size_t rejected_flips = 0;  // candidates skipped because a face would flip or vanish
  std::size_t stale_entries = 0;   // popped entries outdated by an earlier collapse
  std::size_t purged_entries = 0;  // outdated entries swept out of the heap without a pop
  double max_collapse_error = 0;   // largest quadric error of a performed collapse
};

// Quadric-error edge collapse. Vertex quadrics: the area-weighted planes of the faces around
// it, plus boundary planes. Candidates: every edge, cheapest first (ties by vertex indices, so
// the result does not depend on the heap); a collapse is skipped when a remaining face around
// either endpoint would flip its normal or lose its area. The collapsed pair keeps the lower
// index and moves to the chosen position. The result holds the surviving faces in input order
// and only referenced vertices in input order (no colours: look them up on the input).
// Throws dimr::InvalidArgument for a bad index or a non-finite vertex (naming it).
TriangleMesh DecimateQuadric(const std::vector<Vec3>& vertices, const std::vector<Vec3i>& faces,
                             const QuadricDecimationConfig& config,
                             DecimationStats* stats = nullptr);

}  // namespace dimr::geometry
