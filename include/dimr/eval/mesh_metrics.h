// Pairwise mesh metrics of the DIMR protocol (spec ../shared/reference/dimr-metrics.md
// sections 3-5): mesh IoU on the reference voxel set, Chamfer distance, point coverage ratio.
// LFD is in lfd.h.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "dimr/geometry/kdtree.h"
#include "dimr/geometry/mesh_distance.h"
#include "dimr/geometry/types.h"

namespace dimr::eval {

// `reference`: the numbers the paper's scripts print (quirks reproduced where they change
// numbers); `corrected`: symmetric LFD with the GT eccentricity, exact voxel pitch, one
// deterministic sample set per mesh for CD. docs/evaluation.md compares them.
enum class Protocol { kReference, kCorrected };
const char* ProtocolName(Protocol p);
// "reference" | "corrected"; throws dimr::InvalidArgument otherwise.
Protocol ParseProtocol(const std::string& name);

constexpr double kIouVoxelSize = 0.047;  // metres
constexpr std::size_t kCdSamples = 4096;
constexpr double kPcrOmega = 0.047;  // metres

// Chamfer distance of two point sets (spec section 4): 1/2 * (mean over b of the distance to
// the nearest point of a + mean over a of the distance to the nearest point of b), plain
// (not squared) Euclidean. NaN if either set is empty.
double ChamferDistance(const geometry::KdTree& a, const geometry::KdTree& b);
double ChamferDistance(const std::vector<geometry::Vec3>& a, const std::vector<geometry::Vec3>& b);
// `n` area-weighted uniform surface samples of a mesh (seeded).
std::vector<geometry::Vec3> ChamferSamples(const geometry::TriangleMesh& mesh, std::uint64_t seed,
                                           std::size_t n = kCdSamples);

// Point coverage ratio (spec section 5): fraction of `points` whose exact distance to the mesh
// surface is < omega (strict). 0 for an empty point set or a mesh without faces.
double PointCoverageRatio(const geometry::MeshDistance& mesh,
                          const std::vector<geometry::Vec3>& points, double omega = kPcrOmega);

// SplitMix64 finaliser, used to derive per-pair seeds.
std::uint64_t MixSeed(std::uint64_t a, std::uint64_t b);

}  // namespace dimr::eval
