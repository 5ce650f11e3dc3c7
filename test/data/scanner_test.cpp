// Virtual RGB-D scanner: trajectory, noise model, density modes, occlusion, determinism.
#include "dimr/data/scanner.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "dimr/data/labels.h"
#include "dimr/data/synth_random.h"
#include "dimr/data/synthscan.h"
#include "dimr/geometry/error.h"
#include "dimr/geometry/grid_key.h"
#include "dimr/geometry/kdtree.h"
#include "dimr/geometry/mesh_distance.h"

namespace dimr::data {
namespace {

using geometry::Vec3;

// DefaultModesArePinned: TestRoom, SmallScanner with 8 frames, seed 11. The mesh-mode pin is
// with Embree capped at AVX2 (kEmbreeConfig in data/scanner.cpp); before the cap it depended on
// the machine's instruction set (15079 points where it was first recorded). Recorded on an AMD
// EPYC (AVX2); an Intel Xeon (AVX-512, 2026-12-07) gives 14567 points, xyz 138466.059, rgb
// 15168499 (1.1 % / 0.9 % / 1.1 % off) with the same binary code and a bit-identical raw scan,
// so mesh mode is held to kPinMeshTolerance and the raw mode exactly.
constexpr std::size_t kPinMeshPoints = 14728;
constexpr double kPinMeshXyz = 139755.517;
constexpr long long kPinMeshRgb = 15330827;
constexpr double kPinMeshTolerance = 0.03;  // relative, for points, xyz and rgb
constexpr std::size_t kPinRawPoints = 28100;
constexpr double kPinRawXyz = 268432.535;
constexpr long long kPinRawRgb = 29408717;

ScannerConfig SmallScanner() {
  ScannerConfig c;
  c.width = 160;
  c.height = 120;
  c.frames = 24;
  return c;
}

const Room& TestRoom() {
  static const Room room = ComposeRoom(RoomConfig(), 7);
  return room;
}

// RMS distance of the scan points to the placed mesh of the object each one belongs to.
double RmsDistance(const Room& room, const ScanResult& scan, double* max_d) {
  std::vector<std::vector<Vec3>> per(room.objects.size());
  for (std::size_t k = 0; k < scan.points.size(); ++k)
    per[scan.object[k]].push_back(scan.points[k]);
  double sum = 0, mx = 0;
  std::size_t n = 0;
  for (std::size_t o = 0; o < per.size(); ++o) {
    if (per[o].empty()) continue;
    const geometry::MeshDistance md(room.objects[o].WorldMesh());
    for (double d : md.Distances(per[o])) {
      sum += d * d;
      mx = std::max(mx, d);
      ++n;
    }
  }
  *max_d = mx;
  return std::sqrt(sum / std::max<std::size_t>(n, 1));
}

TEST(ScannerTest, TrajectoryIsHandHeldLike) {
  const Room& room = TestRoom();
  ScannerConfig c;
  const auto poses = MakeTrajectory(room, c, 3);
  ASSERT_EQ(poses.size(), static_cast<std::size_t>(c.frames));
  double path = 0;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Vec3 p = poses[i].translation();
    EXPECT_GE(p.z(), c.min_camera_height - 1e-9);
    EXPECT_LE(p.z(), c.max_camera_height + 1e-9);
    EXPECT_TRUE(room.Inside(p.head<2>()));
    const Vec3 fwd = poses[i].linear().col(2);  // optical axis
    const double tilt = std::asin(-fwd.z()) * 180 / M_PI;
    EXPECT_GT(tilt, c.min_tilt_deg - 8);
    EXPECT_LT(tilt, c.max_tilt_deg + 8);
    EXPECT_NEAR(poses[i].linear().determinant(), 1.0, 1e-9);
    if (i > 0) path += (p - poses[i - 1].translation()).norm();
  }
  // The loop goes once around the room.
  EXPECT_GT(path, 1.5 * std::sqrt(room.FloorArea()));
}

TEST(ScannerTest, MeshDensityNoiseAndRawMode) {
  const Room& room = TestRoom();
  ScannerConfig c = SmallScanner();
  const ScanResult mesh = ScanRoom(room, c, 11);
  c.density = ScanDensity::kRaw;
  c.raw_pixel_stride = 1;
  const ScanResult raw = ScanRoom(room, c, 11);
  ASSERT_GT(mesh.points.size(), 5000u);
  EXPECT_EQ(mesh.rays, static_cast<std::size_t>(160 * 120) * mesh.poses.size());
  EXPECT_EQ(mesh.returns, raw.returns);
  EXPECT_LT(mesh.returns, mesh.rays);  // dropout, range limits, windows
  // ScanNet-like: about one point per occupied 2 cm voxel; raw scans are many times denser.
  const double mesh_ratio =
      static_cast<double>(mesh.points.size()) / OccupiedVoxels(mesh.points, 0.02);
  const double raw_ratio =
      static_cast<double>(raw.points.size()) / OccupiedVoxels(raw.points, 0.02);
  EXPECT_GT(mesh_ratio, 0.99);
  EXPECT_LT(mesh_ratio, 1.3);
  EXPECT_GT(raw_ratio, 2.0) << raw.points.size();
  EXPECT_EQ(raw.points.size(), raw.returns);
  // Raw points carry the per-frame depth noise, fused points much less.
  double mesh_max = 0, raw_max = 0;
  const double mesh_rms = RmsDistance(room, mesh, &mesh_max);
  const double raw_rms = RmsDistance(room, raw, &raw_max);
  EXPECT_GT(raw_rms, 0.003);
  EXPECT_LT(raw_rms, 0.02);
  EXPECT_LT(mesh_rms, 0.6 * raw_rms);
  EXPECT_LT(mesh_max, 0.035);
  // Axial noise is truncated at noise_clip sigma of the farthest range.
  const double far_sigma = c.axial_noise_base + c.axial_noise_quad * std::pow(c.max_range - 0.4, 2);
  // (along the ray: depth error / cos of the angle to the optical axis, <= 1.25 here)
  EXPECT_LT(raw_max, 1.25 * c.noise_clip * far_sigma);
  // The ceiling occludes but never appears; every point lies in the room volume.
  for (std::size_t k = 0; k < raw.points.size(); ++k) {
    EXPECT_NE(room.objects[raw.object[k]].role, ObjectRole::kCeiling);
  }
  for (const auto& p : mesh.points) {
    EXPECT_LT(p.z(), room.height + 0.05);
    EXPECT_GT(p.z(), -0.06);
  }
}

TEST(ScannerTest, OcclusionMakesObjectsPartial) {
  const Room& room = TestRoom();
  const ScanResult scan = ScanRoom(room, SmallScanner(), 5);
  int checked = 0;
  for (std::size_t o = 0; o < room.objects.size(); ++o) {
    const PlacedObject& obj = room.objects[o];
    if (obj.role != ObjectRole::kFurniture && obj.role != ObjectRole::kFloor) continue;
    // Undersides are never seen: samples of the bottom face are unobserved.
    const Vec3 bottom = obj.translation - Vec3(0, 0, obj.scale.z() / 2);
    if (obj.role == ObjectRole::kFloor) {
      EXPECT_FALSE(ObservedNear(scan, static_cast<int>(o), bottom));
      const Vec3 top = obj.translation + Vec3(0.3, 0.2, obj.scale.z() / 2);
      (void)top;
    }
    // Backs against walls are never seen.
    if (obj.cad_class == kCadBookshelf || obj.cad_class == kCadSofa) {
      for (double z = -0.4; z <= 0.4; z += 0.1) {
        const Vec3 back =
            obj.translation + obj.Rotation() * Vec3(-obj.scale.x() / 2, 0, z * obj.scale.z());
        EXPECT_FALSE(ObservedNear(scan, static_cast<int>(o), back)) << obj.family;
      }
      ++checked;
    }
  }
  EXPECT_GT(scan.observed_cells.size(), 10000u);
  (void)checked;
}

TEST(ScannerTest, DeterministicAcrossThreadCounts) {
  const Room& room = TestRoom();
  ScannerConfig c = SmallScanner();
  c.frames = 8;
  c.threads = 1;
  const ScanResult a = ScanRoom(room, c, 99);
  c.threads = 3;
  const ScanResult b = ScanRoom(room, c, 99);
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.colors, b.colors);
  EXPECT_EQ(a.object, b.object);
  const ScanResult d = ScanRoom(room, c, 100);
  EXPECT_NE(a.points, d.points);
}

