// Wavefront OBJ reading and writing (v, vn, f with v/vt/vn index forms, negative indices,
// polygons fan-triangulated; other statements ignored). Errors name file and line.
#pragma once

#include <cstdint>
#include <string>

#include "dimr/geometry/types.h"

namespace dimr::geometry {

TriangleMesh ReadObj(const std::string& path);
TriangleMesh ParseObj(const std::uint8_t* data, std::size_t size, const std::string& source);
// `precision` = significant digits after the decimal point for vertex coordinates.
void WriteObj(const std::string& path, const TriangleMesh& mesh, int precision = 8);

// Reads .ply or .obj by extension (case-insensitive); throws ParseError otherwise.
TriangleMesh ReadMesh(const std::string& path);
// The lower-case extension of a path including the dot (".ply"), or "" if it has none.
std::string LowerExtension(const std::string& path);
void WriteMesh(const std::string& path, const TriangleMesh& mesh);

}  // namespace dimr::geometry
