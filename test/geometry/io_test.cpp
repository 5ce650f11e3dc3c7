// PLY / OBJ readers and writers: round trips, hand-written files, malformed input.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "dimr/geometry/error.h"
#include "dimr/geometry/obj_io.h"
#include "dimr/geometry/ply_io.h"
#include "dimr/geometry/types.h"

namespace dimr::geometry {
namespace {

class IoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = ::testing::TempDir() + "dimr_io_XXXXXX";
    ASSERT_NE(mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override { std::system(("rm -rf '" + dir_ + "'").c_str()); }

  std::string Path(const std::string& name) const { return dir_ + "/" + name; }
  std::string Write(const std::string& name, const std::string& bytes) const {
    const std::string p = Path(name);
    std::ofstream(p, std::ios::binary) << bytes;
    return p;
  }
  static std::string Slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }

  std::string dir_;
};

// Runs `fn`, expects a ParseError whose message contains every one of `parts`.
void ExpectParseError(const std::function<void()>& fn, const std::vector<std::string>& parts) {
  try {
    fn();
    ADD_FAILURE() << "no exception; expected ParseError containing '" << parts.back() << "'";
  } catch (const ParseError& e) {
    const std::string msg = e.what();
    for (const auto& p : parts) {
      EXPECT_NE(msg.find(p), std::string::npos) << "message '" << msg << "' lacks '" << p << "'";
    }
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
  }
}

template <typename T>
void PutBE(std::string* s, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  for (int i = sizeof(T) - 1; i >= 0; --i) s->push_back(b[i]);
}
template <typename T>
void PutLE(std::string* s, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  s->append(b, sizeof(T));
}

// A mesh whose values are exactly representable as float, with every attribute type.
TriangleMesh RichMesh() {
  TriangleMesh m;
  m.vertices = {Vec3(0.5, -1.25, 3), Vec3(1e-3f, 2.75, -0.125), Vec3(100.5, 0, 7.0f / 3.0f),
                Vec3(-4, 8, 16)};
  m.faces = {Vec3i(0, 1, 2), Vec3i(0, 2, 3), Vec3i(3, 2, 1)};
  m.vertex_normals = {Vec3(0, 0, 1), Vec3(0.6, 0.8, 0), Vec3(-1, 0, 0), Vec3(0.25f, 0.5, -0.75)};
  m.vertex_colors = {Color(255, 0, 7), Color(1, 2, 3), Color(128, 64, 32), Color(0, 0, 0)};
  m.SetAttribute("label", ScalarType::kUInt16, {0, 65535, 40, 1});
  m.SetAttribute("i8", ScalarType::kInt8, {-128, 127, 0, -1});
  m.SetAttribute("u8", ScalarType::kUInt8, {0, 255, 17, 3});
  m.SetAttribute("i16", ScalarType::kInt16, {-32768, 32767, 5, -5});
  m.SetAttribute("i32", ScalarType::kInt32, {-2147483648.0, 2147483647.0, 9, -9});
  m.SetAttribute("u32", ScalarType::kUInt32, {4294967295.0, 0, 123456789, 1});
  m.SetAttribute("f32", ScalarType::kFloat32,
                 {static_cast<double>(0.1f), -3.5, static_cast<double>(1e30f), 0});
  m.SetAttribute("f64", ScalarType::kFloat64, {0.1, -1e300, 1.0 / 3.0, 2.5e-310});
  return m;
}

void ExpectSameMesh(const TriangleMesh& a, const TriangleMesh& b, bool float_coords) {
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  for (std::size_t i = 0; i < a.vertices.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const double want = float_coords ? static_cast<double>(static_cast<float>(a.vertices[i][k]))
                                       : a.vertices[i][k];
      EXPECT_EQ(b.vertices[i][k], want) << "vertex " << i << " axis " << k;
      const double nwant = float_coords
                               ? static_cast<double>(static_cast<float>(a.vertex_normals[i][k]))
                               : a.vertex_normals[i][k];
      EXPECT_EQ(b.vertex_normals[i][k], nwant) << "normal " << i;
    }
  }
  ASSERT_EQ(b.vertex_colors.size(), a.vertex_colors.size());
  for (std::size_t i = 0; i < a.vertex_colors.size(); ++i) {
    EXPECT_EQ(b.vertex_colors[i], a.vertex_colors[i]) << "colour " << i;
  }
  ASSERT_EQ(a.faces.size(), b.faces.size());
  for (std::size_t f = 0; f < a.faces.size(); ++f) EXPECT_EQ(a.faces[f], b.faces[f]);
  ASSERT_EQ(a.attributes.size(), b.attributes.size());
  for (std::size_t j = 0; j < a.attributes.size(); ++j) {
    EXPECT_EQ(b.attributes[j].name, a.attributes[j].name);
    EXPECT_EQ(b.attributes[j].type, a.attributes[j].type) << a.attributes[j].name;
    ASSERT_EQ(b.attributes[j].values.size(), a.attributes[j].values.size());
    for (std::size_t i = 0; i < a.attributes[j].values.size(); ++i) {
      EXPECT_EQ(b.attributes[j].values[i], a.attributes[j].values[i])
          << a.attributes[j].name << "[" << i << "]";
    }
  }
}