TEST(ScannerTest, DriftMisregistersFrames) {
  const Room& room = TestRoom();
  ScannerConfig c = SmallScanner();
  c.frames = 16;
  const ScanResult clean = ScanRoom(room, c, 4);
  c.drift_translation = 0.004;
  c.drift_rotation_deg = 0.15;
  c.keep_frames = true;
  const ScanResult drift = ScanRoom(room, c, 4);
  double clean_max = 0, drift_max = 0;
  const double clean_rms = RmsDistance(room, clean, &clean_max);
  const double drift_rms = RmsDistance(room, drift, &drift_max);
  EXPECT_GT(drift_rms, 1.5 * clean_rms);
  ASSERT_EQ(drift.frames.size(), drift.poses.size());
  // Estimated poses drift away from the true ones.
  const auto& last = drift.frames.back();
  EXPECT_GT((last.pose.translation() - last.true_pose.translation()).norm(), 0.003);
  EXPECT_FALSE(last.points.empty());
  for (const auto& p : last.points) EXPECT_GT(p.z(), c.min_range - 0.1);  // optical frame
}

TEST(ScannerTest, RejectsBadConfig) {
  ScannerConfig c;
  c.max_range = 0.1;
  EXPECT_THROW(ScanRoom(TestRoom(), c, 0), InvalidArgument);
  EXPECT_THROW(ScanDensityFromName("dense"), InvalidArgument);
  EXPECT_EQ(ScanDensityFromName("raw"), ScanDensity::kRaw);
}

