// dimr-fuzz-libs: dimr_geometry
// Fuzz target for mesh cleaning and quadric decimation (geometry/mesh_simplify.h) on arbitrary,
// mostly broken meshes: duplicate and degenerate faces, non-manifold fans, coincident or
// collinear vertices, out-of-range indices, NaN / huge coordinates. Input bytes: one byte of
// vertex count, one of target share, then 3 x int8 per vertex (scaled; the byte 0x80 is NaN)
// and 3 x uint8 indices per face (an index >= the vertex count must be rejected).
// Every call must return or throw dimr::InvalidArgument; a result must be a valid mesh no
// larger than its input. Anything else (a crash, a hang, another exception, a failed check)
// is a finding.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "dimr/geometry/error.h"
#include "dimr/geometry/mesh_simplify.h"

namespace {

void Check(bool ok, const char* what) {
  if (!ok) throw std::logic_error(std::string("fuzz_mesh_simplify: ") + what);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using dimr::geometry::Vec3;
  using dimr::geometry::Vec3i;
  if (size < 2) return 0;
  const std::size_t nv = data[0] % 64;
  const double share = data[1] / 255.0;
  std::size_t pos = 2;
  std::vector<Vec3> vertices;
  bool finite = true;
  for (std::size_t v = 0; v < nv && pos + 3 <= size; ++v, pos += 3) {
    Vec3 p;
    for (int k = 0; k < 3; ++k) {
      const auto b = static_cast<std::int8_t>(data[pos + k]);
      p[k] = b == -128 ? std::numeric_limits<double>::quiet_NaN() : 0.01 * b;
    }
    finite = finite && p.allFinite();
    vertices.push_back(p);
  }
  std::vector<Vec3i> faces;
  bool in_range = true;
  for (; pos + 3 <= size; pos += 3) {
    Vec3i f(data[pos], data[pos + 1], data[pos + 2]);
    for (int k = 0; k < 3; ++k) in_range = in_range && f[k] < static_cast<int>(vertices.size());
    faces.push_back(f);
  }

  dimr::geometry::QuadricDecimationConfig config;
  config.target_faces = static_cast<std::size_t>(share * faces.size());
  config.invertible_determinant = (data[1] & 1) ? 0.0 : 1e-4;
  try {
    const dimr::geometry::TriangleMesh out =
        dimr::geometry::DecimateQuadric(vertices, faces, config);
    Check(in_range && finite, "accepted a bad mesh");
    Check(out.faces.size() <= faces.size(), "more faces than the input");
    for (const Vec3i& f : out.faces) {
      for (int k = 0; k < 3; ++k)
        Check(f[k] >= 0 && f[k] < static_cast<int>(out.vertices.size()), "index out of range");
    }
    for (const Vec3& p : out.vertices) Check(p.allFinite(), "non-finite vertex");
  } catch (const dimr::InvalidArgument&) {
    Check(!in_range || !finite, "rejected a valid mesh");
  }

  dimr::geometry::TriangleMesh mesh;
  mesh.vertices = vertices;
  mesh.faces = faces;
  try {
    const auto stats = dimr::geometry::RemoveSmallComponents(&mesh, data[1] % 8);
    Check(in_range, "cleaning accepted an out-of-range index");
    Check(stats.removed_faces + mesh.faces.size() == faces.size(), "face count does not add up");
    for (const Vec3i& f : mesh.faces) {
      Check(f[0] != f[1] && f[1] != f[2] && f[0] != f[2], "degenerate face kept");
      for (int k = 0; k < 3; ++k)
        Check(f[k] >= 0 && f[k] < static_cast<int>(mesh.vertices.size()), "index out of range");
    }
  } catch (const dimr::InvalidArgument&) {
    Check(!in_range, "cleaning rejected a valid mesh");
  }
  return 0;
}