// ---------------------------------------------------------------------------
// Round trips.
// ---------------------------------------------------------------------------
class PlyRoundTrip : public IoTest, public ::testing::WithParamInterface<PlyFormat> {};

TEST_P(PlyRoundTrip, MeshFloatCoordinatesAllAttributeTypes) {
  const TriangleMesh m = RichMesh();
  PlyWriteOptions opt;
  opt.format = GetParam();
  const std::string p = Path("rich.ply");
  WritePly(p, m, opt);
  EXPECT_EQ(ReadPlyHeader(p).format, GetParam());
  const TriangleMesh r = ReadPlyMesh(p);
  ExpectSameMesh(m, r, true);
  // 0.6 is not a float: it comes back float-rounded.
  EXPECT_NE(r.vertex_normals[1].x(), 0.6);
  EXPECT_EQ(r.vertex_normals[1].x(), static_cast<double>(0.6f));
}

TEST_P(PlyRoundTrip, MeshDoublePrecisionIsExact) {
  TriangleMesh m = RichMesh();
  m.vertices[0] = Vec3(0.1, 1.0 / 3.0, -123456.789012345678);
  m.vertex_normals[1] = Vec3(0.1, 0.2, 0.3);
  PlyWriteOptions opt;
  opt.format = GetParam();
  opt.double_precision = true;
  const std::string p = Path("double.ply");
  WritePly(p, m, opt);
  const TriangleMesh r = ReadPlyMesh(p);
  ExpectSameMesh(m, r, false);
  EXPECT_EQ(r.vertices[0].x(), 0.1);
  EXPECT_EQ(r.vertices[0].y(), 1.0 / 3.0);
}

TEST_P(PlyRoundTrip, CloudWithLabelAndWithoutOptionalArrays) {
  PointCloud c;
  for (int i = 0; i < 50; ++i) c.points.emplace_back(i * 0.25, -i, i * i);
  std::vector<double> label(50);
  for (int i = 0; i < 50; ++i) label[i] = i * 1000;
  c.SetAttribute("label", ScalarType::kUInt16, label);
  PlyWriteOptions opt;
  opt.format = GetParam();
  const std::string p = Path("cloud.ply");
  WritePly(p, c, opt);
  const PointCloud r = ReadPlyCloud(p);
  ASSERT_EQ(r.size(), 50u);
  EXPECT_FALSE(r.HasNormals());
  EXPECT_FALSE(r.HasColors());
  EXPECT_EQ(r.points[49], Vec3(12.25, -49, 2401));
  const VertexAttribute* a = r.FindAttribute("label");
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(a->type, ScalarType::kUInt16);
  EXPECT_EQ(a->values[49], 49000);
  // Options switch optional arrays off.
  TriangleMesh m = RichMesh();
  opt.write_normals = opt.write_colors = opt.write_attributes = false;
  WritePly(p, m, opt);
  const TriangleMesh rm = ReadPlyMesh(p);
  EXPECT_TRUE(rm.vertex_normals.empty());
  EXPECT_TRUE(rm.vertex_colors.empty());
  EXPECT_TRUE(rm.attributes.empty());
  EXPECT_EQ(rm.faces.size(), 3u);
  // A mesh read as a cloud keeps the vertices and drops the faces.
  WritePly(p, RichMesh(), PlyWriteOptions{GetParam()});
  const PointCloud rc = ReadPlyCloud(p);
  EXPECT_EQ(rc.size(), 4u);
  EXPECT_EQ(rc.colors[2], Color(128, 64, 32));
  ASSERT_NE(rc.FindAttribute("u32"), nullptr);
  EXPECT_EQ(rc.FindAttribute("u32")->values[0], 4294967295.0);
}