// Median and coefficient of variation of the nearest-neighbour spacing.
void Spacing(const std::vector<Vec3>& pts, double* median, double* cv) {
  const geometry::KdTree tree(pts);
  std::vector<double> nn;
  for (const auto& p : pts) nn.push_back(std::sqrt(tree.KNearest(p, 2)[1].second));
  const double mean = std::accumulate(nn.begin(), nn.end(), 0.0) / nn.size();
  double var = 0;
  for (double d : nn) var += (d - mean) * (d - mean);
  *cv = std::sqrt(var / nn.size()) / mean;
  std::nth_element(nn.begin(), nn.begin() + nn.size() / 2, nn.end());
  *median = nn[nn.size() / 2];
}

TEST(ScannerTest, ScanNetModeFusesAMeshLabelledByItsObjects) {
  const Room& room = TestRoom();
  ScannerConfig c = SmallScanner();
  c.frames = 8;
  c.density = ScanDensity::kScanNet;
  // 2 cm voxels keep this test cheap (1 cm costs minutes of Open3D decimation per room).
  c.tsdf.voxel_size = 0.02;
  c.tsdf.truncation = 0.06;
  c.tsdf.target_spacing = 0.03;
  const ScanResult scan = ScanRoom(room, c, 11);
  std::printf("scannet mode: %zu points, %zu faces; %s\n", scan.points.size(), scan.faces.size(),
              scan.timings.ToString().c_str());
  ASSERT_GT(scan.points.size(), 3000u);
  ASSERT_EQ(scan.colors.size(), scan.points.size());
  ASSERT_EQ(scan.object.size(), scan.points.size());
  ASSERT_GT(scan.faces.size(), scan.points.size());
  for (const auto& f : scan.faces) {
    ASSERT_GE(f.minCoeff(), 0);
    ASSERT_LT(f.maxCoeff(), static_cast<int>(scan.points.size()));
  }
  // Each vertex lies on the placed mesh of the object it is labelled with: labels and
  // geometry are right (a wrong nearest-return label would put it on another object).
  double max_d = 0;
  const double rms = RmsDistance(room, scan, &max_d);
  EXPECT_LT(rms, 0.015);
  EXPECT_LT(max_d, 0.08);
  for (std::size_t k = 0; k < scan.points.size(); ++k) {
    ASSERT_NE(room.objects[scan.object[k]].role, ObjectRole::kCeiling);
  }
  // Decimated to an even, ScanNet-like vertex pattern.
  double median = 0, cv = 0;
  Spacing(scan.points, &median, &cv);
  std::printf("NN spacing median %.4f m, CV %.3f\n", median, cv);
  EXPECT_GT(median, 0.008);
  EXPECT_LT(median, 0.06);
  EXPECT_LT(cv, 0.8);
  // Same seed -> same output.
  const ScanResult again = ScanRoom(room, c, 11);
  ASSERT_EQ(again.points.size(), scan.points.size());
  for (std::size_t k = 0; k < scan.points.size(); ++k) {
    ASSERT_EQ(again.points[k], scan.points[k]) << k;
    ASSERT_EQ(again.colors[k], scan.colors[k]) << k;
    ASSERT_EQ(again.object[k], scan.object[k]) << k;
  }
}

