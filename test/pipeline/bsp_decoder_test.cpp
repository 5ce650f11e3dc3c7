#include "dimr/pipeline/bsp_decoder.h"

#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "dimr/core/error.h"
#include "dimr/pipeline/bsp_data.h"
#include "dimr/pipeline/shape_pool.h"

namespace dimr::pipeline {
namespace {

namespace fs = std::filesystem;

const std::string kModel = std::string(DIMR_SOURCE_DIR) + "/models/bsp/bsp.pt";
const std::string kPool = std::string(DIMR_SOURCE_DIR) + "/models/bsp/pool.bin";

const BspDecoder& Decoder() {
  static const BspDecoder decoder = BspDecoder::Load(kModel);
  return decoder;
}

// Inside the exact convex parts of a decoded mesh: some convex has the point behind (or within
// `margin` of) every one of its triangles' planes (outward normals).
bool InsideParts(const BspMeshResult& r, const Eigen::Vector3d& p, double margin) {
  std::map<int, bool> inside;
  for (std::size_t f = 0; f < r.mesh.faces.size(); ++f) {
    const auto& t = r.mesh.faces[f];
    const geometry::Vec3& a = r.mesh.vertices[t[0]];
    const geometry::Vec3 n =
        (r.mesh.vertices[t[1]] - a).cross(r.mesh.vertices[t[2]] - a).normalized();
    auto it = inside.emplace(r.face_convex[f], true).first;
    if (n.allFinite() && n.dot(p - a) > margin) it->second = false;
  }
  for (const auto& [k, in] : inside) {
    if (in) return true;
  }
  return false;
}

TEST(BspDecoder, LoadsTheCardsDecodingAndTheModelsSizes) {
  const BspDecoder& d = Decoder();
  EXPECT_EQ(d.latent_dim(), 128);
  EXPECT_EQ(d.num_classes(), 8);
  EXPECT_EQ(d.resolution(), 32);
  EXPECT_FLOAT_EQ(d.mesh_options().distance_dilation, 0.0145f);  // models/bsp/model.yaml
  EXPECT_FLOAT_EQ(d.mesh_options().dilation, 0.0f);
  EXPECT_EQ(d.convex_planes().size(), 128u);
  // A request overrides the card.
  const BspMeshOptions o = BspDecodingOptions(kModel, {0.25f, -1.0f});
  EXPECT_FLOAT_EQ(o.dilation, 0.25f);
  EXPECT_FLOAT_EQ(o.distance_dilation, 0.0145f);
}

// A pool code decodes to a closed mesh inside [-1, 1]^3 whose parts hold exactly the points
// Occupancy() calls inside (up to the thin shell between the exact faces and the occupancy's
// summed-excess threshold).
TEST(BspDecoder, PoolCodeDecodesToAClosedMeshThatAgreesWithOccupancy) {
  const BspDecoder& d = Decoder();
  const ShapePool pool = ShapePool::Load(kPool);
  ASSERT_GT(pool.size(), 8u);
  for (const std::size_t i : {std::size_t{0}, pool.size() / 2}) {
    const PoolEntry& e = pool.entries()[i];
    ASSERT_EQ(e.code.size(), 2 * d.latent_dim());
    const BspMeshResult r = d.Decode(e.code, e.cad_class);
    ASSERT_GT(r.mesh.faces.size(), 20u) << e.model_id;
    ASSERT_EQ(r.face_convex.size(), r.mesh.faces.size());
    for (const auto& v : r.mesh.vertices) {
      EXPECT_TRUE((v.array().abs() <= 1.0 + 1e-6).all()) << v.transpose();
    }
    // Closed and consistently oriented: every directed edge once, its reverse once.
    std::map<std::pair<int, int>, int> directed;
    for (const auto& f : r.mesh.faces) {
      for (int k = 0; k < 3; ++k) directed[{f[k], f[(k + 1) % 3]}]++;
    }
    for (const auto& [edge, n] : directed) {
      EXPECT_EQ(n, 1);
      EXPECT_EQ(directed.count({edge.second, edge.first}), 1u);
    }
    EXPECT_GT(r.mesh.SignedVolume(), 0.05);  // outward faces, a solid of some size

    // mu alone decodes the same mesh as [mu, logvar].
    const geometry::TriangleMesh from_mu = d.Mesh(e.code.head(d.latent_dim()), e.cad_class);
    ASSERT_EQ(from_mu.faces.size(), r.mesh.faces.size());
    EXPECT_EQ(from_mu.vertices, r.mesh.vertices);

    const Eigen::MatrixX3f pts = BspGridCenters(32);
    const std::vector<std::uint8_t> occ = d.Occupancy(e.code, e.cad_class, pts);
    ASSERT_EQ(occ.size(), static_cast<std::size_t>(pts.rows()));
    int inside = 0, checked = 0, agree = 0;
    for (Eigen::Index p = 0; p < pts.rows(); ++p) {
      const Eigen::Vector3d q = pts.row(p).cast<double>();
      inside += occ[p];
      // Skip points within 0.02 of some face: there the two rules may differ.
      const bool in_loose = InsideParts(r, q, 0.02), in_tight = InsideParts(r, q, -0.02);
      if (in_loose != in_tight) continue;
      ++checked;
      agree += (occ[p] != 0) == in_tight;
    }
    EXPECT_GT(inside, 300) << e.model_id;
    EXPECT_GT(checked, pts.rows() / 2);
    EXPECT_EQ(agree, checked) << e.model_id;
  }
}

// A CAD mesh is encoded in its box-normalised canonical frame: scale and offset do not matter,
// and the code decodes back to the shape (a full box as a cabinet).
TEST(BspDecoder, EncodeMeshIsBoxNormalisedAndDecodesBack) {
  const BspDecoder& d = Decoder();
  geometry::TriangleMesh box;
  for (int i = 0; i < 8; ++i)
    box.vertices.emplace_back(i & 1 ? 0.4 : -0.4, i & 2 ? 0.3 : -0.3, i & 4 ? 0.5 : -0.5);
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    box.faces.emplace_back(q[0], q[1], q[2]);
    box.faces.emplace_back(q[0], q[2], q[3]);
  }
  ASSERT_GT(box.SignedVolume(), 0.0);
  const int kCabinet = 5;
  const Eigen::VectorXf code = d.EncodeMesh(box, kCabinet);
  ASSERT_EQ(code.size(), 2 * d.latent_dim());
  geometry::TriangleMesh moved = box;
  for (auto& v : moved.vertices) v = 3.0 * v + geometry::Vec3(1.0, -2.0, 0.5);
  EXPECT_LT((d.EncodeMesh(moved, kCabinet) - code).cwiseAbs().maxCoeff(), 1e-4f);