TEST_P(PlyRoundTrip, PolygonsAreFanTriangulated) {
  const std::vector<Vec3> v = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 1, 0),
                               Vec3(1, 2, 0), Vec3(0, 1, 0), Vec3(0.1, 0.2, 5)};
  const std::vector<std::vector<int>> polys = {{0, 1, 2, 3, 4}, {5, 0, 1}};
  const std::string p = Path("poly.ply");
  WritePlyPolygons(p, v, polys, GetParam());
  const PlyHeader h = ReadPlyHeader(p);
  ASSERT_EQ(h.elements.size(), 2u);
  EXPECT_EQ(h.elements[1].properties[0], "list uchar int vertex_indices");
  const TriangleMesh m = ReadPlyMesh(p);
  ASSERT_EQ(m.faces.size(), 4u);
  EXPECT_EQ(m.faces[0], Vec3i(0, 1, 2));
  EXPECT_EQ(m.faces[1], Vec3i(0, 2, 3));
  EXPECT_EQ(m.faces[2], Vec3i(0, 3, 4));
  EXPECT_EQ(m.faces[3], Vec3i(5, 0, 1));
  EXPECT_EQ(m.vertices[5], Vec3(0.1, 0.2, 5));  // written as double
  // Pentagon area 2.5 (shoelace); the extra triangle has |(-0.1,-0.2,-5) x (0.9,-0.2,-5)| / 2.
  const double tri = 0.5 * Vec3(-0.1, -0.2, -5).cross(Vec3(0.9, -0.2, -5)).norm();
  EXPECT_NEAR(m.FaceArea(0) + m.FaceArea(1) + m.FaceArea(2), 2.5, 1e-12);
  EXPECT_NEAR(m.SurfaceArea(), 2.5 + tri, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(AllFormats, PlyRoundTrip,
                         ::testing::Values(PlyFormat::kAscii, PlyFormat::kBinaryLittleEndian,
                                           PlyFormat::kBinaryBigEndian),
                         [](const auto& info) { return std::string(PlyFormatName(info.param)); });

TEST_F(IoTest, PlyWriterRejectsUnstorableData) {
  TriangleMesh m = RichMesh();
  m.FindAttribute("u8")->values[1] = 256;
  EXPECT_THROW(WritePly(Path("bad.ply"), m), InvalidArgument);
  m = RichMesh();
  m.FindAttribute("i16")->values[0] = 0.5;
  EXPECT_THROW(WritePly(Path("bad.ply"), m), InvalidArgument);
  m = RichMesh();
  m.faces.emplace_back(0, 1, 4);
  EXPECT_THROW(WritePly(Path("bad.ply"), m), InvalidArgument);
  m = RichMesh();
  m.vertices[0].x() = 1e300;  // does not fit a float property
  EXPECT_THROW(WritePly(Path("bad.ply"), m), InvalidArgument);
  PlyWriteOptions dbl;
  dbl.double_precision = true;
  EXPECT_NO_THROW(WritePly(Path("ok.ply"), m, dbl));
  EXPECT_EQ(ReadPlyMesh(Path("ok.ply")).vertices[0].x(), 1e300);
  EXPECT_THROW(WritePlyPolygons(Path("bad.ply"), {Vec3(0, 0, 0), Vec3(1, 1, 1)}, {{0, 1}}),
               InvalidArgument);
  EXPECT_THROW(WritePly(dir_ + "/no/such/dir/x.ply", RichMesh()), Error);
}

// ---------------------------------------------------------------------------
// Hand-written files.
// ---------------------------------------------------------------------------
TEST_F(IoTest, HandWrittenAsciiPly) {
  const std::string p = Write("hand.ply",
                              "ply\r\n"
                              "format ascii 1.0\r\n"
                              "comment made by hand\r\n"
                              "obj_info some info\r\n"
                              "element vertex 5\r\n"
                              "property float x\r\n"
                              "property float y\r\n"
                              "property double z\r\n"
                              "property float red\r\n"
                              "property float green\r\n"
                              "property float blue\r\n"
                              "property ushort label\r\n"
                              "property list uchar int extra\r\n"
                              "element face 2\r\n"
                              "property uchar flags\r\n"
                              "property list uchar uint vertex_index\r\n"
                              "property float quality\r\n"
                              "element edge 1\r\n"
                              "property int vertex1\r\n"
                              "property int vertex2\r\n"
                              "end_header\r\n"
                              "0 0 0.1 1 0 0.5 7 0\r\n"
                              "1 0 0 0 1 0 65535 2 9 9\r\n"
                              "1 1 0 0 0 1 3 0\r\n"
                              "0 1 0 0.2 0.2 0.2 4 1 -7\r\n"
                              "+2.5 -1e1 3 1 1 1 0 0\r\n"
                              "1 4 0 1 2 3 0.5\r\n"
                              "0 3 0 3 4 -1\r\n"
                              "0 1\r\n");
  const TriangleMesh m = ReadPlyMesh(p);
  ASSERT_EQ(m.vertices.size(), 5u);
  EXPECT_EQ(m.vertices[0], Vec3(0, 0, 0.1));  // z is double: exact
  EXPECT_EQ(m.vertices[4], Vec3(2.5, -10, 3));
  ASSERT_EQ(m.vertex_colors.size(), 5u);
  EXPECT_EQ(m.vertex_colors[0], Color(255, 0, 128));  // 0.5 * 255 = 127.5 rounds to 128
  EXPECT_EQ(m.vertex_colors[3], Color(51, 51, 51));
  ASSERT_EQ(m.attributes.size(), 1u);
  EXPECT_EQ(m.attributes[0].name, "label");
  EXPECT_EQ(m.attributes[0].type, ScalarType::kUInt16);
  EXPECT_EQ(m.attributes[0].values, (std::vector<double>{7, 65535, 3, 4, 0}));
  ASSERT_EQ(m.faces.size(), 3u);
  EXPECT_EQ(m.faces[0], Vec3i(0, 1, 2));
  EXPECT_EQ(m.faces[1], Vec3i(0, 2, 3));
  EXPECT_EQ(m.faces[2], Vec3i(0, 3, 4));
  const PlyHeader h = ReadPlyHeader(p);
  EXPECT_EQ(h.format, PlyFormat::kAscii);
  ASSERT_EQ(h.comments.size(), 2u);
  EXPECT_EQ(h.comments[0], "made by hand");
  EXPECT_EQ(h.elements[2].name, "edge");
  EXPECT_EQ(h.elements[0].properties[7], "list uchar int extra");
}

TEST_F(IoTest, HandWrittenBigEndianBinaryPly) {
  std::string b =
      "ply\n"
      "format binary_big_endian 1.0\n"
      "comment big endian by hand\n"
      "element vertex 4\n"
      "property float x\n"
      "property float y\n"
      "property float z\n"
      "property list ushort short junk\n"
      "property uchar red\n"
      "property uchar green\n"
      "property uchar blue\n"
      "property uchar alpha\n"
      "property ushort label\n"
      "property double quality\n"
      "element face 1\n"
      "property list uchar int vertex_indices\n"
      "property uchar flags\n"
      "element edge 2\n"
      "property int vertex1\n"
      "property int vertex2\n"
      "end_header\n";
  const float xyz[4][3] = {{1.5f, -2.0f, 0.25f}, {3, 4, 5}, {-1, -1, -1}, {0, 0, 1e-3f}};
  for (int i = 0; i < 4; ++i) {
    for (float f : xyz[i]) PutBE(&b, f);
    PutBE<std::uint16_t>(&b, static_cast<std::uint16_t>(i));  // junk list of i shorts
    for (int k = 0; k < i; ++k) PutBE<std::int16_t>(&b, -1);
    b += static_cast<char>(10 * i);
    b += static_cast<char>(200);
    b += static_cast<char>(255 - i);
    b += static_cast<char>(99);  // alpha -> attribute
    PutBE<std::uint16_t>(&b, static_cast<std::uint16_t>(40000 + i));
    PutBE<double>(&b, 0.1 * i);
  }
  b += static_cast<char>(4);
  for (int idx : {3, 2, 1, 0}) PutBE<std::int32_t>(&b, idx);
  b += static_cast<char>(1);
  for (int k = 0; k < 4; ++k) PutBE<std::int32_t>(&b, 1000 + k);  // edges: never indices
  const std::string p = Write("be.ply", b);
  const TriangleMesh m = ReadPlyMesh(p);
  ASSERT_EQ(m.vertices.size(), 4u);
  EXPECT_EQ(m.vertices[0], Vec3(1.5, -2, 0.25));
  EXPECT_EQ(m.vertices[3].z(), static_cast<double>(1e-3f));
  EXPECT_EQ(m.vertex_colors[2], Color(20, 200, 253));
  ASSERT_EQ(m.attributes.size(), 3u);
  EXPECT_EQ(m.attributes[0].name, "alpha");
  EXPECT_EQ(m.attributes[0].values[3], 99);
  EXPECT_EQ(m.attributes[1].name, "label");
  EXPECT_EQ(m.attributes[1].type, ScalarType::kUInt16);
  EXPECT_EQ(m.attributes[1].values, (std::vector<double>{40000, 40001, 40002, 40003}));
  EXPECT_EQ(m.attributes[2].type, ScalarType::kFloat64);
  EXPECT_EQ(m.attributes[2].values[3], 0.1 * 3);
  ASSERT_EQ(m.faces.size(), 2u);
  EXPECT_EQ(m.faces[0], Vec3i(3, 2, 1));
  EXPECT_EQ(m.faces[1], Vec3i(3, 1, 0));
  // The same bytes parsed from memory, as a cloud.
  const PointCloud c =
      ParsePlyCloud(reinterpret_cast<const std::uint8_t*>(b.data()), b.size(), "mem");
  EXPECT_EQ(c.points[1], Vec3(3, 4, 5));
}

TEST_F(IoTest, LittleEndianWideListTypes) {
  std::string b =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\n"
      "property double y\nproperty double z\nelement face 1\n"
      "property list uint ushort vertex_indices\nend_header\n";
  for (double v : {0.1, 0.2, 0.3, 1.0, 2.0, 3.0, -0.5, 1e-300, 7.0}) PutLE(&b, v);
  PutLE<std::uint32_t>(&b, 3);
  for (std::uint16_t i : {2, 0, 1}) PutLE(&b, i);
  const std::string p = Write("le.ply", b);
  const TriangleMesh m = ReadPlyMesh(p);
  EXPECT_EQ(m.vertices[0], Vec3(0.1, 0.2, 0.3));
  EXPECT_EQ(m.vertices[2].y(), 1e-300);
  ASSERT_EQ(m.faces.size(), 1u);
  EXPECT_EQ(m.faces[0], Vec3i(2, 0, 1));
}

// ---------------------------------------------------------------------------
// OBJ.
// ---------------------------------------------------------------------------
TEST_F(IoTest, ObjIndexFormsNegativeIndicesAndIgnoredStatements) {
  const std::string p = Write("forms.obj",
                              "# comment\n"
                              "mtllib scene.mtl\n"
                              "o thing\n"
                              "v 0 0 0 1 0 0\n"
                              "v 1 0 0   # trailing comment\n"
                              "v 1 1 0 0.5 0.5 0.5\n"
                              "v 0 1 0\r\n"
                              "vt 0 0\nvt 1 0\nvt 1 1\n"
                              "vn 0 0 1\n"
                              "g group\n"
                              "usemtl red\n"
                              "s off\n"
                              "f 1 2 3\n"
                              "f 1/1 3/3 4/2\n"
                              "f 1//1 2//1 4//1\n"
                              "f 2/2/1 3/3/1 4/3/1\n"
                              "f -4 -3 -2 -1\n"
                              "l 1 2\n"
                              "v 5 5 5\n"
                              "f -1 1 2\n");
  const TriangleMesh m = ReadObj(p);
  ASSERT_EQ(m.vertices.size(), 5u);
  EXPECT_EQ(m.vertices[2], Vec3(1, 1, 0));
  EXPECT_EQ(m.vertices[4], Vec3(5, 5, 5));
  EXPECT_TRUE(m.vertex_colors.empty());
  const std::vector<Vec3i> want = {Vec3i(0, 1, 2), Vec3i(0, 2, 3), Vec3i(0, 1, 3), Vec3i(1, 2, 3),
                                   Vec3i(0, 1, 2), Vec3i(0, 2, 3), Vec3i(4, 0, 1)};
  ASSERT_EQ(m.faces.size(), want.size());
  for (std::size_t f = 0; f < want.size(); ++f) EXPECT_EQ(m.faces[f], want[f]) << "face " << f;
}

TEST_F(IoTest, ObjWriterPrecisionAndRoundTrip) {
  TriangleMesh m;
  m.vertices = {Vec3(0.123456789012, -2, 1e-9), Vec3(1, 2, 3), Vec3(-0.5, 0.25, 100)};
  m.faces = {Vec3i(0, 1, 2), Vec3i(2, 1, 0)};
  const std::string p = Path("out.obj");
  WriteObj(p, m);
  const std::string text = Slurp(p);
  EXPECT_NE(text.find("v 0.12345679 -2.00000000 0.00000000\n"), std::string::npos) << text;
  EXPECT_NE(text.find("f 3 2 1\n"), std::string::npos) << text;
  WriteObj(p, m, 3);
  EXPECT_NE(Slurp(p).find("v -0.500 0.250 100.000\n"), std::string::npos);
  const TriangleMesh r = ReadObj(p);
  ASSERT_EQ(r.vertices.size(), 3u);
  EXPECT_EQ(r.vertices[0], Vec3(0.123, -2, 0));
  EXPECT_EQ(r.faces, m.faces);
  EXPECT_THROW(WriteObj(p, m, -1), InvalidArgument);
}

TEST_F(IoTest, ReadWriteMeshDispatchByExtension) {
  TriangleMesh m;
  m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  m.faces = {Vec3i(0, 2, 1), Vec3i(0, 1, 3), Vec3i(0, 3, 2), Vec3i(1, 2, 3)};
  WriteMesh(Path("a.PLY"), m);
  WriteMesh(Path("a.obj"), m);
  EXPECT_EQ(ReadPlyHeader(Path("a.PLY")).format, PlyFormat::kBinaryLittleEndian);
  EXPECT_EQ(Slurp(Path("a.obj")).substr(0, 1), "#");
  for (const char* name : {"a.PLY", "a.obj"}) {
    const TriangleMesh r = ReadMesh(Path(name));
    EXPECT_EQ(r.faces, m.faces) << name;
    EXPECT_NEAR(r.SignedVolume(), 1.0 / 6.0, 1e-12) << name;
  }
  ExpectParseError([&] { ReadMesh(Path("a.stl")); }, {"a.stl", "unsupported mesh format '.stl'"});
  EXPECT_THROW(WriteMesh(Path("a.off"), m), InvalidArgument);
  ExpectParseError([&] { ReadMesh(Path("missing.ply")); }, {"missing.ply", "cannot open file"});
}

// ---------------------------------------------------------------------------
// Malformed PLY.
// ---------------------------------------------------------------------------
const char kAsciiHead[] =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";

struct BadCase {
  const char* name;
  std::string bytes;
  const char* problem;
};

std::string BinHead(const char* fmt, const std::string& elements) {
  return std::string("ply\nformat ") + fmt + " 1.0\n" + elements + "end_header\n";
}

std::vector<BadCase> BadPlyCases() {
  std::vector<BadCase> c;
  c.push_back({"empty", "", "empty file"});
  c.push_back({"magic", "plx\nformat ascii 1.0\nend_header\n", "not a PLY file"});
  c.push_back({"garbage", std::string("\x7f\x45\x4c\x46\x02\x01\x01\x00\xff\xfe", 10) + "\n\x01",
               "not a PLY file"});
  c.push_back({"trunc_header", "ply\nformat ascii 1.0\nelement vertex 3\nproperty flo",
               "truncated header: no 'end_header' line"});
  c.push_back({"no_format", "ply\nelement vertex 0\nproperty float x\nend_header\n",
               "header has no 'format' line"});
  c.push_back({"bad_format", "ply\nformat binary_middle_endian 1.0\nend_header\n",
               "unknown format 'binary_middle_endian'"});
  c.push_back({"bad_keyword", "ply\nformat ascii 1.0\nelemnt vertex 3\nend_header\n",
               ":3: unknown header keyword 'elemnt'"});
  c.push_back({"unknown_type",
               "ply\nformat ascii 1.0\nelement vertex 1\nproperty float16 x\nend_header\n",
               ":4: unknown property type 'float16'"});
  c.push_back({"bad_count", "ply\nformat ascii 1.0\nelement vertex -3\nend_header\n",
               "element 'vertex': invalid count '-3'"});
  c.push_back({"prop_first", "ply\nformat ascii 1.0\nproperty float x\nend_header\n",
               "property before any element"});
  c.push_back({"dup_element",
               "ply\nformat ascii 1.0\nelement vertex 0\nelement vertex 0\nend_header\n",
               "duplicate element 'vertex'"});
  c.push_back({"dup_property",
               "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty int x\n"
               "end_header\n",
               "duplicate property 'x'"});
  c.push_back({"missing_y",
               "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float z\n"
               "end_header\n1 2\n",
               "vertex element has no property 'y'"});
  c.push_back({"float_count",
               "ply\nformat ascii 1.0\nelement face 0\nproperty list float int vertex_indices\n"
               "end_header\n",
               "count type float is not an integer type"});
  c.push_back({"float_index",
               "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
               "property float z\nelement face 0\nproperty list uchar float vertex_indices\n"
               "end_header\n",
               "non-integer index type float"});
  c.push_back({"no_index_list",
               "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
               "property float z\nelement face 1\nproperty uchar flags\nend_header\n3\n",
               "face element has no 'vertex_indices' list"});
  c.push_back({"ascii_token", std::string(kAsciiHead) + "0 0 0\n1 abc 0\n0 1 0\n3 0 1 2\n",
               ":11: vertex 1: property 'y': 'abc' is not a valid float value"});
  c.push_back({"ascii_trunc", std::string(kAsciiHead) + "0.0 0.0 0.0\n1.0 0.0 0.0\n0.0 1.0",
               "vertex 2: property 'z': unexpected end of file"});
  c.push_back({"ascii_trunc_face", std::string(kAsciiHead) + "0 0 0\n1 0 0\n0 1 0\n3   0   1",
               "face 0: property 'vertex_indices': unexpected end of file"});
  c.push_back({"ascii_nan", std::string(kAsciiHead) + "0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n",
               "vertex 1: non-finite coordinate (1, nan, 0)"});
  c.push_back({"ascii_inf", std::string(kAsciiHead) + "0 0 0\n1 0 -inf\n0 1 0\n3 0 1 2\n",
               "vertex 1: non-finite coordinate (1, 0, -inf)"});
  c.push_back({"ascii_float_range", std::string(kAsciiHead) + "0 0 0\n1 0 1e39\n0 1 0\n3 0 1 2\n",
               "vertex 1: property 'z': value '1e39' out of range for float"});
  c.push_back({"ascii_index", std::string(kAsciiHead) + "0 0 0\n1 0 0\n0 1 0\n3 0 5 2\n",
               "face 0: vertex index 5 out of range (3 vertices)"});
  c.push_back({"ascii_neg_index", std::string(kAsciiHead) + "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n",
               "face 0: vertex index -1 out of range (3 vertices)"});
  c.push_back({"ascii_two_indices", std::string(kAsciiHead) + "0 0 0\n1 0 0\n0 1 0\n2 0 1\n",
               "face 0: 2 vertex indices (a face needs at least 3)"});
  c.push_back({"ascii_count_overflow", std::string(kAsciiHead) + "0 0 0\n1 0 0\n0 1 0\n300 0 1 2\n",
               "face 0: property 'vertex_indices': value '300' out of range for uchar"});
  c.push_back({"ascii_label_range",
               "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
               "property float z\nproperty ushort label\nend_header\n0 0 0 70000\n",
               "vertex 0: property 'label': value '70000' out of range for ushort"});
  c.push_back({"face_first_index_beyond_int",
               "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar uint vertex_indices\n"
               "element vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\n"
               "end_header\n3 0 1 3000000000\n",
               "face 0: vertex index 3000000000 out of range (4000000000 vertices)"});
  c.push_back({"ascii_huge_count",
               "ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\n"
               "property float y\nproperty float z\nend_header\n0 0 0\n",
               "element 'vertex' claims 4000000000 records"});
  c.push_back({"bin_huge_count",
               BinHead("binary_little_endian",
                       "element vertex 1000000000\nproperty float x\nproperty float y\n"
                       "property float z\n") +
                   std::string(24, '\0'),
               "element 'vertex' claims 1000000000 records (at least 12 bytes each) but only 24 "
               "bytes remain"});
  c.push_back({"bin_huge_u64_count",
               BinHead("binary_little_endian",
                       "element vertex 18446744073709551615\nproperty float x\nproperty float y\n"
                       "property float z\n"),
               "claims 18446744073709551615 records"});
  c.push_back({"bin_count_too_big_for_u64",
               BinHead("binary_little_endian", "element vertex 18446744073709551616\n"),
               "invalid count '18446744073709551616'"});
  {
    // The minimal record size fits, but the list in vertex 0 eats the bytes of vertex 1.
    std::string b = BinHead("binary_little_endian",
                            "element vertex 2\nproperty float x\nproperty float y\n"
                            "property float z\nproperty list uchar float extra\n");
    for (int k = 0; k < 3; ++k) PutLE(&b, 1.0f);
    b += static_cast<char>(2);
    PutLE(&b, 0.0f);
    PutLE(&b, 0.0f);
    PutLE(&b, 2.0f);
    b += "\x01";
    c.push_back({"bin_trunc", b, "vertex 1: property 'y': unexpected end of file"});
  }
  {
    std::string b = BinHead("binary_big_endian",
                            "element vertex 3\nproperty float x\nproperty float y\n"
                            "property float z\nelement face 1\n"
                            "property list uint int vertex_indices\n");
    for (int k = 0; k < 9; ++k) PutBE(&b, 0.5f);
    PutBE<std::uint32_t>(&b, 0xffffffffu);
    for (int k = 0; k < 3; ++k) PutBE<std::int32_t>(&b, 0);  // room for a minimal face
    c.push_back({"bin_list_overflow", b,
                 "face 0: list of 4294967295 indices runs past the end of the file"});
  }
  {
    std::string b = BinHead("binary_big_endian",
                            "element vertex 1\nproperty float x\nproperty float y\n"
                            "property float z\nelement edge 5\nproperty list int int v\n");
    for (int k = 0; k < 3; ++k) PutBE(&b, 0.5f);
    PutBE<std::int32_t>(&b, 2000000000);
    for (int k = 0; k < 4; ++k) PutBE<std::int32_t>(&b, 0);
    c.push_back({"bin_skip_list_overflow", b,
                 "edge 0: property 'v': list of 2000000000 items runs past the end"});
  }
  {
    std::string b = BinHead("binary_little_endian",
                            "element vertex 1\nproperty float x\nproperty float y\n"
                            "property float z\nelement edge 1\nproperty list char int v\n");
    for (int k = 0; k < 3; ++k) PutLE(&b, 0.5f);
    b += static_cast<char>(-3);
    c.push_back({"bin_negative_count", b, "edge 0: property 'v': negative list count -3"});
  }
  {
    std::string b = BinHead("binary_little_endian",
                            "element vertex 2\nproperty double x\nproperty double y\n"
                            "property double z\n");
    for (int k = 0; k < 3; ++k) PutLE(&b, 1.0);
    PutLE(&b, 1.0);
    PutLE(&b, std::numeric_limits<double>::infinity());
    PutLE(&b, 1.0);
    c.push_back({"bin_inf", b, "vertex 1: non-finite coordinate (1, inf, 1)"});
  }
  {
    std::string b = BinHead("binary_little_endian",
                            "element vertex 3\nproperty float x\nproperty float y\n"
                            "property float z\nelement face 1\n"
                            "property list uchar uint vertex_indices\n");
    for (int k = 0; k < 9; ++k) PutLE(&b, 0.5f);
    b += static_cast<char>(3);
    for (std::uint32_t i : {0u, 1u, 4000000000u}) PutLE(&b, i);
    c.push_back({"bin_index", b, "face 0: vertex index 4000000000 out of range (3 vertices)"});
  }
  return c;
}

TEST_F(IoTest, MalformedPlyThrowsParseErrorNamingFileAndProblem) {
  for (const BadCase& bc : BadPlyCases()) {
    SCOPED_TRACE(bc.name);
    const std::string name = std::string("bad_") + bc.name + ".ply";
    const std::string p = Write(name, bc.bytes);
    ExpectParseError([&] { ReadPlyMesh(p); }, {name, bc.problem});
    // The same problem from memory, with the given source name.
    ExpectParseError(
        [&] {
          ParsePlyMesh(reinterpret_cast<const std::uint8_t*>(bc.bytes.data()), bc.bytes.size(),
                       "scene.ply");
        },
        {"scene.ply", bc.problem});
  }
}

TEST_F(IoTest, PlyCloudIgnoresFacesButNotVertexErrors) {
  // Out-of-range face indices do not matter to a cloud reader...
  const std::string ok = std::string(kAsciiHead) + "0 0 0\n1 0 0\n0 1 0\n3 0 9 2\n";
  const PointCloud c =
      ParsePlyCloud(reinterpret_cast<const std::uint8_t*>(ok.data()), ok.size(), "cloud.ply");
  EXPECT_EQ(c.size(), 3u);
  ExpectParseError([&] { ReadPlyMesh(Write("c.ply", ok)); }, {"c.ply", "vertex index 9"});
  // ... but a non-finite vertex does.
  const std::string bad = std::string(kAsciiHead) + "0 0 0\n1 0 0\n0 inf 0\n3 0 1 2\n";
  ExpectParseError([&] { ReadPlyCloud(Write("c2.ply", bad)); },
                   {"c2.ply:12: vertex 2: non-finite coordinate"});
}

// ---------------------------------------------------------------------------
// Malformed OBJ.
// ---------------------------------------------------------------------------
TEST_F(IoTest, MalformedObjThrowsParseErrorNamingFileLineAndProblem) {
  const std::string quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
  const std::vector<BadCase> cases = {
      {"empty", "", "mesh.obj: empty file"},
      {"index", quad + "f 1 2 3\nf 1 2 9\n", "mesh.obj:6: face index 9 out of range (4 vertices)"},
      {"zero", quad + "f 0 1 2\n", "mesh.obj:5: face index 0 out of range (4 vertices)"},
      {"neg", quad + "f -5 1 2\n", "mesh.obj:5: face index -5 out of range (4 vertices)"},
      {"huge", quad + "f 1 2 99999999999999999999\n",
       "mesh.obj:5: invalid face index '99999999999999999999'"},
      {"before", "f 1 2 3\n" + quad, "mesh.obj:1: face index 1 out of range (0 vertices)"},
      {"token", "v 1 x 2\n", "mesh.obj:1: 'x' is not a number"},
      {"nan", quad + "v 0 nan 1\n", "mesh.obj:5: vertex 5: non-finite coordinate (0, nan, 1)"},
      {"inf", "v inf 0 1\n", "mesh.obj:1: vertex 1: non-finite coordinate (inf, 0, 1)"},
      {"range", "v 1e999 0 1\n", "mesh.obj:1: number '1e999' out of range"},
      {"short_v", "v 1 2\n", "mesh.obj:1: vertex needs 3 coordinates, got 2"},
      {"short_f", quad + "f 1 2\n", "mesh.obj:5: face with 2 vertices (a face needs at least 3)"},
      {"normal", quad + "vn 0 0 1\nf 1//1 2//2 3//1\n",
       "mesh.obj:6: normal index 2 out of range (1 normals)"},
      {"texcoord", quad + "f 1/x 2 3\n", "mesh.obj:5: invalid texture coordinate index 'x'"},
      {"slashes", quad + "f 1// 2 3\n", "mesh.obj:5: invalid face vertex '1//'"},
      {"garbage", std::string("\x89PNG\r\n\x1a\n\x01\x02\x03", 11),
       "mesh.obj:1: unknown statement '\\x89PNG'"},
      {"nul", std::string("v 0 0 0\nv 1") + '\0' + " 0 0\n", "mesh.obj:2: binary data (NUL byte)"},
  };
  for (const BadCase& bc : cases) {
    SCOPED_TRACE(bc.name);
    const std::string p = Write("mesh.obj", bc.bytes);
    ExpectParseError([&] { ReadObj(p); }, {p, bc.problem});
    ExpectParseError([&] { ReadMesh(p); }, {bc.problem});
  }
}

#ifdef DIMR_CLI
// `dimr mesh info` / `dimr mesh convert` end to end.
TEST_F(IoTest, MeshCliInfoAndConvert) {
  TriangleMesh cube;
  for (int i = 0; i < 8; ++i)
    cube.vertices.emplace_back(2 * (i & 1), 2 * ((i >> 1) & 1), 2 * ((i >> 2) & 1));
  const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                        {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  for (auto& t : f) cube.faces.emplace_back(t[0], t[1], t[2]);
  cube.SetAttribute("label", ScalarType::kUInt16, {1, 2, 3, 4, 5, 6, 7, 40});
  PlyWriteOptions ascii;
  ascii.format = PlyFormat::kAscii;
  WritePly(Path("cube.ply"), cube, ascii);
  const std::string cli = DIMR_CLI;
  ASSERT_EQ(
      std::system((cli + " mesh info " + Path("cube.ply") + " > " + Path("info.txt")).c_str()), 0);
  const std::string info = Slurp(Path("info.txt"));
  for (const char* want :
       {"format:         ply ascii", "vertices:       8", "faces:          12",
        "attribute:      label (ushort), range [1, 40]", "surface area:   24", "signed volume:  8",
        "bounds:         min (0, 0, 0) max (2, 2, 2)", "finite:         yes"}) {
    EXPECT_NE(info.find(want), std::string::npos) << "missing '" << want << "' in\n" << info;
  }
  ASSERT_EQ(std::system((cli + " mesh convert " + Path("cube.ply") + " " + Path("be.ply") +
                         " --binary-be > /dev/null")
                            .c_str()),
            0);
  EXPECT_EQ(ReadPlyHeader(Path("be.ply")).format, PlyFormat::kBinaryBigEndian);
  const TriangleMesh be = ReadPlyMesh(Path("be.ply"));
  EXPECT_EQ(be.faces, cube.faces);
  EXPECT_EQ(be.FindAttribute("label")->values, cube.FindAttribute("label")->values);
  ASSERT_EQ(std::system((cli + " mesh convert " + Path("be.ply") + " " + Path("c.obj") +
                         " --precision 3 > /dev/null")
                            .c_str()),
            0);
  EXPECT_NE(Slurp(Path("c.obj")).find("v 2.000 2.000 2.000\n"), std::string::npos);
  // Errors: nonzero exit, message naming the file and the problem.
  Write("bad.ply", std::string(kAsciiHead) + "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
  EXPECT_NE(
      std::system(
          (cli + " mesh info " + Path("bad.ply") + " > /dev/null 2> " + Path("err.txt")).c_str()),
      0);
  const std::string err = Slurp(Path("err.txt"));
  EXPECT_NE(err.find("bad.ply:13: face 0: vertex index 7 out of range (3 vertices)"),
            std::string::npos)
      << err;
  EXPECT_NE(std::system((cli + " mesh convert " + Path("cube.ply") + " " + Path("x.obj") +
                         " --ascii > /dev/null 2>&1")
                            .c_str()),
            0);
}
#endif

}  // namespace
}  // namespace dimr::geometry