TEST(ScannerTest, StructuredLightNoiseModelStatistics) {
  ScannerConfig c;
  c.EnableRealism();  // sigma(z) = 0.0005 + 0.0025 z^2, disparity steps 0.0029 z^2
  ASSERT_EQ(c.axial_noise_z0, 0.0);
  EXPECT_NEAR(AxialSigma(c, 2.0), 0.0005 + 0.0025 * 4, 1e-12);
  synth::Rng rng(42);
  // Truncated standard normal at 2.5 sigma has standard deviation 0.9668.
  const double trunc_sd = 0.9668;
  for (double z : {1.0, 2.0, 3.0}) {
    c.disparity_quantum = 0;
    const int n = 40000;
    double sum = 0, sum2 = 0, mx = 0;
    for (int i = 0; i < n; ++i) {
      const double e = MeasuredDepth(c, z, rng.Normal()) - z;
      sum += e;
      sum2 += e * e;
      mx = std::max(mx, std::abs(e));
    }
    const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
    const double sigma = AxialSigma(c, z);
    EXPECT_NEAR(sd, trunc_sd * sigma, 0.03 * sigma) << z;
    EXPECT_NEAR(mean, 0.0, 0.03 * sigma) << z;
    EXPECT_LE(mx, c.noise_clip * sigma + 1e-12) << z;
    // Disparity quantisation: depths fall on levels 1 / (k q), spaced ~ q z^2 apart.
    c.disparity_quantum = 0.0029;
    std::vector<double> levels;
    for (int i = 0; i < 2000; ++i) levels.push_back(MeasuredDepth(c, z, rng.Normal()));
    std::sort(levels.begin(), levels.end());
    levels.erase(std::unique(levels.begin(), levels.end()), levels.end());
    ASSERT_GT(levels.size(), 2u) << z;
    for (double l : levels) {
      const double k = 1.0 / (l * c.disparity_quantum);
      EXPECT_NEAR(k, std::round(k), 1e-6) << z;
    }
    const double step = levels[levels.size() / 2 + 1] - levels[levels.size() / 2];
    EXPECT_NEAR(step, c.disparity_quantum * z * z, 0.1 * c.disparity_quantum * z * z) << z;
  }
  // Today's default (Kinect model of Nguyen et al.): sigma(z) = 0.0012 + 0.0019 (z - 0.4)^2.
  const ScannerConfig d;
  EXPECT_NEAR(AxialSigma(d, 2.4), 0.0012 + 0.0019 * 4, 1e-12);
  EXPECT_EQ(MeasuredDepth(d, 2.0, 0.0), 2.0);
}

// The default (v1) modes must not move when v2 knobs are added: a fingerprint of a mesh-mode
// and a raw-mode scan (raw: recorded before SynthScan v2's tuning; mesh: re-recorded with the
// Embree cap named at kPinMeshPoints, the only intended change since).
TEST(ScannerTest, DefaultModesArePinned) {
  const Room& room = TestRoom();
  ScannerConfig c = SmallScanner();
  c.frames = 8;
  auto fingerprint = [](const ScanResult& s, double* xyz, long long* rgb) {
    *xyz = 0;
    *rgb = 0;
    for (std::size_t k = 0; k < s.points.size(); ++k) {
      *xyz += s.points[k].x() + 2 * s.points[k].y() + 3 * s.points[k].z();
      *rgb += s.colors[k][0] + 2 * s.colors[k][1] + 3 * s.colors[k][2] + 7 * s.object[k];
    }
  };
  double xyz = 0;
  long long rgb = 0;
  const ScanResult mesh = ScanRoom(room, c, 11);
  fingerprint(mesh, &xyz, &rgb);
  std::printf("mesh: %zu points, xyz %.9g, rgb %lld\n", mesh.points.size(), xyz, rgb);
  EXPECT_NEAR(static_cast<double>(mesh.points.size()), static_cast<double>(kPinMeshPoints),
              kPinMeshTolerance * kPinMeshPoints);
  EXPECT_NEAR(xyz, kPinMeshXyz, kPinMeshTolerance * std::abs(kPinMeshXyz));
  EXPECT_NEAR(static_cast<double>(rgb), static_cast<double>(kPinMeshRgb),
              kPinMeshTolerance * kPinMeshRgb);
  c.density = ScanDensity::kRaw;
  const ScanResult raw = ScanRoom(room, c, 11);
  fingerprint(raw, &xyz, &rgb);
  std::printf("raw: %zu points, xyz %.9g, rgb %lld\n", raw.points.size(), xyz, rgb);
  EXPECT_EQ(raw.points.size(), kPinRawPoints);
  EXPECT_NEAR(xyz, kPinRawXyz, 1e-6 * std::abs(kPinRawXyz));
  EXPECT_EQ(rgb, kPinRawRgb);
}

