// Stage-1 inference after the network (issue 21): the test-time-augmentation average against a
// straightforward per-point accumulation of single passes, the in-place softmax against double
// precision, and the network frame's floor against the sorted sweep it replaced.
#include "../../src/nn/stage1_heads.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "dimr/nn/stage1_data.h"
#include "dimr/nn/stage1_model.h"

namespace dimr::nn {
namespace {

// An asymmetric room: floor, two walls, an L-shaped block and a few loose points, ~n points,
// with colours.
void Room(int n, std::uint64_t seed, std::vector<Eigen::Vector3f>* points,
          std::vector<Eigen::Vector3f>* colours) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  for (int i = 0; i < n; ++i) {
    const float r = u(rng);
    Eigen::Vector3f p;
    if (r < 0.45f) {
      p = {3.1f * u(rng), 2.3f * u(rng), 0.01f * u(rng)};
    } else if (r < 0.65f) {
      p = {3.1f * u(rng), 0.0f, 2.2f * u(rng)};
    } else if (r < 0.8f) {
      p = {0.0f, 2.3f * u(rng), 2.2f * u(rng)};
    } else if (r < 0.97f) {
      p = {0.6f + 0.9f * u(rng), 0.4f + 0.3f * u(rng), 0.8f * u(rng)};
      if (u(rng) < 0.4f) p = {0.6f + 0.3f * u(rng), 0.7f + 0.8f * u(rng), 0.8f * u(rng)};
    } else {
      p = {3.1f * u(rng), 2.3f * u(rng), 2.2f * u(rng)};
    }
    points->push_back(p + Eigen::Vector3f(10.0f, -4.0f, 0.3f));
    colours->push_back(Eigen::Vector3f(u(rng), u(rng), u(rng)));
  }
}

// The mean over the passes of Predict on the moved points, mapped back point by point:
// pass (m, k) saw p -> centre + R(theta) (s * (p - centre)), s = -1 on x if m = 1, theta =
// 2 pi k / rotations. A direction d seen there is s R(-theta) d here; a heading h here is
// theta + (pi - h if mirrored, else h) there, so bin b here is bin (6 - b if mirrored, else
// b) + 12 k / rotations there, and a mirrored residual changes sign.
Stage1Output PerPointAverage(const Stage1Model& model, const std::vector<Eigen::Vector3f>& points,
                             const std::vector<Eigen::Vector3f>* colours, int rotations,
                             bool mirror) {
  const std::size_t n = points.size();
  const int nc = model.config().num_classes;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (const auto& p : points) centre += p.head<2>().cast<double>();
  centre /= static_cast<double>(n);
  std::vector<double> sem(n * nc, 0), hp(n * 12, 0), hr(n * 12, 0), off(n * 3, 0);
  int passes = 0;
  for (int m = 0; m < (mirror ? 2 : 1); ++m) {
    for (int k = 0; k < rotations; ++k) {
      const double s = m == 1 ? -1.0 : 1.0;
      const double theta = 2.0 * M_PI * k / rotations;
      const double c = std::cos(theta), sn = std::sin(theta);
      std::vector<Eigen::Vector3f> moved(n);
      for (std::size_t i = 0; i < n; ++i) {
        const double x = s * (points[i].x() - centre.x());
        const double y = points[i].y() - centre.y();
        moved[i] = Eigen::Vector3f(static_cast<float>(centre.x() + c * x - sn * y),
                                   static_cast<float>(centre.y() + sn * x + c * y), points[i].z());
      }
      Stage1Output o = model.Predict(ScenePoints(moved, colours, "moved"));
      o.ExpandToPoints(n, nc);  // per-voxel rows -> one row per point
      ++passes;
      for (std::size_t i = 0; i < n; ++i) {
        for (int j = 0; j < nc; ++j) sem[i * nc + j] += o.semantic_prob[i * nc + j];
        for (int b = 0; b < 12; ++b) {
          const int there = ((m == 1 ? 6 - b : b) + 12 * k / rotations + 24) % 12;
          hp[i * 12 + b] += o.heading_prob[i * 12 + there];
          hr[i * 12 + b] += s * o.heading_residual[i * 12 + there];
        }
        const double dx = o.offsets[i].x(), dy = o.offsets[i].y();
        off[3 * i] += s * (c * dx + sn * dy);
        off[3 * i + 1] += -sn * dx + c * dy;
        off[3 * i + 2] += o.offsets[i].z();
      }
    }
  }
  Stage1Output r;
  for (double v : sem) r.semantic_prob.push_back(static_cast<float>(v / passes));
  for (double v : hp) r.heading_prob.push_back(static_cast<float>(v / passes));
  for (double v : hr) r.heading_residual.push_back(static_cast<float>(v / passes));
  for (std::size_t i = 0; i < n; ++i) {
    r.offsets.emplace_back(off[3 * i] / passes, off[3 * i + 1] / passes, off[3 * i + 2] / passes);
    const float* p = r.semantic_prob.data() + i * nc;
    r.semantic.push_back(static_cast<int>(std::max_element(p, p + nc) - p));
  }
  return r;
}

double MaxDiff(const std::vector<float>& a, const std::vector<float>& b) {
  EXPECT_EQ(a.size(), b.size());
  double d = 0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    d = std::max<double>(d, std::abs(a[i] - b[i]));
  }
  return d;
}

