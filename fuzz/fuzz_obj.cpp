// dimr-fuzz-libs: dimr_geometry
// Fuzz target for the OBJ reader: every input must either parse or throw dimr::Error
// (ParseError). Any other exception, a crash, a sanitizer report, or a returned mesh that
// fails Validate (its InvalidArgument escapes on purpose) is a finding.
#include <cstddef>
#include <cstdint>

#include "dimr/geometry/error.h"
#include "dimr/geometry/obj_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  dimr::geometry::TriangleMesh mesh;
  try {
    mesh = dimr::geometry::ParseObj(data, size, "fuzz.obj");
  } catch (const dimr::Error&) {
    mesh = dimr::geometry::TriangleMesh();
  }
  mesh.Validate("fuzz.obj mesh");
  return 0;
}