// Mesh mode keeps one point per occupied voxel. On the default grid the floor (z = 0) lies on a
// voxel boundary, so its hits are split between two layers and every floor column gets two
// points a few millimetres apart; mesh_grid_offset = 0.5 puts the floor inside one layer.
TEST(ScannerTest, MeshGridOffsetKeepsOneFloorLayer) {
  const Room& room = TestRoom();
  struct Layers {
    std::size_t points = 0, close = 0, floor = 0, columns = 0, below = 0;
  };
  auto measure = [&](double offset) {
    ScannerConfig c = SmallScanner();
    c.mesh_grid_offset = offset;
    const ScanResult mesh = ScanRoom(room, c, 11);
    Layers out;
    out.points = mesh.points.size();
    const geometry::KdTree tree(mesh.points);
    std::vector<std::int64_t> columns;
    for (const Vec3& p : mesh.points) {
      const auto nn = tree.KNearest(p, 2);
      if (nn.size() == 2 && nn[1].second < 0.005 * 0.005) ++out.close;
      if (std::abs(p.z()) >= 0.03) continue;
      ++out.floor;
      out.below += p.z() < 0;
      // The x-y cell of the (shifted) grid the point was fused in.
      const auto ix = static_cast<std::int64_t>(std::floor(p.x() / c.mesh_voxel_size + offset));
      const auto iy = static_cast<std::int64_t>(std::floor(p.y() / c.mesh_voxel_size + offset));
      columns.push_back(geometry::PackCell2(ix, iy));
    }
    std::sort(columns.begin(), columns.end());
    out.columns =
        static_cast<std::size_t>(std::unique(columns.begin(), columns.end()) - columns.begin());
    std::printf(
        "offset %.1f: %zu points, %zu with a neighbour within 5 mm; %zu floor points in %zu "
        "columns\n",
        offset, out.points, out.close, out.floor, out.columns);
    return out;
  };
  const Layers split = measure(0.0);
  ASSERT_GT(split.floor, 100u);
  EXPECT_LT(split.columns, split.floor * 6 / 10) << "the default grid doubles the floor";
  const Layers one = measure(0.5);
  ASSERT_GT(one.floor, 100u);
  EXPECT_GE(one.columns, one.floor * 97 / 100) << "floor columns with two points";
  EXPECT_LT(one.close, one.points / 100);
  EXPECT_GT(split.close, 4 * one.close + 100);
  // The same floor area either way; the noisy measurements average to both sides of z = 0.
  EXPECT_NEAR(static_cast<double>(one.columns), static_cast<double>(split.columns),
              0.05 * static_cast<double>(split.columns));
  EXPECT_GT(one.below, one.floor / 5);
  EXPECT_LT(one.below, one.floor * 4 / 5);
  ScannerConfig bad = SmallScanner();
  bad.mesh_grid_offset = 1.0;
  EXPECT_THROW(bad.Validate(), InvalidArgument);
  // The API and the --scanner parser accept the same range, [0, 0.99].
  bad.mesh_grid_offset = 0.995;
  EXPECT_THROW(bad.Validate(), InvalidArgument);
  bad.mesh_grid_offset = 0.99;
  EXPECT_NO_THROW(bad.Validate());
  EXPECT_THROW(ScannerFields().Parse("mesh_grid_offset=0.995", bad), InvalidArgument);
}

