// `dimr mesh info <file>` and `dimr mesh convert <in> <out>`: inspect and convert PLY/OBJ
// meshes and point clouds.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>

#include "dimr/geometry/error.h"
#include "dimr/geometry/obj_io.h"
#include "dimr/geometry/ply_io.h"
#include "tools/command_registry.h"

namespace {

using dimr::geometry::PlyFormat;
using dimr::geometry::TriangleMesh;

std::string Vec(const dimr::geometry::Vec3& v) {
  char buf[128];
  std::snprintf(buf, sizeof(buf), "(%.9g, %.9g, %.9g)", v.x(), v.y(), v.z());
  return buf;
}

void PrintInfo(const std::string& path) {
  const std::string ext = dimr::geometry::LowerExtension(path);
  std::string format = "obj";
  if (ext == ".ply") {
    const auto header = dimr::geometry::ReadPlyHeader(path);
    format = std::string("ply ") + dimr::geometry::PlyFormatName(header.format);
    std::printf("file:           %s\nformat:         %s\n", path.c_str(), format.c_str());
    for (const auto& c : header.comments) std::printf("comment:        %s\n", c.c_str());
    for (const auto& e : header.elements) {
      std::string props;
      for (const auto& p : e.properties) props += (props.empty() ? "" : ", ") + p;
      std::printf("element:        %s %llu (%s)\n", e.name.c_str(),
                  static_cast<unsigned long long>(e.count), props.c_str());
    }
  } else {
    std::printf("file:           %s\nformat:         %s\n", path.c_str(), format.c_str());
  }
  const TriangleMesh mesh = dimr::geometry::ReadMesh(path);
  std::printf("vertices:       %zu\n", mesh.vertices.size());
  std::printf("faces:          %zu (triangles after fan triangulation)\n", mesh.faces.size());
  std::printf("normals:        %s\n", mesh.vertex_normals.empty() ? "no" : "yes");
  std::printf("colors:         %s\n", mesh.vertex_colors.empty() ? "no" : "yes");
  if (mesh.attributes.empty()) std::printf("attributes:     none\n");
  for (const auto& a : mesh.attributes) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (double v : a.values) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    std::printf("attribute:      %s (%s), range [%.9g, %.9g]\n", a.name.c_str(),
                dimr::geometry::ScalarName(a.type), lo, hi);
  }
  const auto box = mesh.Bounds();
  if (box.Empty()) {
    std::printf("bounds:         empty\n");
  } else {
    std::printf("bounds:         min %s max %s\n", Vec(box.min).c_str(), Vec(box.max).c_str());
    std::printf("extent:         %s\n", Vec(box.Extent()).c_str());
  }
  std::size_t degenerate = 0;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    if (!(mesh.FaceArea(f) > 0)) ++degenerate;
  }
  std::printf("surface area:   %.9g\n", mesh.SurfaceArea());
  std::printf("signed volume:  %.9g\n", mesh.SignedVolume());
  std::printf("degenerate:     %zu faces with zero area\n", degenerate);
  std::string finite = "yes";
  try {
    mesh.Validate(path);
  } catch (const dimr::Error& e) {
    finite = std::string("no: ") + e.what();
  }
  std::printf("finite:         %s\n", finite.c_str());
}

void SetupInfo(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  app.add_option("file", *path, "PLY or OBJ file")->required();
  app.callback([path]() { PrintInfo(*path); });
}

struct ConvertArgs {
  std::string in, out;
  bool ascii = false, binary_le = false, binary_be = false, double_precision = false;
  int precision = 8;
};

void Convert(const ConvertArgs& a) {
  const TriangleMesh mesh = dimr::geometry::ReadMesh(a.in);
  const std::string ext = dimr::geometry::LowerExtension(a.out);
  const int n_format = int(a.ascii) + int(a.binary_le) + int(a.binary_be);
  if (n_format > 1) {
    throw dimr::InvalidArgument(
        "mesh convert: give at most one of --ascii, --binary-le, --binary-be");
  }
  if (ext == ".ply") {
    dimr::geometry::PlyWriteOptions opt;
    if (a.ascii) opt.format = PlyFormat::kAscii;
    if (a.binary_be) opt.format = PlyFormat::kBinaryBigEndian;
    opt.double_precision = a.double_precision;
    dimr::geometry::WritePly(a.out, mesh, opt);
    std::printf("wrote %s (ply %s): %zu vertices, %zu faces\n", a.out.c_str(),
                dimr::geometry::PlyFormatName(opt.format), mesh.vertices.size(), mesh.faces.size());
  } else if (ext == ".obj") {
    if (n_format > 0 || a.double_precision) {
      throw dimr::InvalidArgument(
          "mesh convert: --ascii/--binary-le/--binary-be/--double apply to .ply output only");
    }
    dimr::geometry::WriteObj(a.out, mesh, a.precision);
    std::printf("wrote %s (obj, %d decimals): %zu vertices, %zu faces\n", a.out.c_str(),
                a.precision, mesh.vertices.size(), mesh.faces.size());
  } else {
    throw dimr::InvalidArgument("mesh convert: cannot write '" + a.out + "': unsupported format '" +
                                ext + "' (expected .ply or .obj)");
  }
}

void SetupConvert(CLI::App& app) {
  auto args = std::make_shared<ConvertArgs>();
  app.add_option("input", args->in, "PLY or OBJ file to read")->required();
  app.add_option("output", args->out, "PLY or OBJ file to write (format by extension)")->required();
  app.add_flag("--ascii", args->ascii, "PLY output: ascii");
  app.add_flag("--binary-le", args->binary_le, "PLY output: binary little endian (default)");
  app.add_flag("--binary-be", args->binary_be, "PLY output: binary big endian");
  app.add_flag("--double", args->double_precision, "PLY output: double vertex coordinates");
  app.add_option("--precision", args->precision, "OBJ output: decimals per coordinate")
      ->check(CLI::Range(0, 17));
  app.callback([args]() { Convert(*args); });
}

const dimr::tools::Registrar kRegInfo(
    "mesh", "info",
    "Show format, counts, attributes, bounds, area, volume of a PLY/OBJ mesh or cloud", &SetupInfo);
const dimr::tools::Registrar kRegConvert("mesh", "convert",
                                         "Convert between PLY (ascii/binary) and OBJ",
                                         &SetupConvert);

}  // namespace
