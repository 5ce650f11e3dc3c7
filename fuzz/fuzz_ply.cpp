// dimr-fuzz-libs: dimr_geometry
// Fuzz target for the PLY reader: every input must either parse or throw dimr::Error
// (ParseError). Any other exception, a crash, a sanitizer report, or a returned mesh that
// fails Validate (its InvalidArgument escapes on purpose) is a finding.
#include <cstddef>
#include <cstdint>

#include "dimr/geometry/error.h"
#include "dimr/geometry/ply_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace dimr::geometry;
  TriangleMesh mesh;
  try {
    mesh = ParsePlyMesh(data, size, "fuzz.ply");
  } catch (const dimr::Error&) {
    mesh = TriangleMesh();
  }
  mesh.Validate("fuzz.ply mesh");

  PointCloud cloud;
  try {
    cloud = ParsePlyCloud(data, size, "fuzz.ply");
  } catch (const dimr::Error&) {
    cloud = PointCloud();
  }
  cloud.Validate("fuzz.ply cloud");

  try {
    ParsePlyHeader(data, size, "fuzz.ply");
  } catch (const dimr::Error&) {
  }
  return 0;
}