TEST(ScannerTest, TemporalAveragingShrinksNoiseAndDithersDisparitySteps) {
  ScannerConfig c;
  c.EnableRealism();
  ASSERT_GT(c.sensor_frames, 1);
  synth::Rng rng(7);
  const double trunc_sd = 0.9668;  // sd of a standard normal truncated at 2.5
  for (int k : {1, 4, 16}) {
    for (double z : {1.5, 3.0}) {
      for (double q : {0.0, 0.0029}) {
        c.disparity_quantum = q;
        const int n = 20000;
        double sum = 0, sum2 = 0;
        std::vector<double> values;
        std::vector<double> normals(k);
        for (int i = 0; i < n; ++i) {
          for (double& x : normals) x = rng.Normal();
          const double e = AveragedDepth(c, z, normals.data(), k) - z;
          sum += e;
          sum2 += e * e;
          if (i < 400) values.push_back(e);
        }
        const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
        const double sigma = AxialSigma(c, z);
        // Quantisation of each sample adds ~step^2 / 12 of variance before the averaging.
        const double step = q * z * z;
        const double expect = std::sqrt(std::pow(trunc_sd * sigma, 2) + step * step / 12) /
                              std::sqrt(static_cast<double>(k));
        EXPECT_NEAR(sd, expect, 0.12 * expect) << "k " << k << " z " << z << " q " << q;
        EXPECT_NEAR(mean, 0.0, 0.1 * sigma + 0.02 * step) << "k " << k << " z " << z;
        // Averaged measurements fall between the disparity levels: many distinct values.
        std::sort(values.begin(), values.end());
        values.erase(std::unique(values.begin(), values.end()), values.end());
        // (one measurement: the ~5 levels within the noise clip)
        if (q > 0 && k == 1) {
          EXPECT_LT(values.size(), 12u) << "z " << z;
        }
        if (q > 0 && k > 1) {
          EXPECT_GT(values.size(), 12u) << "k " << k << " z " << z;
        }
      }
    }
  }
  // One measurement is MeasuredDepth itself.
  const double x = 0.7;
  EXPECT_EQ(AveragedDepth(c, 2.0, &x, 1), MeasuredDepth(c, 2.0, x));
  EXPECT_THROW(AveragedDepth(c, 2.0, &x, 0), InvalidArgument);
  c.sensor_frames = 0;
  EXPECT_THROW(c.Validate(), InvalidArgument);
}

TEST(ScannerTest, ScannerUsesTheAveragedDepth) {
  // Raw returns of a v2 scan (no drift, no flying pixels): averaging 16 sensor frames puts them
  // ~4x closer to the true surfaces than one measurement.
  const Room& room = TestRoom();
  ScannerConfig c = SmallScanner();
  c.frames = 4;
  c.EnableRealism();
  c.density = ScanDensity::kRaw;
  c.drift_translation = 0;
  c.drift_rotation_deg = 0;
  c.flying_pixel_probability = 0;
  c.sensor_frames = 1;
  double max1 = 0, max16 = 0;
  const double rms1 = RmsDistance(room, ScanRoom(room, c, 9), &max1);
  c.sensor_frames = 16;
  const double rms16 = RmsDistance(room, ScanRoom(room, c, 9), &max16);
  std::printf("raw rms: 1 frame %.4f m, 16 frames %.4f m\n", rms1, rms16);
  EXPECT_GT(rms1, 0.005);
  EXPECT_LT(rms16, 0.4 * rms1);
  EXPECT_GT(rms16, 0.1 * rms1);
}

TEST(ScannerTest, ScannerFieldsParseAndCheckTheKnobs) {
  ScannerConfig c;
  c.EnableRealism();
  const ScannerConfig d =
      ScannerFields().Parse("disparity_quantum=0 sensor_frames=4 tsdf_voxel_size=0.02", c);
  EXPECT_EQ(d.disparity_quantum, 0.0);
  EXPECT_EQ(d.sensor_frames, 4);
  EXPECT_EQ(d.tsdf.voxel_size, 0.02);
  EXPECT_EQ(d.axial_noise_quad, c.axial_noise_quad);  // untouched keys keep the base
  EXPECT_THROW(ScannerFields().Parse("no_such_key=1", c), InvalidArgument);
  EXPECT_THROW(ScannerFields().Parse("dropout=1.5", c), InvalidArgument);
  EXPECT_THROW(ScannerFields().Parse("sensor_frames=2.5", c), InvalidArgument);
  // Format -> Parse reproduces the config.
  const ScannerConfig e = ScannerFields().Parse(ScannerFields().Format(d), ScannerConfig());
  EXPECT_EQ(ScannerFields().Format(e), ScannerFields().Format(d));
  EXPECT_EQ(e.shadow_strength, d.shadow_strength);
  EXPECT_EQ(e.exposure_drift, d.exposure_drift);
}