  BspSampleOptions so;
  so.resolution = d.resolution();
  const nn::BspSample sample = MakeBspSample(box, kCabinet, "box", so, 1);
  const double iou = OccupancyIoU(d.Occupancy(code, kCabinet, BspGridCenters(32)), sample.iou_grid);
  EXPECT_GT(iou, 0.85);
  // Refinement on the box's own points does not make it worse.
  BspEncodeOptions refine;
  refine.refine_steps = 10;
  const Eigen::VectorXf refined = d.EncodeMesh(box, kCabinet, refine);
  EXPECT_EQ(refined.tail(d.latent_dim()), code.tail(d.latent_dim()));  // logvar kept
  EXPECT_GE(OccupancyIoU(d.Occupancy(refined, kCabinet, BspGridCenters(32)), sample.iou_grid),
            iou - 0.02);
}

// One batched network call for several codes: each entry is the single call's planes up to float
// rounding, repeatable bit for bit, and bad entries are named by index.
TEST(BspDecoder, PlanesBatchMatchesSingleCalls) {
  const BspDecoder& d = Decoder();
  const ShapePool pool = ShapePool::Load(kPool);
  std::vector<Eigen::VectorXf> codes;
  std::vector<int> classes;
  for (std::size_t i = 0; i < 9; ++i) {
    const PoolEntry& e = pool.entries()[i * pool.size() / 9];
    codes.push_back(i % 2 ? e.code : Eigen::VectorXf(e.code.head(d.latent_dim())));
    classes.push_back(e.cad_class);
  }
  const std::vector<Eigen::MatrixXf> batch = d.PlanesBatch(codes, classes);
  ASSERT_EQ(batch.size(), codes.size());
  for (std::size_t i = 0; i < codes.size(); ++i) {
    const Eigen::MatrixXf single = d.Planes(codes[i], classes[i]);
    ASSERT_EQ(batch[i].rows(), single.rows());
    ASSERT_EQ(batch[i].cols(), 4);
    const float scale = single.cwiseAbs().maxCoeff();
    EXPECT_GT(scale, 0.1f);
    EXPECT_LT((batch[i] - single).cwiseAbs().maxCoeff(), 1e-5f * scale) << i;
  }
  const std::vector<Eigen::MatrixXf> again = d.PlanesBatch(codes, classes);
  for (std::size_t i = 0; i < codes.size(); ++i) EXPECT_TRUE(batch[i] == again[i]) << i;
  // Different codes give different planes (not one row copied).
  EXPECT_GT((batch[0] - batch[1]).cwiseAbs().maxCoeff(), 1e-3f);
  EXPECT_TRUE(d.PlanesBatch({}, {}).empty());
  EXPECT_THROW(d.PlanesBatch(codes, {0}), InvalidArgument);
  std::vector<Eigen::VectorXf> bad = codes;
  bad[3](5) = std::numeric_limits<float>::quiet_NaN();
  try {
    d.PlanesBatch(bad, classes);
    ADD_FAILURE() << "a NaN code was decoded";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("code 3"), std::string::npos) << e.what();
  }
  std::vector<int> bad_classes = classes;
  bad_classes[2] = 8;
  EXPECT_THROW(d.PlanesBatch(codes, bad_classes), InvalidArgument);
}