void ExpectSameAverage(const Stage1Model& model, const std::vector<Eigen::Vector3f>& points,
                       const std::vector<Eigen::Vector3f>* colours, int rotations, bool mirror) {
  SCOPED_TRACE("rotations " + std::to_string(rotations) + (mirror ? " + mirror" : ""));
  const ScenePoints view(points, colours, "room");
  Stage1Output got = model.PredictAugmented(view, rotations, mirror);
  const Stage1Output want = PerPointAverage(model, points, colours, rotations, mirror);
  const std::size_t n = points.size();
  const int nc = model.config().num_classes;
  ASSERT_EQ(got.semantic.size(), n);
  // One row per point (each its own mean), stored in the first pass's voxel order: point_row
  // is a permutation of the points.
  ASSERT_EQ(got.point_row.size(), n);
  ASSERT_EQ(got.NumRows(nc), n);
  std::vector<bool> seen(n, false);
  for (std::int64_t r : got.point_row) {
    ASSERT_TRUE(r >= 0 && r < static_cast<std::int64_t>(n) && !seen[r]) << r;
    seen[r] = true;
  }
  EXPECT_EQ(got.SemanticProb(n / 2, nc)[1], got.semantic_prob[got.point_row[n / 2] * nc + 1]);
  got.ExpandToPoints(n, nc);
  // Sums of up to 12 floats in another order (float vs double): a few 1e-7. A wrong heading
  // bin, sign, offset rotation or point -> voxel row is off by 1e-3 or more.
  EXPECT_LT(MaxDiff(got.semantic_prob, want.semantic_prob), 2e-6);
  EXPECT_LT(MaxDiff(got.heading_prob, want.heading_prob), 2e-6);
  EXPECT_LT(MaxDiff(got.heading_residual, want.heading_residual), 2e-6);
  double doff = 0;
  for (std::size_t i = 0; i < n; ++i) {
    doff = std::max<double>(doff, (got.offsets[i] - want.offsets[i]).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(doff, 2e-6);
  int ties = 0;
  for (std::size_t i = 0; i < n; ++i) {
    std::vector<float> p(want.semantic_prob.begin() + i * nc,
                         want.semantic_prob.begin() + (i + 1) * nc);
    std::sort(p.rbegin(), p.rend());
    if (p[0] - p[1] < 1e-5f) {
      ++ties;
      continue;
    }
    ASSERT_EQ(got.semantic[i], want.semantic[i]) << i;
  }
  EXPECT_LT(ties, static_cast<int>(n / 100));
  // Not vacuous: a single pass differs from the average by far more than the tolerance.
  Stage1Output plain = model.Predict(view);
  plain.ExpandToPoints(n, nc);
  EXPECT_GT(MaxDiff(plain.semantic_prob, want.semantic_prob), 1e-3);
  EXPECT_GT(MaxDiff(plain.heading_prob, want.heading_prob), 1e-3);
}

TEST(Stage1Heads, AugmentedPassesMatchPerPointAccumulation) {
  std::vector<Eigen::Vector3f> points, colours;
  Room(6000, 3, &points, &colours);
  // The shipped layout (25 classes: the 52-float rows of the unrolled path), xyz only.
  Stage1Config a;
  a.input.scale = 20;
  a.widths = {8, 12, 16};
  const Stage1Model model_a(a, 5);
  ExpectSameAverage(model_a, points, nullptr, 6, true);  // the model card's 12 passes
  ExpectSameAverage(model_a, points, nullptr, 4, false);
  // Another class count (the run-time row length) with colours, at 10 cm.
  Stage1Config b;
  b.input.scale = 10;
  b.input.use_rgb = true;
  b.widths = {8, 12, 16};
  b.num_classes = 7;
  const Stage1Model model_b(b, 9);
  ExpectSameAverage(model_b, points, &colours, 3, true);
  ExpectSameAverage(model_b, points, &colours, 2, false);
}

// ---------------------------------------------------------------- softmax
TEST(Stage1Heads, SoftmaxMatchesDoublePrecision) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> logit(-40, 40);
  for (int dim : {1, 3, 4, 7, 12, 25, 40}) {
    const int stride = dim + 5;  // strided rows: the 5 floats after each row are not touched
    const int rows = 300;
    std::vector<float> x(rows * stride);
    for (auto& v : x) v = logit(rng);
    // Extreme rows: all equal, one huge, -inf entries, values far below the maximum.
    for (int c = 0; c < dim; ++c) {
      x[0 * stride + c] = 3.0f;
      x[1 * stride + c] = c == dim / 2 ? 1e30f : -1e30f;
      x[2 * stride + c] = c == 0 ? 0.0f : -std::numeric_limits<float>::infinity();
      x[3 * stride + c] = c == dim - 1 ? 50.0f : -60.0f + c;
    }
    const std::vector<float> in = x;
    std::vector<int> argmax(rows, -1);
    stage1_heads::SoftmaxRows(x.data(), rows, dim, stride, argmax.data());
    for (int v = 0; v < rows; ++v) {
      // The reference of the float formula: exp of the float difference x - max (its rounding
      // is the formula's, ~5e-6 relative at |x| ~ 40), in double from there on.
      float mx = -INFINITY;
      for (int c = 0; c < dim; ++c) mx = std::max(mx, in[v * stride + c]);
      auto e = [&](int c) { return std::exp(static_cast<double>(in[v * stride + c] - mx)); };
      double sum = 0;
      for (int c = 0; c < dim; ++c) sum += e(c);
      double total = 0;
      for (int c = 0; c < dim; ++c) {
        const double want = e(c) / sum;
        const float got = x[v * stride + c];
        total += got;
        if (want > 1e-30) {
          ASSERT_NEAR(got / want, 1.0, 1e-6) << "dim " << dim << " row " << v << " col " << c;
        } else {
          ASSERT_LT(got, 1e-30) << "dim " << dim << " row " << v << " col " << c;
        }
      }
      ASSERT_NEAR(total, 1.0, 1e-6);
      const float* row = x.data() + v * stride;
      ASSERT_EQ(argmax[v], std::max_element(row, row + dim) - row) << "dim " << dim << " row " << v;
      for (int c = dim; c < stride; ++c) ASSERT_EQ(x[v * stride + c], in[v * stride + c]);
    }
    EXPECT_FLOAT_EQ(x[0], 1.0f / dim);
  }
  // A NaN logit makes its row NaN, not a plausible distribution.
  std::vector<float> bad{0.5f, std::nanf(""), 1.0f, 2.0f, 0.0f};
  stage1_heads::SoftmaxRows(bad.data(), 1, 5, 5);
  for (float v : bad) EXPECT_TRUE(std::isnan(v));
}

// Every softmax kernel this CPU runs (4-lane, AVX2, AVX-512) gives the 4-lane kernel's bits,
// row lengths 1 ... 33 (the wide kernels take rows <= 32; 33 falls back), strided rows, ties,
// extreme and NaN rows; a kernel the CPU cannot run is refused by name.
TEST(Stage1Heads, SoftmaxKernelsGiveTheSameBits) {
  const auto isas = stage1_heads::SupportedHeadsIsas();
  ASSERT_FALSE(isas.empty());
  ASSERT_EQ(isas.front(), stage1_heads::HeadsIsa::kGeneric);
  std::printf("softmax kernels on this CPU:");
  for (auto isa : isas) std::printf(" %s", stage1_heads::HeadsIsaName(isa));
  std::printf(" (auto: %s)\n", stage1_heads::HeadsIsaName(
                                   stage1_heads::ResolveHeadsIsa(stage1_heads::HeadsIsa::kAuto)));
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<float> logit(-30, 30);
  for (int dim = 1; dim <= 33; ++dim) {
    const int stride = dim + 3;
    const int rows = 200;
    std::vector<float> x(rows * stride);
    for (auto& v : x) v = logit(rng);
    for (int c = 0; c < dim; ++c) {
      x[0 * stride + c] = 1.5f;                                 // all tied: argmax 0
      x[1 * stride + c] = c % 3 == 1 ? 7.0f : -2.0f;            // tied maxima
      x[2 * stride + c] = c == dim - 1 ? 0.0f : -INFINITY;      // one finite entry
      x[3 * stride + c] = c == 0 ? 90.0f : -90.0f;              // underflow to 0
      x[4 * stride + c] = c == dim / 2 ? std::nanf("") : 1.0f;  // NaN row
      // Near ties: exps of 1 and of one ulp below the maximum (the argmax is the first 1).
      x[5 * stride + c] = c % 2 ? 1.0f : std::nextafter(1.0f, 0.0f);
    }
    std::vector<float> want = x;
    std::vector<int> want_arg(rows, -1);
    stage1_heads::SoftmaxRows(want.data(), rows, dim, stride, want_arg.data(),
                              stage1_heads::HeadsIsa::kGeneric);
    for (auto isa : isas) {
      std::vector<float> got = x;
      std::vector<int> got_arg(rows, -1);
      stage1_heads::SoftmaxRows(got.data(), rows, dim, stride, got_arg.data(), isa);
      for (int v = 0; v < rows; ++v) {
        ASSERT_EQ(got_arg[v], want_arg[v])
            << stage1_heads::HeadsIsaName(isa) << " dim " << dim << " row " << v;
        for (int c = 0; c < stride; ++c) {
          const float a = got[v * stride + c], b = want[v * stride + c];
          if (std::isnan(b)) {
            ASSERT_TRUE(std::isnan(a)) << stage1_heads::HeadsIsaName(isa) << " dim " << dim;
            continue;
          }
          std::uint32_t ua, ub;
          std::memcpy(&ua, &a, 4);
          std::memcpy(&ub, &b, 4);
          ASSERT_EQ(ua, ub) << stage1_heads::HeadsIsaName(isa) << " dim " << dim << " row " << v
                            << " col " << c;
        }
      }
      if (dim > 1) {
        ASSERT_EQ(got_arg[1], 1);
      }
      ASSERT_EQ(got_arg[2], dim - 1);
      ASSERT_EQ(got_arg[5], dim > 1 ? 1 : 0);
      ASSERT_EQ(got[3 * stride], 1.0f);
      for (int c = 0; c < dim; ++c) ASSERT_TRUE(std::isnan(got[4 * stride + c]));
    }
  }
  for (auto isa : {stage1_heads::HeadsIsa::kAvx2, stage1_heads::HeadsIsa::kAvx512}) {
    if (std::find(isas.begin(), isas.end(), isa) != isas.end()) continue;
    float row[3] = {0, 1, 2};
    EXPECT_THROW(stage1_heads::SoftmaxRows(row, 1, 3, 3, nullptr, isa), InvalidArgument);
  }
}

// The TTA mean on every kernel this CPU runs gives the 4-lane kernel's bits and argmax: the
// shipped row (25 classes, 52 floats), a short one (7 classes) and one past the wide kernels'
// 64 floats (40 classes: the 4-lane fallback), 12 and 5 passes, rows with ties and NaN.
TEST(Stage1Heads, MeanKernelsGiveTheSameBits) {
  const auto isas = stage1_heads::SupportedHeadsIsas();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> u(0, 1);
  for (int classes : {25, 7, 40}) {
    const stage1_heads::RowLayout L(classes);
    for (int passes : {12, 5}) {
      // Pass 0 has m0 voxels of 1..6 points in voxel order; pass k >= 1 a table of mk voxels.
      const std::int64_t m0 = 300;
      std::vector<std::int64_t> off{0};
      for (std::int64_t v = 0; v < m0; ++v) off.push_back(off.back() + 1 + rng() % 6);
      const std::size_t n = static_cast<std::size_t>(off.back());
      std::vector<std::int64_t> pts(n);
      for (std::size_t j = 0; j < n; ++j) pts[j] = static_cast<std::int64_t>(j);
      std::shuffle(pts.begin(), pts.end(), rng);
      std::vector<std::vector<float>> tables(passes);
      std::vector<std::vector<std::int32_t>> voxel_of(passes);
      for (int k = 0; k < passes; ++k) {
        const std::int64_t mk = k == 0 ? m0 : 150 + 40 * k;
        tables[k].resize(static_cast<std::size_t>(mk) * L.stride);
        for (auto& x : tables[k]) x = u(rng);
        if (k > 0) {
          voxel_of[k].resize(n);
          for (auto& x : voxel_of[k]) x = static_cast<std::int32_t>(rng() % mk);
        }
      }
      // Ties (voxel 1 of pass 0 and every row it meets: equal semantic entries) and a NaN.
      for (int k = 0; k < passes; ++k) {
        const std::int64_t row = k == 0 ? 1 : voxel_of[k][off[1]];
        for (int c = 0; c < classes; ++c) tables[k][row * L.stride + c] = c % 4 == 2 ? 0.5f : 0.1f;
      }
      tables[0][2 * L.stride + classes / 2] = std::nanf("");
      std::vector<const float*> rows;
      std::vector<const std::int32_t*> index;
      for (int k = 0; k < passes; ++k) {
        rows.push_back(tables[k].data());
        index.push_back(voxel_of[k].data());
      }
      Stage1Output want;
      stage1_heads::AverageInVoxelOrder(off.data(), m0, pts.data(), n, rows, index, L, &want,
                                        stage1_heads::HeadsIsa::kGeneric);
      // The tie row's answer is its first maximum, entry 2.
      ASSERT_EQ(want.semantic[pts[off[1]]], classes > 2 ? 2 : 0);
      for (auto isa : isas) {
        Stage1Output got;
        stage1_heads::AverageInVoxelOrder(off.data(), m0, pts.data(), n, rows, index, L, &got, isa);
        const char* name = stage1_heads::HeadsIsaName(isa);
        ASSERT_EQ(got.semantic, want.semantic) << name << " classes " << classes;
        auto same_bits = [&](const std::vector<float>& a, const std::vector<float>& b) {
          if (a.size() != b.size()) return false;
          return std::memcmp(a.data(), b.data(), sizeof(float) * a.size()) == 0;
        };
        ASSERT_TRUE(same_bits(got.semantic_prob, want.semantic_prob)) << name << " " << classes;
        ASSERT_TRUE(same_bits(got.heading_prob, want.heading_prob)) << name << " " << classes;
        ASSERT_TRUE(same_bits(got.heading_residual, want.heading_residual)) << name;
        for (std::size_t i = 0; i < n; ++i) {
          ASSERT_EQ(std::memcmp(got.offsets[i].data(), want.offsets[i].data(), 12), 0) << name;
        }
      }
      // The 4-lane mean is the pass-order sum times 1 / passes, point by point.
      for (std::size_t j = 0; j < n; j += 37) {
        std::int64_t v = 0;
        while (off[v + 1] <= static_cast<std::int64_t>(j)) ++v;
        const int c = 3;
        float sum = tables[0][v * L.stride + c];
        for (int k = 1; k < passes; ++k) sum += tables[k][voxel_of[k][j] * L.stride + c];
        const float mean = sum * (1.0f / passes);
        ASSERT_EQ(want.point_row[pts[j]], static_cast<std::int64_t>(j));  // row j: voxel order
        if (!std::isnan(mean)) {
          ASSERT_EQ(want.semantic_prob[j * classes + c], mean);
        }
      }
    }
  }
}

// ---------------------------------------------------------------- network frame
// The floor rule as first implemented: sort z, sweep the occupied 2 cm bins upwards from the
// lowest point, the median of the first bin with >= 2 % of the points and the next bin; the
// 1st percentile without such a bin.
float SortedSweepFloor(const std::vector<Eigen::Vector3f>& points) {
  std::vector<float> z;
  for (const auto& p : points) z.push_back(p.z());
  std::sort(z.begin(), z.end());
  const std::size_t n = z.size();
  const std::size_t need = std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(0.02 * n)));
  const double z0 = z[0];
  auto bin = [&](float v) { return static_cast<long long>(std::floor((v - z0) / 0.02)); };
  for (std::size_t begin = 0; begin < n;) {
    std::size_t end = begin;
    while (end < n && bin(z[end]) == bin(z[begin])) ++end;
    if (end - begin >= need) {
      std::size_t stop = end;
      while (stop < n && bin(z[stop]) <= bin(z[begin]) + 1) ++stop;
      return z[begin + (stop - begin) / 2];
    }
    begin = end;
  }
  return z[std::min(n - 1, static_cast<std::size_t>(0.01 * (n - 1)))];
}