TEST(ScannerTest, CastShadowsOnlyDarken) {
  const Room& room = TestRoom();
  ScannerConfig c = SmallScanner();
  c.frames = 6;
  c.EnableRealism();
  c.shadow_strength = 0;
  const ScanResult lit = ScanRoom(room, c, 5);
  c.shadow_strength = 1.0;
  const ScanResult shadowed = ScanRoom(room, c, 5);
  // Shadow rays draw no random numbers: same points, colours only ever darker.
  ASSERT_EQ(lit.points.size(), shadowed.points.size());
  ASSERT_GT(lit.points.size(), 1000u);
  std::size_t darker = 0;
  double drop = 0;
  for (std::size_t k = 0; k < lit.points.size(); ++k) {
    ASSERT_EQ(lit.points[k], shadowed.points[k]);
    int d = 0;
    for (int ch = 0; ch < 3; ++ch) {
      ASSERT_LE(shadowed.colors[k][ch], lit.colors[k][ch] + 1) << k;
      d += lit.colors[k][ch] - shadowed.colors[k][ch];
    }
    if (d > 6) ++darker;
    drop += d / 3.0;
  }
  const double share = static_cast<double>(darker) / lit.points.size();
  std::printf("shadowed share %.3f, mean drop %.1f\n", share, drop / lit.points.size());
  // Furniture shadows the floor and walls under the point light: a real share, not all.
  EXPECT_GT(share, 0.03);
  EXPECT_LT(share, 0.8);
}

TEST(ScannerTest, RealismChangesColoursAndKeepsDefaultsOff) {
  const Room& room = TestRoom();
  ScannerConfig c = SmallScanner();
  c.frames = 6;
  EXPECT_FALSE(c.ColourRealism());
  const ScanResult plain = ScanRoom(room, c, 3);
  c.EnableRealism();
  EXPECT_TRUE(c.ColourRealism());
  const ScanResult v2 = ScanRoom(room, c, 3);
  ASSERT_GT(v2.points.size(), 1000u);
  // Colour spread per channel grows (palettes, exposure, shading).
  auto spread = [](const ScanResult& s) {
    double total = 0;
    for (int k = 0; k < 3; ++k) {
      double m = 0, m2 = 0;
      for (const auto& col : s.colors) {
        m += col[k];
        m2 += double(col[k]) * col[k];
      }
      m /= s.colors.size();
      total += std::sqrt(m2 / s.colors.size() - m * m);
    }
    return total / 3;
  };
  std::printf("colour std: plain %.1f, v2 %.1f\n", spread(plain), spread(v2));
  EXPECT_GT(spread(v2), spread(plain) + 10);
  // Same seed -> identical v2 scan.
  const ScanResult again = ScanRoom(room, c, 3);
  ASSERT_EQ(again.points.size(), v2.points.size());
  for (std::size_t k = 0; k < v2.points.size(); ++k) {
    ASSERT_EQ(again.points[k], v2.points[k]);
    ASSERT_EQ(again.colors[k], v2.colors[k]);
  }
  // Height cap: no surface above the cap.
  c.height_cap_probability = 1.0;
  c.height_cap_min = c.height_cap_max = 1.0;
  const ScanResult capped = ScanRoom(room, c, 3);
  for (const auto& p : capped.points) EXPECT_LT(p.z(), 1.0 + 0.08);
  c = SmallScanner();
  c.min_coverage = 0.05;
  EXPECT_THROW(c.Validate(), InvalidArgument);
  c = SmallScanner();
  c.density = ScanDensity::kScanNet;
  c.tsdf.truncation = 0.001;
  EXPECT_THROW(c.Validate(), InvalidArgument);
  EXPECT_EQ(ScanDensityFromName("scannet"), ScanDensity::kScanNet);
  EXPECT_STREQ(ScanDensityName(ScanDensity::kScanNet), "scannet");
}

