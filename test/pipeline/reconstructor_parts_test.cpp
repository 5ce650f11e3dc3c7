// Parts of the Reconstructor that do not need the networks: placement, the pool's mesh paths,
// the configuration.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "dimr/geometry/error.h"
#include "dimr/geometry/obj_io.h"
#include "dimr/geometry/oriented_box.h"
#include "dimr/geometry/ply_io.h"
#include "dimr/pipeline/cloud_io.h"
#include "dimr/pipeline/placement.h"
#include "dimr/pipeline/reconstructor_config.h"
#include "dimr/pipeline/shape_pool.h"

namespace dimr::pipeline {
namespace {

namespace fs = std::filesystem;

fs::path TempDir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("dimr_recon_parts_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

TEST(Placement, CanonicalCubeCornersLandOnTheBoxCorners) {
  geometry::OrientedBox unit{geometry::Vec3::Zero(), geometry::Vec3(2, 2, 2), 0};
  const geometry::TriangleMesh cube = unit.ToMesh();  // [-1, 1]^3
  geometry::OrientedBox box{geometry::Vec3(3, -1, 0.4), geometry::Vec3(1.2, 0.6, 0.8), 0.7};
  const geometry::TriangleMesh placed = PlaceCanonicalMesh(cube, box);
  ASSERT_EQ(placed.vertices.size(), cube.vertices.size());
  const auto corners = box.Corners();
  for (const auto& v : placed.vertices) {
    double best = 1e9;
    for (const auto& c : corners) best = std::min(best, (v - c).norm());
    EXPECT_LT(best, 1e-12);
  }
  EXPECT_EQ(placed.faces, cube.faces);
  // v_world = Rz(theta)(v * size / 2) + centre for a single point, by hand.
  geometry::TriangleMesh one;
  one.vertices = {geometry::Vec3(1, 0, 0)};
  const auto p = PlaceCanonicalMesh(one, box).vertices[0];
  EXPECT_NEAR(p.x(), 3 + 0.6 * std::cos(0.7), 1e-12);
  EXPECT_NEAR(p.y(), -1 + 0.6 * std::sin(0.7), 1e-12);
  EXPECT_NEAR(p.z(), 0.4, 1e-12);
  box.size.x() = -1;
  EXPECT_THROW(PlaceCanonicalMesh(cube, box), InvalidArgument);
}

TEST(Placement, RetrievedMeshFillsTheBoxPerAxis) {
  // A CAD mesh of arbitrary scale and offset: after placement it spans exactly the box.
  geometry::OrientedBox src{geometry::Vec3(5, 5, 5), geometry::Vec3(0.3, 2.0, 0.7), 0};
  const geometry::TriangleMesh cad = src.ToMesh();
  const geometry::OrientedBox box{geometry::Vec3(1, 2, 0.5), geometry::Vec3(0.8, 0.5, 1.0), -1.2};
  const geometry::TriangleMesh placed = PlaceRetrievedMesh(cad, box);
  const Eigen::Matrix3d rt = box.Rotation().transpose();
  geometry::AABB local;
  for (const auto& v : placed.vertices) local.Extend(rt * (v - box.center));
  EXPECT_TRUE(local.min.isApprox(-0.5 * box.size, 1e-12));
  EXPECT_TRUE(local.max.isApprox(0.5 * box.size, 1e-12));
  EXPECT_THROW(PlaceRetrievedMesh(geometry::TriangleMesh(), box), InvalidArgument);
}

TEST(Placement, ShapeNetAxesAreRemappedToCanonical) {
  const fs::path d = TempDir("obj");
  geometry::TriangleMesh m;
  m.vertices = {geometry::Vec3(1, 2, 3), geometry::Vec3(0, 0, 0), geometry::Vec3(0, 1, 0)};
  m.faces = {geometry::Vec3i(0, 1, 2)};
  geometry::WriteObj((d / "m.obj").string(), m);
  const geometry::TriangleMesh c = ReadShapeNetMeshCanonical((d / "m.obj").string());
  // (x, y, z) -> (-z, -x, y): ShapeNet's -z forward becomes +x, -x becomes left, y up.
  EXPECT_TRUE(c.vertices[0].isApprox(geometry::Vec3(-3, -1, 2)));
  EXPECT_TRUE(c.vertices[2].isApprox(geometry::Vec3(0, 0, 1)));
  EXPECT_THROW(ReadShapeNetMeshCanonical((d / "missing.obj").string()), ParseError);
}

ShapePool SmallPool() {
  ShapePool pool(4);
  std::mt19937 rng(3);
  std::normal_distribution<float> g;
  for (int i = 0; i < 6; ++i) {
    Eigen::VectorXf code(8);
    for (int k = 0; k < 8; ++k) code[k] = g(rng);
    PoolEntry e;
    e.model_id = "model" + std::to_string(i);
    e.cad_class = i % 2;
    e.code = code;
    pool.Add(e);
  }
  return pool;
}

TEST(PoolMeshes, MeshPathsRoundTripRelativeToThePoolFile) {
  const fs::path d = TempDir("pool");
  ShapePool pool = SmallPool();
  EXPECT_EQ(pool.NumWithMeshes(), 0);
  pool.SetMeshPath(1, "meshes/model1.obj");
  pool.SetMeshPath(4, "/abs/model4.obj");
  EXPECT_EQ(pool.NumWithMeshes(), 2);
  EXPECT_THROW(pool.SetMeshPath(6, "x"), InvalidArgument);
  pool.Save((d / "pool.bin").string());
  const ShapePool back = ShapePool::Load((d / "pool.bin").string());
  ASSERT_EQ(back.size(), pool.size());
  EXPECT_EQ(back.ContentHash(), pool.ContentHash());  // paths are not part of the hash
  EXPECT_EQ(back.entries()[1].mesh_path, (d / "meshes/model1.obj").string());
  EXPECT_EQ(back.entries()[4].mesh_path, "/abs/model4.obj");
  EXPECT_TRUE(back.entries()[0].mesh_path.empty());
  // A truncated version-2 file is refused, naming the file.
  std::ifstream in(d / "pool.bin", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  bytes.resize(bytes.size() - 5);
  std::ofstream((d / "cut.bin").string(), std::ios::binary) << bytes;
  try {
    ShapePool::Load((d / "cut.bin").string());
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("cut.bin"), std::string::npos);
  }
}

TEST(PoolMeshes, PoolsWithoutMeshesKeepTheOldFormat) {
  const fs::path d = TempDir("v1");
  const ShapePool pool = SmallPool();
  pool.Save((d / "a.bin").string());
  std::ifstream in(d / "a.bin", std::ios::binary);
  char head[12];
  in.read(head, 12);
  EXPECT_EQ(head[8], 1);  // version 1 bytes, as before mesh paths existed
  // The shipped pool (version 1) loads and has no mesh paths.
  const std::string shipped = std::string(DIMR_SOURCE_DIR) + "/models/bsp/pool.bin";
  if (fs::exists(shipped)) {
    const ShapePool p = ShapePool::Load(shipped);
    EXPECT_GT(p.size(), 100u);
    EXPECT_EQ(p.NumWithMeshes(), 0);
  }
}

TEST(PoolMeshes, AttachMeshTreeFindsModelsInAnySynsetFolder) {
  const fs::path d = TempDir("tree");
  ShapePool pool = SmallPool();
  for (const auto& [syn, id] :
       {std::pair<std::string, std::string>{"03001627", "model2"}, {"04379243", "model3"}}) {
    fs::create_directories(d / syn / id / "models");
    std::ofstream(d / syn / id / "models" / "model_normalized.obj") << "v 0 0 0\n";
  }
  EXPECT_EQ(pool.AttachMeshTree(d.string()), 2);
  EXPECT_EQ(pool.entries()[2].mesh_path,
            (d / "03001627" / "model2" / "models" / "model_normalized.obj").string());
  EXPECT_TRUE(pool.entries()[0].mesh_path.empty());
  EXPECT_THROW(pool.AttachMeshTree((d / "nope").string()), InvalidArgument);
}

TEST(CloudIo, ReadsAsciiAndBinaryPcdAndPly) {
  const fs::path d = TempDir("pcd");
  {
    std::ofstream f(d / "a.pcd");
    f << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\n"
         "COUNT 1 1 1 1\nWIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n"
         "1 2 3 16711680\n4 5 6 65280\n-1 0.5 2.25 255\n";
  }
  const geometry::PointCloud a = ReadPointCloudFile((d / "a.pcd").string());
  ASSERT_EQ(a.size(), 3u);
  EXPECT_EQ(a.points[2], geometry::Vec3(-1, 0.5, 2.25));
  ASSERT_TRUE(a.HasColors());
  EXPECT_EQ(a.colors[0], geometry::Color(255, 0, 0));
  EXPECT_EQ(a.colors[1], geometry::Color(0, 255, 0));
  {
    std::ofstream f(d / "b.pcd", std::ios::binary);
    f << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\n"
         "HEIGHT 1\nPOINTS 2\nDATA binary\n";
    const float v[6] = {0.5f, -2.f, 1.f, 3.f, 4.f, 5.f};
    f.write(reinterpret_cast<const char*>(v), sizeof(v));
  }
  const geometry::PointCloud b = ReadPointCloudFile((d / "b.pcd").string());
  ASSERT_EQ(b.size(), 2u);
  EXPECT_EQ(b.points[0], geometry::Vec3(0.5, -2, 1));
  EXPECT_FALSE(b.HasColors());
  {
    // binary_compressed: the field-major block (all x, all y, all z) as LZF literal runs.
    const float xyz[6] = {1.f, 4.f, 2.f, 5.f, 3.f, 6.f};  // x0 x1 y0 y1 z0 z1
    std::string lzf;
    lzf.push_back(static_cast<char>(sizeof(xyz) - 1));
    lzf.append(reinterpret_cast<const char*>(xyz), sizeof(xyz));
    std::ofstream f(d / "c.pcd", std::ios::binary);
    f << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\n"
         "HEIGHT 1\nPOINTS 2\nDATA binary_compressed\n";
    const std::uint32_t sizes[2] = {static_cast<std::uint32_t>(lzf.size()), sizeof(xyz)};
    f.write(reinterpret_cast<const char*>(sizes), sizeof(sizes));
    f << lzf;
  }
  const geometry::PointCloud cc = ReadPointCloudFile((d / "c.pcd").string());
  ASSERT_EQ(cc.size(), 2u);
  EXPECT_EQ(cc.points[0], geometry::Vec3(1, 2, 3));
  EXPECT_EQ(cc.points[1], geometry::Vec3(4, 5, 6));
  // A header claiming more points than the file holds is refused before allocating.
  {
    std::ofstream f(d / "huge.pcd", std::ios::binary);
    f << "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1000000000\nHEIGHT 1\n"
         "POINTS 1000000000\nDATA binary\n0123";
  }
  EXPECT_THROW(ReadPointCloudFile((d / "huge.pcd").string()), ParseError);
  geometry::PointCloud c;
  c.points = {geometry::Vec3(1, 1, 1), geometry::Vec3(2, 2, 2)};
  geometry::WritePly((d / "c.PLY").string(), c);
  EXPECT_EQ(ReadPointCloudFile((d / "c.PLY").string()).size(), 2u);
  std::ofstream(d / "bad.pcd") << "not a pcd\n";
  EXPECT_THROW(ReadPointCloudFile((d / "bad.pcd").string()), ParseError);
  EXPECT_THROW(ReadPointCloudFile((d / "missing.pcd").string()), ParseError);
  std::ofstream(d / "x.xyz") << "1 2 3\n";
  EXPECT_THROW(ReadPointCloudFile((d / "x.xyz").string()), ParseError);
}

TEST(CloudIo, OrganisedCloudsDropTheirPixelsWithoutAReturn) {
  // A 3 x 2 organised PCD (a depth camera's frame): NaN where the sensor saw nothing.
  const fs::path d = TempDir("pcd_nan");
  {
    std::ofstream f(d / "org.pcd");
    f << "VERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\nWIDTH 3\n"
         "HEIGHT 2\nPOINTS 6\nDATA ascii\n"
         "nan nan nan 0\n1 2 3 16711680\nnan nan nan 0\n4 5 6 65280\n7 nan 9 255\n"
         "0.5 0.5 0.5 255\n";
  }
  geometry::PointCloud c = ReadPointCloudFile((d / "org.pcd").string());
  ASSERT_EQ(c.size(), 6u);  // the reader keeps them: dropping is the caller's choice
  c.SetAttribute("label", geometry::ScalarType::kInt32, {0, 1, 2, 3, 4, 5});
  EXPECT_EQ(DropNonFinitePoints(&c), 3u);
  ASSERT_EQ(c.size(), 3u);
  EXPECT_EQ(c.points[0], geometry::Vec3(1, 2, 3));
  EXPECT_EQ(c.points[1], geometry::Vec3(4, 5, 6));
  EXPECT_EQ(c.points[2], geometry::Vec3(0.5, 0.5, 0.5));
  ASSERT_EQ(c.colors.size(), 3u);
  EXPECT_EQ(c.colors[0], geometry::Color(255, 0, 0));
  EXPECT_EQ(c.colors[1], geometry::Color(0, 255, 0));
  EXPECT_EQ(c.colors[2], geometry::Color(0, 0, 255));
  EXPECT_EQ(c.FindAttribute("label")->values, std::vector<double>({1, 3, 5}));
  EXPECT_EQ(DropNonFinitePoints(&c), 0u);  // nothing left to drop
  c.normals.resize(1);
  EXPECT_THROW(DropNonFinitePoints(&c), InvalidArgument);
}

TEST(ReconstructorConfig, ModesAndPresetsRoundTripByName) {
  for (auto m : {ReconstructionMode::kGeneration, ReconstructionMode::kProjection,
                 ReconstructionMode::kRetrieval}) {
    EXPECT_EQ(ParseReconstructionMode(ReconstructionModeName(m)), m);
  }
  for (auto p : {ReconstructionPreset::kFast, ReconstructionPreset::kAccurate}) {
    EXPECT_EQ(ParseReconstructionPreset(ReconstructionPresetName(p)), p);
  }
  EXPECT_THROW(ParseReconstructionMode("generate"), InvalidArgument);
  EXPECT_THROW(ParseReconstructionPreset("quick"), InvalidArgument);
  for (auto r : {ScoreRanking::kStage2, ScoreRanking::kCombined}) {
    EXPECT_EQ(ParseScoreRanking(ScoreRankingName(r)), r);
  }
  EXPECT_THROW(ParseScoreRanking("sqrt"), InvalidArgument);
}

void ExpectKey(const ReconstructorConfig& c, const std::string& key) {
  try {
    c.Validate();
    ADD_FAILURE() << "no error for " << key;
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
  }
}

TEST(ReconstructorConfig, ValidateNamesTheBadKey) {
  ReconstructorConfig ok;
  EXPECT_NO_THROW(ok.Validate());
  ReconstructorConfig c = ok;
  c.k = 0;
  ExpectKey(c, "k ");
  c = ok;
  c.score_threshold = 1.0;
  ExpectKey(c, "score_threshold");
  c = ok;
  c.nms_iou = -0.1;
  ExpectKey(c, "nms_iou");
  c = ok;
  c.samples = -1;
  ExpectKey(c, "samples");
  c = ok;
  c.icp.max_iterations = 0;
  ExpectKey(c, "icp.max_iterations");
  c = ok;
  c.crop = true;
  c.crop_min = geometry::Vec3(0, 0, 0);
  c.crop_max = geometry::Vec3(1, 0, 1);
  ExpectKey(c, "crop_min");
  c = ok;
  c.pool.clear();
  c.mode = ReconstructionMode::kRetrieval;
  ExpectKey(c, "pool");
  c = ok;
  c.decoded_mesh_scale = 0.5;
  ExpectKey(c, "decoded_mesh_scale");
  c.decoded_mesh_scale = std::nan("");
  ExpectKey(c, "decoded_mesh_scale");
  c = ok;
  c.icp.relative_rms_change = -1;
  ExpectKey(c, "icp.relative_rms_change");
  const std::string yaml = ok.ToYaml();
  for (const char* key :
       {"mode: generation", "preset: accurate", "score_threshold: 0.05", "max_correspondence: 0.04",
        "nms_iou: 0.3", "backend: own", "score: ", "decoded_mesh_scale: "}) {
    EXPECT_NE(yaml.find(key), std::string::npos) << key;
  }
}

}  // namespace
}  // namespace dimr::pipeline