TEST(Stage1Heads, NetworkFrameMatchesTheSortedSweep) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<float> u(0, 1);
  std::vector<std::vector<Eigen::Vector3f>> clouds;
  // Rooms with a noisy floor at several heights, the floor straddling a bin boundary.
  for (float floor : {0.0f, 0.7f, -3.21f, 12.345f}) {
    std::vector<Eigen::Vector3f> c;
    for (int i = 0; i < 5000; ++i) {
      const bool on_floor = u(rng) < 0.3f;
      c.emplace_back(4 * u(rng), 3 * u(rng),
                     on_floor ? floor + 0.015f * u(rng) : floor + 0.05f + 2.5f * u(rng));
    }
    clouds.push_back(c);
  }
  // No well-populated bin (uniform heights over 10 m): the 1st percentile.
  {
    std::vector<Eigen::Vector3f> c;
    for (int i = 0; i < 4000; ++i) c.emplace_back(u(rng), u(rng), 10 * u(rng));
    clouds.push_back(c);
  }
  // Far outliers above (beyond the histogram) with a floor, and without one.
  {
    std::vector<Eigen::Vector3f> c = clouds[1], d = clouds[4];
    for (int i = 0; i < 20; ++i) {
      c.emplace_back(u(rng), u(rng), 5000 + 10 * u(rng));
      d.emplace_back(u(rng), u(rng), 5000 + 10 * u(rng));
    }
    clouds.push_back(c);
    clouds.push_back(d);
  }
  // A far outlier below: the floor lies beyond the histogram (the sweep's fallback).
  {
    std::vector<Eigen::Vector3f> c = clouds[1];
    c.emplace_back(0.0f, 0.0f, -3000.0f);
    clouds.push_back(c);
  }
  // One point, two points, all at one height.
  clouds.push_back({Eigen::Vector3f(1, 2, 3)});
  clouds.push_back({Eigen::Vector3f(1, 2, 3), Eigen::Vector3f(0, 0, -1)});
  clouds.push_back(std::vector<Eigen::Vector3f>(100, Eigen::Vector3f(0, 1, 0.5f)));
  for (std::size_t k = 0; k < clouds.size(); ++k) {
    const NetworkFrame f = EstimateNetworkFrame(clouds[k]);
    EXPECT_EQ(f.floor_z, SortedSweepFloor(clouds[k])) << "cloud " << k;
    EXPECT_EQ(f.origin.z(), f.floor_z);
  }
  EXPECT_NEAR(EstimateNetworkFrame(clouds[1]).floor_z, 0.7, 0.02);
  EXPECT_NEAR(EstimateNetworkFrame(clouds[5]).floor_z, 0.7, 0.02);  // outliers above ignored
}

