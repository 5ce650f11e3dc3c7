// ShapeNet tree writer / reader: layout, axis convention, normalisation, exact round trip,
// error reporting.
#include "dimr/data/shapenet_io.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "dimr/data/cad_library.h"
#include "dimr/data/labels.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/obj_io.h"

namespace dimr::data {
namespace {

namespace fs = std::filesystem;
using geometry::Vec3;

class ShapeNetIo : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = (fs::temp_directory_path() /
            ("dimr_shapenet_" +
             std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
             std::to_string(::getpid())))
               .string();
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string dir_;
};

TEST_F(ShapeNetIo, AxisConventionAndNormalisation) {
  // Canonical forward (+x) becomes ShapeNet -z, left (+y) becomes -x, up (+z) becomes +y.
  const Eigen::Matrix3d A = CanonicalToShapeNetAxes();
  EXPECT_TRUE((A * Vec3::UnitX()).isApprox(Vec3(0, 0, -1)));
  EXPECT_TRUE((A * Vec3::UnitY()).isApprox(Vec3(-1, 0, 0)));
  EXPECT_TRUE((A * Vec3::UnitZ()).isApprox(Vec3(0, 1, 0)));
  const Vec3 s(0.5, 1.2, 0.9);  // a 0.5 deep, 1.2 wide, 0.9 tall model
  const Eigen::Matrix3d M = CanonicalToShapeNet(s);
  // The unit box corner (0.5, 0.5, 0.5) maps to half the proportional size.
  const Vec3 q = M * Vec3(0.5, 0.5, 0.5);
  EXPECT_NEAR(q.x(), -0.6 / s.norm(), 1e-15);
  EXPECT_NEAR(q.y(), 0.45 / s.norm(), 1e-15);
  EXPECT_NEAR(q.z(), -0.25 / s.norm(), 1e-15);
  EXPECT_NEAR((2 * q).norm(), 1.0, 1e-15);  // bbox diagonal 1
  EXPECT_THROW(CanonicalToShapeNet(Vec3(0, 1, 1)), InvalidArgument);
}

TEST_F(ShapeNetIo, WritesLayoutAndShapeNetFrame) {
  const CadModel chair = GenerateCadModel(kCadChair, 17);
  WriteShapeNetTree(dir_, {chair});
  const std::string obj = dir_ + "/03001627/" + chair.model_id + "/models/model_normalized.obj";
  ASSERT_TRUE(fs::exists(obj));
  ASSERT_TRUE(fs::exists(dir_ + "/index.json"));
  const geometry::TriangleMesh m = geometry::ReadObj(obj);
  ASSERT_EQ(m.faces.size(), chair.mesh.faces.size());
  const geometry::AABB box = m.Bounds();
  // Centred, diagonal 1, y up: the chair's height ends up on y, its width on x, depth on z.
  EXPECT_NEAR(box.Center().norm(), 0.0, 1e-8);
  EXPECT_NEAR(box.Extent().norm(), 1.0, 1e-7);
  const Vec3 s = chair.nominal_size;
  EXPECT_NEAR(box.Extent().x() / box.Extent().y(), s.y() / s.z(), 1e-6);
  EXPECT_NEAR(box.Extent().z() / box.Extent().y(), s.x() / s.z(), 1e-6);
  // The backrest (canonical -x) lies at ShapeNet +z: the back part's centroid z > 0.
  int back = -1;
  for (int p = 0; p < chair.NumParts(); ++p) {
    if (chair.part_names[p] == "back") back = p;
  }
  ASSERT_GE(back, 0);
  double zsum = 0;
  int n = 0;
  for (int f = chair.PartBegin(back); f < chair.PartEnd(back); ++f) {
    for (int k = 0; k < 3; ++k) zsum += m.vertices[m.faces[f][k]].z(), ++n;
  }
  EXPECT_GT(zsum / n, 0.05);
  // Orientation is preserved by the (determinant +1) transform: volume stays positive.
  EXPECT_GT(m.SignedVolume(), 0.0);
}

TEST_F(ShapeNetIo, RoundTripIsExactToObjPrecision) {
  std::vector<CadModel> models;
  for (int c = 0; c < kNumCadClasses; ++c) {
    for (std::uint64_t s = 0; s < 4; ++s) models.push_back(GenerateCadModel(c, 1000 + s));
  }
  WriteShapeNetTree(dir_, models);
  const std::vector<CadModel> back = ReadShapeNetTree(dir_);
  ASSERT_EQ(back.size(), models.size());
  for (std::size_t i = 0; i < models.size(); ++i) {
    const CadModel& a = models[i];
    const CadModel& b = back[i];
    SCOPED_TRACE(a.family);
    EXPECT_EQ(b.model_id, a.model_id);
    EXPECT_EQ(b.synset, a.synset);
    EXPECT_EQ(b.cad_class, a.cad_class);
    EXPECT_EQ(b.rfs_class, a.rfs_class);
    EXPECT_EQ(b.family, a.family);
    EXPECT_EQ(b.seed, a.seed);
    EXPECT_EQ(b.symmetric_about_z, a.symmetric_about_z);
    EXPECT_EQ(b.part_face_begin, a.part_face_begin);
    EXPECT_EQ(b.part_names, a.part_names);
    EXPECT_TRUE(b.nominal_size == a.nominal_size);  // JSON doubles round-trip exactly
    ASSERT_EQ(b.mesh.faces, a.mesh.faces);
    ASSERT_EQ(b.mesh.vertices.size(), a.mesh.vertices.size());
    double err = 0;
    for (std::size_t v = 0; v < a.mesh.vertices.size(); ++v) {
      err = std::max(err, (b.mesh.vertices[v] - a.mesh.vertices[v]).cwiseAbs().maxCoeff());
    }
    // 8 decimals in a file whose coordinates are below 0.5 / |s| relative: < 1e-7 back in
    // the unit box for models at least 0.1 of their diagonal along each axis.
    EXPECT_LT(err, 2e-7);
    const geometry::AABB box = b.mesh.Bounds();
    EXPECT_EQ(box.min, Vec3::Constant(-0.5));
    EXPECT_EQ(box.max, Vec3::Constant(0.5));
  }
}

TEST_F(ShapeNetIo, FullPrecisionRoundTrip) {
  const CadModel m = GenerateCadModel(kCadSofa, 5);
  WriteShapeNetTree(dir_, {m}, 17);
  const CadModel b = ReadShapeNetTree(dir_).at(0);
  double err = 0;
  for (std::size_t v = 0; v < m.mesh.vertices.size(); ++v) {
    err = std::max(err, (b.mesh.vertices[v] - m.mesh.vertices[v]).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(err, 1e-14);
}

TEST_F(ShapeNetIo, IndexMergesAndReplaces) {
  WriteShapeNetTree(dir_, {GenerateCadModel(kCadTable, 1), GenerateCadModel(kCadTable, 2)});
  WriteShapeNetTree(dir_, {GenerateCadModel(kCadTable, 2), GenerateCadModel(kCadBathtub, 3)});
  const auto all = ReadShapeNetTree(dir_);
  ASSERT_EQ(all.size(), 3u);
  EXPECT_EQ(all[0].model_id, GenerateCadModel(kCadTable, 1).model_id);
  EXPECT_EQ(all[1].model_id, GenerateCadModel(kCadTable, 2).model_id);
  EXPECT_EQ(all[2].cad_class, kCadBathtub);
}

TEST_F(ShapeNetIo, DeterministicBytes) {
  const std::vector<CadModel> models = {GenerateCadModel(kCadCabinet, 9),
                                        GenerateCadModel(kCadDisplay, 9)};
  WriteShapeNetTree(dir_ + "/a", models);
  WriteShapeNetTree(dir_ + "/b", models);
  auto bytes = [](const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  for (const auto& m : models) {
    const std::string rel = "/" + ShapeNetRelativePath(m.synset, m.model_id);
    EXPECT_EQ(bytes(dir_ + "/a" + rel), bytes(dir_ + "/b" + rel));
    EXPECT_GT(bytes(dir_ + "/a" + rel).size(), 1000u);
  }
  EXPECT_EQ(bytes(dir_ + "/a/index.json"), bytes(dir_ + "/b/index.json"));
}

TEST_F(ShapeNetIo, ReadsPlainShapeNetTreeWithoutIndex) {
  // A hand-written ShapeNet-frame box: 2 wide (x_sn), 1 tall (y_sn), 0.5 deep (z_sn), centred
  // off the origin; read back it is a unit box with proportions (depth .5, width 2, height 1).
  const std::string d = dir_ + "/02933112/0123456789abcdef0123456789abcdef/models";
  fs::create_directories(d);
  std::ofstream(d + "/model_normalized.obj")
      << "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 0 1 0\nv 0 0 0.5\nv 2 0 0.5\nv 2 1 0.5\nv 0 1 0.5\n"
         "f 1 4 3\nf 1 3 2\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\n"
         "f 3 8 7\nf 4 1 5\nf 4 5 8\n";
  const auto models = ReadShapeNetTree(dir_);
  ASSERT_EQ(models.size(), 1u);
  const CadModel& m = models[0];
  EXPECT_EQ(m.cad_class, kCadCabinet);
  EXPECT_EQ(m.model_id, "0123456789abcdef0123456789abcdef");
  EXPECT_TRUE(m.nominal_size.isApprox(Vec3(0.5, 2.0, 1.0)));
  // ShapeNet vertex (2, 1, 0.5) -> canonical (-z, -x, y) = (-0.5, -2, 1) -> unit box corner
  // (-0.5, -0.5, 0.5).
  EXPECT_TRUE(m.mesh.vertices[6].isApprox(Vec3(-0.5, -0.5, 0.5)));
  EXPECT_TRUE(m.mesh.vertices[0].isApprox(Vec3(0.5, 0.5, -0.5)));
  EXPECT_GT(m.mesh.SignedVolume(), 0.0);
}

TEST_F(ShapeNetIo, ErrorsNameThePath) {
  try {
    ReadShapeNetTree(dir_ + "/missing");
    FAIL() << "no throw";
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("missing"), std::string::npos);
  }
  fs::create_directories(dir_);
  std::ofstream(dir_ + "/index.json") << "{\"models\": [ {\"model_id\": 3} ]";
  try {
    ReadShapeNetTree(dir_);
    FAIL() << "no throw";
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("index.json"), std::string::npos) << e.what();
  }
  std::ofstream(dir_ + "/index.json") << "{\"models\": [ {\"model_id\": 3} ]}";
  EXPECT_THROW(ReadShapeNetTree(dir_), ParseError);
  // Writing into a malformed index is refused, not silently overwritten.
  EXPECT_THROW(WriteShapeNetTree(dir_, {GenerateCadModel(0, 0)}), ParseError);
  // Unwritable output: a path below a regular file.
  std::ofstream(dir_ + "/file") << "x";
  try {
    WriteShapeNetTree(dir_ + "/file/sub", {GenerateCadModel(0, 0)});
    FAIL() << "no throw";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("file/sub"), std::string::npos) << e.what();
  }
  // Non-CAD models have no synset.
  EXPECT_THROW(WriteShapeNetTree(dir_ + "/x", {GenerateDistractor(0, 0)}), InvalidArgument);
  // A truncated OBJ referenced by a valid index.
  fs::remove_all(dir_);
  const CadModel m = GenerateCadModel(kCadTable, 4);
  WriteShapeNetTree(dir_, {m});
  const std::string obj = dir_ + "/" + ShapeNetRelativePath(m.synset, m.model_id);
  std::ofstream(obj, std::ios::trunc) << "v 0 0 0\nf 1 2 3\n";
  try {
    ReadShapeNetTree(dir_);
    FAIL() << "no throw";
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find(m.model_id), std::string::npos) << e.what();
  }
}