TEST(BspDecoder, ConstCallsMayRunConcurrently) {
  const BspDecoder& d = Decoder();
  const ShapePool pool = ShapePool::Load(kPool);
  const PoolEntry& e = pool.entries()[1];
  const geometry::TriangleMesh ref = d.Mesh(e.code, e.cad_class);
  std::atomic<int> same{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 3; ++t) {
    threads.emplace_back([&] {
      for (int k = 0; k < 3; ++k) same += d.Mesh(e.code, e.cad_class).vertices == ref.vertices;
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(same.load(), 9);
}

TEST(BspDecoder, RejectsBadCodesAndCorruptModels) {
  const BspDecoder& d = Decoder();
  EXPECT_THROW(d.Mesh(Eigen::VectorXf::Zero(7), 0), InvalidArgument);
  EXPECT_THROW(d.Mesh(Eigen::VectorXf::Zero(128), 8), InvalidArgument);
  EXPECT_THROW(d.Mesh(Eigen::VectorXf::Zero(128), -1), InvalidArgument);
  Eigen::VectorXf nan = Eigen::VectorXf::Zero(256);
  nan[3] = std::nanf("");
  EXPECT_THROW(d.Mesh(nan, 0), InvalidArgument);
  EXPECT_THROW(d.EncodeMesh(geometry::TriangleMesh(), 0), InvalidArgument);

  const fs::path dir = fs::temp_directory_path() / "dimr_bsp_decoder_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string corrupt = (dir / "bsp.pt").string();
  {
    std::ifstream in(kModel, std::ios::binary);
    std::string bytes(4096, '\0');
    in.read(&bytes[0], static_cast<std::streamsize>(bytes.size()));
    std::ofstream(corrupt, std::ios::binary) << bytes;  // a truncated copy
  }
  try {
    BspDecoder::Load(corrupt);
    ADD_FAILURE() << "a truncated model loaded";
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find(corrupt), std::string::npos) << e.what();
  }
  std::ofstream(corrupt, std::ios::binary) << "not a model at all";
  EXPECT_THROW(BspDecoder::Load(corrupt), ParseError);
  EXPECT_THROW(BspDecoder::Load((dir / "missing.pt").string()), ParseError);
  // A malformed card beside the weights is named.
  std::ofstream(dir / "model.yaml") << "recommended_distance_dilation: [0.1\n";
  try {
    BspDecoder::Load(corrupt);
    ADD_FAILURE() << "a malformed card was accepted";
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("model.yaml"), std::string::npos) << e.what();
  }
  std::ofstream(dir / "model.yaml") << "recommended_distance_dilation: -0.1\n";
  EXPECT_THROW(BspDecodingOptions(corrupt), ParseError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace dimr::pipeline