// ---------------------------------------------------------------- moved scenes
// The moved points and the network input of a TTA pass (and of the plain pass, from AoS
// points): every kernel this CPU runs gives the bits of the point-by-point formula (the code
// they replaced), for point counts around the
// 16-point blocks, with and without colours, mirrored or not; huge coordinates overflow to a
// non-finite box.
TEST(Stage1Heads, MovedSceneKernelsGiveTheFormulasBits) {
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<float> u(-4, 9);
  for (std::size_t n : {0, 1, 15, 16, 17, 47, 1000}) {
    std::vector<Eigen::Vector3f> p(n), c(n);
    for (auto& q : p) q = Eigen::Vector3f(u(rng), u(rng), 0.3f * u(rng));
    for (auto& q : c) q = Eigen::Vector3f(u(rng), u(rng), u(rng)) / 9.0f;
    for (double sign : {1.0, -1.0}) {
      const double theta = sign > 0 ? 2 * M_PI * 5 / 12 : 2 * M_PI * 7 / 12;
      const double cx = 1.234567, cy = -0.7654321, co = std::cos(theta), si = std::sin(theta);
      // The reference: the formulas as ForwardMovedScene wrote them per point.
      std::vector<float> wx(n), wy(n);
      float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
      for (std::size_t i = 0; i < n; ++i) {
        const double x = sign * (p[i].x() - cx);
        const double y = p[i].y() - cy;
        wx[i] = static_cast<float>(cx + co * x - si * y);
        wy[i] = static_cast<float>(cy + si * x + co * y);
        const float v[3] = {wx[i], wy[i], p[i].z()};
        for (int a = 0; a < 3; ++a) {
          lo[a] = std::min(lo[a], v[a]);
          hi[a] = std::max(hi[a], v[a]);
        }
      }
      const float origin[3] = {0.5f * (lo[0] + hi[0]), 0.5f * (lo[1] + hi[1]), -0.25f};
      const float scale = 20.0f;
      float qmin[3];
      for (int a = 0; a < 3; ++a) qmin[a] = (lo[a] - origin[a]) * scale;
      for (bool rgb : {false, true}) {
        const int C = rgb ? 6 : 3;
        std::vector<float> wf(n * C);
        std::vector<std::int32_t> wv(n * 4);
        for (std::size_t i = 0; i < n; ++i) {
          const float m[3] = {wx[i], wy[i], p[i].z()};
          wv[4 * i] = 0;
          for (int a = 0; a < 3; ++a) {
            const float d = m[a] - origin[a];
            wf[C * i + a] = d;
            wv[4 * i + 1 + a] = static_cast<std::int32_t>(static_cast<double>(d * scale) -
                                                          static_cast<double>(qmin[a]));
            if (rgb) wf[C * i + 3 + a] = c[i][a] - 0.5f;
          }
        }
        for (auto isa : stage1_heads::SupportedHeadsIsas()) {
          SCOPED_TRACE(std::string(stage1_heads::HeadsIsaName(isa)) + " n " + std::to_string(n) +
                       (rgb ? " rgb" : "") + (sign < 0 ? " mirrored" : ""));
          stage1_heads::MovedPoints m;
          stage1_heads::MoveScenePoints(p.data(), n, cx, cy, sign, co, si, &m, isa);
          ASSERT_EQ(m.x.size(), n);
          for (std::size_t i = 0; i < n; ++i) {
            ASSERT_EQ(m.x[i], wx[i]) << i;  // exact: the same operations in the same order
            ASSERT_EQ(m.y[i], wy[i]) << i;
            ASSERT_EQ(m.z[i], p[i].z()) << i;
          }
          for (int a = 0; a < 3; ++a) {
            EXPECT_EQ(m.lo[a], lo[a]);
            EXPECT_EQ(m.hi[a], hi[a]);
          }
          std::vector<float> f(n * C, -7.0f);
          std::vector<std::int32_t> v(n * 4, -7);
          stage1_heads::WriteMovedNetworkInput(m, rgb ? c.data() : nullptr, n, origin, scale, qmin,
                                               f.data(), v.data(), isa);
          for (std::size_t k = 0; k < n * C; ++k) ASSERT_EQ(f[k], wf[k]) << k;
          for (std::size_t k = 0; k < n * 4; ++k) ASSERT_EQ(v[k], wv[k]) << k;
          // The same writer on AoS points (the plain pass: WriteStage1NetworkInput).
          std::vector<Eigen::Vector3f> aos(n);
          for (std::size_t i = 0; i < n; ++i) aos[i] = Eigen::Vector3f(wx[i], wy[i], p[i].z());
          std::fill(f.begin(), f.end(), -7.0f);
          std::fill(v.begin(), v.end(), -7);
          stage1_heads::WriteNetworkInput(aos.data(), rgb ? c.data() : nullptr, n, origin, scale,
                                          qmin, f.data(), v.data(), isa);
          for (std::size_t k = 0; k < n * C; ++k) ASSERT_EQ(f[k], wf[k]) << "aos " << k;
          for (std::size_t k = 0; k < n * 4; ++k) ASSERT_EQ(v[k], wv[k]) << "aos " << k;
        }
      }
    }
  }
  // A coordinate that overflows float when moved gives a non-finite box on every kernel.
  std::vector<Eigen::Vector3f> far(40, Eigen::Vector3f(1, 2, 3));
  far[33].x() = 3.0e38f;
  far[33].y() = 3.0e38f;
  for (auto isa : stage1_heads::SupportedHeadsIsas()) {
    stage1_heads::MovedPoints m;
    stage1_heads::MoveScenePoints(far.data(), far.size(), 0, 0, 1, std::cos(0.7), std::sin(0.7), &m,
                                  isa);
    EXPECT_FALSE(std::isfinite(m.hi[0]) && std::isfinite(m.hi[1]) && std::isfinite(m.lo[0]) &&
                 std::isfinite(m.lo[1]))
        << stage1_heads::HeadsIsaName(isa);
  }
}

}  // namespace
}  // namespace dimr::nn