#ifdef DIMR_CLI
// Runs a shell command, returns (exit status, stdout + stderr).
std::pair<int, std::string> RunShell(const std::string& cmd) {
  std::string out;
  FILE* p = ::popen((cmd + " 2>&1").c_str(), "r");
  if (p == nullptr) return {-1, out};
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof(buf), p)) > 0) out.append(buf, n);
  const int status = ::pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

std::uint32_t Crc(const std::string& data) {
  std::uint32_t c = 0xffffffffu;
  for (unsigned char b : data) {
    c ^= b;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
  }
  return ~c;
}

std::uint32_t Be32(const std::string& s, std::size_t at) {
  return (static_cast<std::uint32_t>(static_cast<unsigned char>(s[at])) << 24) |
         (static_cast<std::uint32_t>(static_cast<unsigned char>(s[at + 1])) << 16) |
         (static_cast<std::uint32_t>(static_cast<unsigned char>(s[at + 2])) << 8) |
         static_cast<std::uint32_t>(static_cast<unsigned char>(s[at + 3]));
}

TEST_F(ShapeNetIo, CliGenerateStatsRender) {
  if (!fs::exists(DIMR_CLI)) GTEST_SKIP() << "dimr CLI not built";
  const std::string cli = DIMR_CLI;
  auto [rc, out] = RunShell(cli + " cad generate --class chair --count 3 --seed 5 --out " + dir_);
  ASSERT_EQ(rc, 0) << out;
  const auto models = ReadShapeNetTree(dir_);
  ASSERT_EQ(models.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(models[i].model_id, GenerateCadModel(kCadChair, 5 + i).model_id);
    EXPECT_EQ(models[i].family, GenerateCadModel(kCadChair, 5 + i).family);
  }
  std::tie(rc, out) = RunShell(cli + " cad stats --dir " + dir_);
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("chair"), std::string::npos) << out;
  EXPECT_NE(out.find("total: 3 models"), std::string::npos) << out;
  std::tie(rc, out) = RunShell(cli + " cad generate --class sofa_bed --count 1 --out " + dir_);
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("sofa_bed"), std::string::npos) << out;
  // Render: a valid PNG (signature, IHDR size, chunk CRCs, IEND).
  const std::string png = dir_ + "/sheet.png";
  std::tie(rc, out) =
      RunShell(cli + " cad render --class table --per-class 3 --tile 64 --out " + png);
  ASSERT_EQ(rc, 0) << out;
  std::ifstream in(png, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  ASSERT_GT(bytes.size(), 100u);
  EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_EQ(bytes.substr(12, 4), "IHDR");
  EXPECT_EQ(Be32(bytes, 16), 3u * 64u);   // width: 3 tiles
  EXPECT_EQ(Be32(bytes, 20), 64u + 24u);  // height: one row + label strip
  std::size_t at = 8;
  std::string last;
  while (at + 12 <= bytes.size()) {
    const std::uint32_t len = Be32(bytes, at);
    ASSERT_LE(at + 12 + len, bytes.size());
    const std::string body = bytes.substr(at + 4, 4 + len);
    EXPECT_EQ(Crc(body), Be32(bytes, at + 8 + len)) << body.substr(0, 4);
    last = body.substr(0, 4);
    at += 12 + len;
  }
  EXPECT_EQ(last, "IEND");
  EXPECT_EQ(at, bytes.size());
}
#endif  // DIMR_CLI

}  // namespace
}  // namespace dimr::data