TEST(ScannerTest, CeilingScansKeepTheCeilingAsIgnoredPoints) {
  const Room& room = TestRoom();
  int ceiling = -1;
  for (std::size_t o = 0; o < room.objects.size(); ++o)
    if (room.objects[o].role == ObjectRole::kCeiling) ceiling = static_cast<int>(o);
  ASSERT_GE(ceiling, 0);
  EXPECT_LT(room.objects[ceiling].rfs_class, 0);  // its points carry the ignore label
  ScannerConfig c = SmallScanner();
  c.frames = 12;
  const ScanResult plain = ScanRoom(room, c, 4);
  c.ceiling_probability = 0.0;  // the default: the ceiling only occludes
  for (int o : plain.object) ASSERT_NE(o, ceiling);
  c.ceiling_probability = 1.0;
  const ScanResult with = ScanRoom(room, c, 4);
  // Every 5th frame (look-up fraction 0.2) got an upward twin.
  EXPECT_EQ(with.poses.size(), plain.poses.size() + (plain.poses.size() + 4) / 5);
  int up = 0;
  for (const auto& p : with.poses) up += p.linear().col(2).z() > 0.1;  // optical axis upward
  EXPECT_GE(up, static_cast<int>(plain.poses.size() / 5));
  std::size_t on_ceiling = 0;
  for (std::size_t k = 0; k < with.points.size(); ++k) {
    if (with.object[k] != ceiling) continue;
    ++on_ceiling;
    EXPECT_NEAR(with.points[k].z(), room.height, 0.06) << k;
  }
  std::printf("ceiling points: %zu of %zu\n", on_ceiling, with.points.size());
  EXPECT_GT(on_ceiling, with.points.size() / 50);
  // Deterministic, and a capped scan sees no ceiling.
  const ScanResult again = ScanRoom(room, c, 4);
  ASSERT_EQ(again.points.size(), with.points.size());
  for (std::size_t k = 0; k < with.points.size(); ++k) ASSERT_EQ(again.points[k], with.points[k]);
  c.height_cap_probability = 1.0;
  c.height_cap_min = c.height_cap_max = 1.5;
  for (int o : ScanRoom(room, c, 4).object) ASSERT_NE(o, ceiling);
  c = SmallScanner();
  c.ceiling_max_up_deg = 5;
  EXPECT_THROW(c.Validate(), InvalidArgument);
}

TEST(ScannerTest, RealFurnitureVertexColoursReachTheScan) {
  Room room = TestRoom();
  ScannerConfig c = SmallScanner();
  c.frames = 8;
  // The best-seen furniture object gets a texture.
  std::vector<int> count(room.objects.size(), 0);
  for (int o : ScanRoom(room, c, 5).object) ++count[o];
  int target = -1;
  for (std::size_t o = 0; o < room.objects.size(); ++o) {
    if (room.objects[o].role == ObjectRole::kFurniture && (target < 0 || count[o] > count[target]))
      target = static_cast<int>(o);
  }
  ASSERT_GE(target, 0);
  auto& obj = room.objects[target];
  // Texture: red on the vertices above the object's middle height, blue below.
  obj.mesh.vertex_colors.clear();
  for (const auto& v : obj.mesh.vertices)
    obj.mesh.vertex_colors.push_back(v.z() > 0 ? geometry::Color(230, 20, 20)
                                               : geometry::Color(20, 20, 230));
  const ScanResult scan = ScanRoom(room, c, 5);
  int red = 0, blue = 0, total = 0;
  for (std::size_t k = 0; k < scan.points.size(); ++k) {
    if (scan.object[k] != target) continue;
    const auto& col = scan.colors[k];
    red += col[0] > col[1] + 60 && col[0] > col[2] + 60;
    blue += col[2] > col[0] + 60 && col[2] > col[1] + 60;
    ++total;
  }
  ASSERT_GT(total, 50) << obj.family;
  // Every point shows the texture (mixed voxels on the red / blue border aside).
  EXPECT_GT(red + blue, 0.85 * total) << red << " " << blue << " " << total;
  EXPECT_GT(red, 0);
}

}  // namespace
}  // namespace dimr::data
