// PLY reading and writing (ascii, binary_little_endian, binary_big_endian).
// Reads vertices (x, y, z [+ nx, ny, nz] [+ red, green, blue [alpha]] [+ any other scalar
// properties, kept as VertexAttribute with their type, e.g. ScanNet's `label`]) and faces
// (`vertex_indices` or `vertex_index` list; polygons are fan-triangulated). Other elements
// are skipped correctly. Malformed input throws dimr::ParseError naming the file and the
// problem; claimed counts are checked against the remaining bytes before allocating.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "dimr/geometry/types.h"

namespace dimr::geometry {

enum class PlyFormat { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

// The PLY name of a format ("ascii", "binary_little_endian", "binary_big_endian").
const char* PlyFormatName(PlyFormat format);

// What a PLY header declares (used by `dimr mesh info`).
struct PlyHeader {
  struct Element {
    std::string name;
    std::uint64_t count = 0;
    std::vector<std::string>
        properties;  // as declared, e.g. "float x", "list uchar int vertex_indices"
  };
  PlyFormat format = PlyFormat::kAscii;
  std::vector<Element> elements;
  std::vector<std::string> comments;  // comment and obj_info lines, without the keyword
  std::size_t body_offset = 0;        // byte offset of the first body byte
};
PlyHeader ParsePlyHeader(const std::uint8_t* data, std::size_t size, const std::string& source);
PlyHeader ReadPlyHeader(const std::string& path);

struct PlyWriteOptions {
  PlyFormat format = PlyFormat::kBinaryLittleEndian;
  bool write_normals = true;      // if present
  bool write_colors = true;       // if present
  bool write_attributes = true;   // extra per-vertex properties
  bool double_precision = false;  // vertex coordinates as double instead of float
};

// Mesh (faces may be empty: then it is a vertex-only PLY, e.g. a ScanNet cloud).
TriangleMesh ReadPlyMesh(const std::string& path);
// Parses PLY bytes held in memory; `source` names the data in error messages.
TriangleMesh ParsePlyMesh(const std::uint8_t* data, std::size_t size, const std::string& source);
// Vertices only (faces ignored).
PointCloud ReadPlyCloud(const std::string& path);
PointCloud ParsePlyCloud(const std::uint8_t* data, std::size_t size, const std::string& source);

void WritePly(const std::string& path, const TriangleMesh& mesh, const PlyWriteOptions& opt = {});
void WritePly(const std::string& path, const PointCloud& cloud, const PlyWriteOptions& opt = {});
// Polygon mesh (n-gons, e.g. BSP convex faces) as `property list uchar int vertex_indices`.
void WritePlyPolygons(const std::string& path, const std::vector<Vec3>& vertices,
                      const std::vector<std::vector<int>>& polygons,
                      PlyFormat format = PlyFormat::kAscii);

namespace detail {
// Whole-file helpers shared by the mesh readers/writers: one bulk read, one bulk write.
// Reading throws ParseError(path, reason); writing throws dimr::Error naming the path.
std::vector<std::uint8_t> ReadFileBytes(const std::string& path);
void WriteFileBytes(const std::string& path, std::string_view bytes);
// The first 40 characters of `s` with non-printable bytes as \xNN (for error messages).
std::string Printable(std::string_view s);
}  // namespace detail

}  // namespace dimr::geometry
