#include "dimr/eval/lfd.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <set>

#include "eval/test_meshes.h"

namespace dimr::eval::lfd {
namespace {

using geometry::TriangleMesh;
using geometry::Vec3;
using testing::Box;

TEST(LfdTables, FromSpecAppendix) {
  EXPECT_EQ(CameraSets()[0][6], Vec3(1.0515, 0, -0.20081));
  EXPECT_EQ(CameraSets()[9][9], Vec3(-0.711583, 0.769847, 0.216524));
  const auto& a = Align10();
  for (int m = 0; m < kViews; ++m) EXPECT_EQ(a[0][m], m);  // row 0 = identity
  std::set<std::array<std::uint8_t, kViews>> rows;
  for (const auto& row : a) {
    std::set<int> vals(row.begin(), row.end());
    EXPECT_EQ(vals.size(), 10u);  // a permutation of 0..9
    rows.insert(row);
  }
  EXPECT_EQ(rows.size(), 60u);
  // Closed under inverse (a group): the ecc-fixed distance is therefore symmetric.
  for (const auto& row : a) {
    std::array<std::uint8_t, kViews> inv{};
    for (int m = 0; m < kViews; ++m) inv[row[m]] = static_cast<std::uint8_t>(m);
    EXPECT_TRUE(rows.count(inv));
  }
  EXPECT_TRUE(DelTab(0));
  EXPECT_FALSE(DelTab(1));
  EXPECT_TRUE(DelTab(17));  // "10000000000000000110..." bit 17
  EXPECT_TRUE(DelTab(255));
}

Image SquareView(double half, bool only_first_triangle = false) {
  // A square [-half, half]^2 seen face-on from +z (s = +x, u = +y).
  std::vector<Vec3> v = {{-half, -half, 0}, {half, -half, 0}, {half, half, 0}, {-half, half, 0}};
  std::vector<geometry::Vec3i> f = {{0, 1, 2}, {0, 2, 3}};
  if (only_first_triangle) f.pop_back();
  return RenderSilhouette(v, f, Vec3(0, 0, 1));
}

int CountFg(const Image& img) {
  int n = 0;
  for (auto p : img) n += p < 255;
  return n;
}

TEST(LfdRaster, SquareAndTopLeftRule) {
  // x_w = (x + 1) * 128: the square spans window [96, 160]^2 -> exactly 64 x 64 pixel centres.
  const Image sq = SquareView(0.25);
  EXPECT_EQ(CountFg(sq), 64 * 64);
  const ViewCentre c = ComputeCentre(sq);
  EXPECT_EQ(c.minx, 96);
  EXPECT_EQ(c.maxx, 159);
  EXPECT_DOUBLE_EQ(c.cx, 127.5);
  // Triangle (96,96) (160,96) (160,160): its diagonal runs through pixel centres and is a
  // "top-left" edge (dy < 0), so the pixels with x >= y are covered: 64 * 65 / 2.
  EXPECT_EQ(CountFg(SquareView(0.25, true)), 64 * 65 / 2);
}

TEST(LfdFeatures, HandComputedSquareAndRectangle) {
  const Image sq = SquareView(0.25);
  const ViewCentre c = ComputeCentre(sq);
  // Square: mu20 = mu02, mu11 = 0 -> eccentricity 0.
  EXPECT_EQ(EccentricityByte(sq, c), 0);
  // Circularity: A = 4096, P = 252 border pixels; 12.5663704 * 4096 / 252^2 = 0.8105 -> 207.
  EXPECT_EQ(CircularityByte(sq), 207);
  // Contour: the 252 border pixels plus the start pixel again.
  EXPECT_EQ(TraceContour(sq).size(), 253u);
  // 64 x 32 rectangle: mu20 = 32 * 21840, mu02 = 64 * 2728 ->
  // ((mu20 - mu02) / (mu20 + mu02))^2 = 0.36028 -> floor(256 * 0.36028) = 92.
  std::vector<Vec3> v = {
      {-0.25, -0.125, 0}, {0.25, -0.125, 0}, {0.25, 0.125, 0}, {-0.25, 0.125, 0}};
  const Image rect = RenderSilhouette(v, {{0, 1, 2}, {0, 2, 3}}, Vec3(0, 0, 1));
  EXPECT_EQ(CountFg(rect), 64 * 32);
  EXPECT_EQ(EccentricityByte(rect, ComputeCentre(rect)), 92);
  // Empty image: no contour, zero features.
  const Image empty(kSize * kSize, 255);
  EXPECT_TRUE(TraceContour(empty).empty());
  EXPECT_EQ(ComputeCentre(empty).cx, -1);
}

TEST(LfdDistance, MatchesShippedBinaryMagnitudes) {
  // Spec section 6.5: numbers printed by the reference `Distance` binary.
  const Descriptor cube = ComputeDescriptor(Box({0, 0, 0}, {1, 1, 1}));
  const Descriptor slab = ComputeDescriptor(Box({0, 0, 0}, {1, 0.5, 0.1}));
  const Descriptor rod = ComputeDescriptor(Box({0, 0, 0}, {0.1, 0.1, 1}));
  EXPECT_EQ(Distance(cube, cube, false), 36);
  EXPECT_EQ(Distance(slab, slab, false), 1166);
  EXPECT_EQ(Distance(rod, rod, false), 2196);
  EXPECT_EQ(Distance(cube, slab, false), 6472);
  EXPECT_EQ(Distance(slab, cube, false), 7622);
  EXPECT_EQ(Distance(cube, rod, false), 14389);
  // Eccentricity bug removed: symmetric, 0 for identical shapes.
  EXPECT_EQ(Distance(cube, slab, true), 7561);
  EXPECT_EQ(Distance(slab, cube, true), 7561);
  EXPECT_EQ(Distance(slab, slab, true), 0);
}

TEST(LfdDistance, ReferenceSelfDistanceIsPredictionEccentricity) {
  const Descriptor t = ComputeDescriptor(testing::Table());
  long long best = -1;
  for (int d = 0; d < kSets; ++d) {
    long long s = 0;
    for (int v = 0; v < kViews; ++v) s += t.ecc[d * kViews + v];
    best = best < 0 ? s : std::min(best, s);
  }
  EXPECT_GT(best, 0);
  EXPECT_EQ(Distance(t, t, false), best);
  EXPECT_EQ(Distance(t, t, true), 0);
}

TEST(LfdDescriptor, InvariantToTranslationAndScale) {
  const TriangleMesh a = testing::Table();
  TriangleMesh b = a;
  for (Vec3& v : b.vertices) v = v * 4.0 + Vec3(2.5, -1.25, 0.5);  // exact in binary
  EXPECT_TRUE(ComputeDescriptor(a) == ComputeDescriptor(b));
  EXPECT_NE(MeshHash(a), MeshHash(b));
}

TEST(LfdDescriptor, RotationInvariance) {
  const TriangleMesh table = testing::Table();
  TriangleMesh rotated = table;
  const Eigen::Matrix3d r =
      (Eigen::AngleAxisd(0.5, Vec3(0.3, 0.2, 1.0).normalized())).toRotationMatrix();
  rotated.Transform(r, Vec3(1, 2, 3));
  const Descriptor dt = ComputeDescriptor(table);
  const Descriptor dr = ComputeDescriptor(rotated);
  const Descriptor ds = ComputeDescriptor(testing::Sphere());
  const Descriptor dc = ComputeDescriptor(Box({0, 0, 0}, {1, 1, 1}));
  const long long same = Distance(dr, dt, true);
  EXPECT_LT(3 * same, Distance(ds, dt, true));
  EXPECT_LT(3 * same, Distance(dc, dt, true));
}

TEST(LfdArt, SplatEqualsReferenceLoopOrder) {
  const TriangleMesh m = testing::Table();
  const auto verts = NormalizeForLfd(m);
  for (int v = 0; v < kViews; ++v) {
    const Image img = RenderSilhouette(verts, m.faces, CameraSets()[3][v]);
    const ViewCentre c = ComputeCentre(img);
    std::uint8_t a[kArt], b[kArt];
    ArtBytes(img, c, 50.0 / 90.0, a);
    ArtBytesDirect(img, c, 50.0 / 90.0, b);
    for (int k = 0; k < kArt; ++k) EXPECT_EQ(a[k], b[k]) << "view " << v << " coef " << k;
  }
}

TEST(LfdCache, ContentHashAndDisk) {
  const std::string dir =
      (std::filesystem::temp_directory_path() / "dimr_eval_lfd_cache_test").string();
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const TriangleMesh cube = Box({0, 0, 0}, {1, 1, 1});
  TriangleMesh same = cube;  // same bytes, different object: a cache hit
  DescriptorCache c1(dir);
  auto d1 = c1.Get(cube);
  auto d2 = c1.Get(same);
  EXPECT_EQ(d1.get(), d2.get());
  EXPECT_EQ(c1.computed(), 1u);
  EXPECT_EQ(c1.hits(), 1u);
  DescriptorCache c2(dir);  // a new process: loads from disk
  auto d3 = c2.Get(cube);
  EXPECT_EQ(c2.computed(), 0u);
  EXPECT_TRUE(*d3 == *d1);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace dimr::eval::lfd
