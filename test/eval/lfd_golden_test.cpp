// LFD descriptors pinned bit for bit: FNV-1a hashes of the full descriptors of several meshes
// (single part, holes, multipart silhouettes that take the dilation / thinning / bounding-box
// branches of the Fourier descriptor, tiny and rotated shapes), recorded with the implementation
// of 2026-12-01 before its speed-up. Any change of a single byte fails here.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "dimr/eval/lfd.h"
#include "eval/test_meshes.h"

namespace dimr::eval::lfd {
namespace {

using geometry::TriangleMesh;
using geometry::Vec3;

std::uint64_t DescriptorHash(const Descriptor& d) {
  std::uint64_t h = 1469598103934665603ULL;
  auto mix = [&h](const auto& arr) {
    for (std::uint8_t b : arr) {
      h ^= b;
      h *= 1099511628211ULL;
    }
  };
  mix(d.art);
  mix(d.fd);
  mix(d.cir);
  mix(d.ecc);
  return h;
}

TriangleMesh Torus(int nu, int nv, double big, double small) {
  TriangleMesh m;
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const double u = 2 * M_PI * i / nu, v = 2 * M_PI * j / nv;
      m.vertices.emplace_back((big + small * std::cos(v)) * std::cos(u),
                              (big + small * std::cos(v)) * std::sin(u), small * std::sin(v));
    }
  }
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const int a = j * nu + i, b = j * nu + (i + 1) % nu;
      const int c = ((j + 1) % nv) * nu + i, d = ((j + 1) % nv) * nu + (i + 1) % nu;
      m.faces.emplace_back(a, b, c);
      m.faces.emplace_back(b, d, c);
    }
  }
  return m;
}

// A chair: seat, back, four thin legs (separate parts in many views).
TriangleMesh Chair() {
  TriangleMesh m;
  testing::AddBox(&m, {0, 0, 0.45}, {0.5, 0.5, 0.5});
  testing::AddBox(&m, {0, 0.45, 0.5}, {0.5, 0.5, 1.0});
  for (double x : {0.0, 0.46}) {
    for (double y : {0.0, 0.46}) testing::AddBox(&m, {x, y, 0}, {x + 0.04, y + 0.04, 0.45});
  }
  return m;
}

struct Case {
  const char* name;
  TriangleMesh mesh;
  std::uint64_t hash;
};

TEST(LfdGolden, DescriptorsBitExactWithRecordedOutput) {
  std::vector<Case> cases;
  cases.push_back({"table", testing::Table(), 0xcc7e11ed9eae68fcULL});
  cases.push_back({"sphere", testing::Sphere(), 0x6c4b4d858a3d3fdbULL});
  cases.push_back({"box", testing::Box({0, 0, 0}, {1, 0.5, 0.25}), 0xc382e825ea3a2dc9ULL});
  cases.push_back({"torus", Torus(40, 16, 1.0, 0.3), 0x33b613909cbea54dULL});
  cases.push_back({"chair", Chair(), 0x81ca9bc5d7d03cefULL});
  {
    TriangleMesh two = testing::Box({0, 0, 0}, {0.3, 0.3, 0.3});  // far apart: bbox-fill branch
    testing::AddBox(&two, {1.0, 0.8, 0.6}, {1.2, 1.1, 0.9});
    cases.push_back({"two boxes far", two, 0x30897086347c6a86ULL});
  }
  {
    TriangleMesh two = testing::Box({0, 0, 0}, {0.5, 0.5, 0.5});  // a 1-2 pixel gap: dilation
    testing::AddBox(&two, {0.505, 0, 0}, {1.0, 0.5, 0.5});
    cases.push_back({"two boxes near", two, 0x20411993c0058eedULL});
  }
  {
    TriangleMesh t = testing::Table();
    const Eigen::Matrix3d r =
        Eigen::AngleAxisd(0.7, Vec3(0.2, -0.5, 1.0).normalized()).toRotationMatrix();
    t.Transform(r, Vec3(0.1, 0.2, 0.3));
    cases.push_back({"rotated table", t, 0xe354d60700748a6aULL});
  }
  cases.push_back({"square", testing::Square(), 0x1982530fcc6efb23ULL});
  for (const Case& c : cases) {
    const std::uint64_t h = DescriptorHash(ComputeDescriptor(c.mesh));
    EXPECT_EQ(h, c.hash) << c.name << ": descriptor hash now 0x" << std::hex << h;
  }
}

}  // namespace
}  // namespace dimr::eval::lfd
