// Tests of the procedural CAD library: unit-box normalisation, closed consistently oriented
// parts, determinism, variety, canonical orientation and real cavities.
#include "dimr/data/cad_library.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "dimr/data/labels.h"
#include "dimr/data/room.h"
#include "dimr/geometry/error.h"

namespace dimr::data {
namespace {

using geometry::AABB;
using geometry::Vec3;

AABB PartBounds(const CadModel& m, int p) {
  AABB box;
  for (int f = m.PartBegin(p); f < m.PartEnd(p); ++f) {
    for (int k = 0; k < 3; ++k) box.Extend(m.mesh.vertices[m.mesh.faces[f][k]]);
  }
  return box;
}

double PartVolume(const CadModel& m, int p) {
  const Vec3 o = PartBounds(m, p).Center();
  double v = 0.0;
  for (int f = m.PartBegin(p); f < m.PartEnd(p); ++f) {
    const auto& t = m.mesh.faces[f];
    v += (m.mesh.vertices[t[0]] - o)
             .dot((m.mesh.vertices[t[1]] - o).cross(m.mesh.vertices[t[2]] - o));
  }
  return v / 6.0;
}

// Every directed edge of the part occurs exactly once and its reverse exactly once: the part
// is a closed 2-manifold-edged surface with consistent orientation. Returns "" or a problem.
std::string PartEdgeProblem(const CadModel& m, int p) {
  std::map<std::pair<int, int>, int> directed;
  for (int f = m.PartBegin(p); f < m.PartEnd(p); ++f) {
    const auto& t = m.mesh.faces[f];
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) return "degenerate face";
    for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
  }
  for (const auto& [e, n] : directed) {
    if (n != 1) return "directed edge used " + std::to_string(n) + " times";
    const auto it = directed.find({e.second, e.first});
    if (it == directed.end()) return "boundary edge";
  }
  return "";
}

// Ray-parity point-in-part test (the ray direction is generic to avoid edge hits).
bool InsidePart(const CadModel& m, int p, const Vec3& q) {
  const Vec3 d = Vec3(0.2718, 0.1414, 0.9523).normalized();
  int hits = 0;
  for (int f = m.PartBegin(p); f < m.PartEnd(p); ++f) {
    const auto& t = m.mesh.faces[f];
    const Vec3& a = m.mesh.vertices[t[0]];
    const Vec3 e1 = m.mesh.vertices[t[1]] - a, e2 = m.mesh.vertices[t[2]] - a;
    const Vec3 h = d.cross(e2);
    const double det = e1.dot(h);
    if (std::abs(det) < 1e-15) continue;
    const Vec3 s = q - a;
    const double u = s.dot(h) / det;
    if (u < 0 || u > 1) continue;
    const Vec3 qq = s.cross(e1);
    const double v = d.dot(qq) / det;
    if (v < 0 || u + v > 1) continue;
    if (e2.dot(qq) / det > 0) ++hits;
  }
  return hits % 2 == 1;
}

bool InsideAnyPart(const CadModel& m, const Vec3& q) {
  for (int p = 0; p < m.NumParts(); ++p) {
    if (InsidePart(m, p, q)) return true;
  }
  return false;
}

int FindPart(const CadModel& m, const std::string& name) {
  for (int p = 0; p < m.NumParts(); ++p) {
    if (m.part_names[p] == name) return p;
  }
  return -1;
}

// Number of connected components of the parts under "bounding boxes overlap or touch" (a
// necessary condition for a connected union: a floating part always shows up here).
int BoxComponents(const CadModel& m) {
  const int n = m.NumParts();
  std::vector<AABB> box(n);
  for (int i = 0; i < n; ++i) box[i] = PartBounds(m, i);
  std::vector<int> comp(n, -1);
  int count = 0;
  for (int s = 0; s < n; ++s) {
    if (comp[s] >= 0) continue;
    std::vector<int> stack = {s};
    comp[s] = count;
    while (!stack.empty()) {
      const int i = stack.back();
      stack.pop_back();
      for (int j = 0; j < n; ++j) {
        if (comp[j] >= 0) continue;
        bool touch = true;
        for (int a = 0; a < 3; ++a) {
          touch = touch && box[i].min[a] <= box[j].max[a] + 1e-9 &&
                  box[j].min[a] <= box[i].max[a] + 1e-9;
        }
        if (touch) {
          comp[j] = count;
          stack.push_back(j);
        }
      }
    }
    ++count;
  }
  return count;
}

void CheckWellFormed(const CadModel& m, const std::string& what) {
  SCOPED_TRACE(what);
  ASSERT_FALSE(m.mesh.faces.empty());
  ASSERT_NO_THROW(m.mesh.Validate(what));
  const AABB box = m.mesh.Bounds();
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(box.min[a], -0.5, 1e-9);
    EXPECT_NEAR(box.max[a], 0.5, 1e-9);
    EXPECT_GT(m.nominal_size[a], 0.005);
    EXPECT_LT(m.nominal_size[a], 3.0);
  }
  EXPECT_LT(m.mesh.faces.size(), 5000u);
  ASSERT_EQ(m.part_face_begin.size(), m.part_names.size());
  ASSERT_GE(m.NumParts(), 1);
  EXPECT_EQ(m.part_face_begin[0], 0);
  for (int p = 0; p < m.NumParts(); ++p) {
    ASSERT_LT(m.PartBegin(p), m.PartEnd(p)) << "part " << p;
    EXPECT_EQ(PartEdgeProblem(m, p), "") << "part " << p << " " << m.part_names[p];
    EXPECT_GT(PartVolume(m, p), 1e-9) << "part " << p << " " << m.part_names[p];
  }
  for (const auto& v : m.mesh.vertices) ASSERT_TRUE(v.allFinite());
  for (std::size_t f = 0; f < m.mesh.faces.size(); ++f) {
    ASSERT_GT(m.mesh.FaceArea(f), 1e-14) << "face " << f;
  }
  ASSERT_EQ(m.model_id.size(), 32u);
  for (char c : m.model_id)
    EXPECT_TRUE(std::isxdigit(static_cast<unsigned char>(c)) && !std::isupper(c));
}

TEST(CadLibrary, EveryClassFiftySeedsWellFormed) {
  for (int c = 0; c < kNumCadClasses; ++c) {
    for (std::uint64_t s = 0; s < 50; ++s) {
      const CadModel m = GenerateCadModel(c, s * 7919 + 3);
      CheckWellFormed(
          m, std::string(CadClassNames()[c]) + " seed " + std::to_string(s) + " " + m.family);
      EXPECT_EQ(m.cad_class, c);
      EXPECT_EQ(RfsToCad(m.rfs_class), c);
      EXPECT_EQ(m.rfs_class, m.family == "desk" ? kDesk : CadToRfs(c));
      EXPECT_EQ(m.synset, CadSynsets()[c]);
      EXPECT_EQ(m.distractor_kind, -1);
      const auto fams = CadFamilies(c);
      EXPECT_NE(std::find(fams.begin(), fams.end(), m.family), fams.end()) << m.family;
    }
  }
}

TEST(CadLibrary, DistractorsWellFormed) {
  ASSERT_EQ(NumDistractorKinds(), 14);
  std::set<int> labels;
  for (int k = 0; k < NumDistractorKinds(); ++k) {
    const DistractorInfo& info = GetDistractorInfo(k);
    labels.insert(info.rfs_class);
    for (std::uint64_t s = 0; s < 20; ++s) {
      const CadModel m = GenerateDistractor(k, s);
      CheckWellFormed(m, std::string(info.name) + " seed " + std::to_string(s));
      EXPECT_EQ(m.cad_class, kNonCad);
      EXPECT_EQ(m.rfs_class, info.rfs_class);
      EXPECT_EQ(m.family, info.name);
      EXPECT_EQ(m.distractor_kind, k);
      EXPECT_TRUE(m.synset.empty());
      if (info.placement == DistractorPlacement::kWall) {
        // Wall objects are thin along x (their back at -x against the wall).
        EXPECT_LT(m.nominal_size.x(), 0.35) << info.name;
      }
    }
  }
  // bed, door, window, picture, curtain, otherfurniture, kitchen_cabinet and ignore.
  EXPECT_EQ(labels, (std::set<int>{-1, kBed, kDoor, kWindow, kPicture, kCurtain, kOtherFurniture,
                                   kKitchenCabinet}));
  EXPECT_NE(GenerateDistractor(0, 1).model_id, GenerateCadModel(0, 1).model_id);
}

TEST(CadLibrary, NoFloatingParts) {
  for (int c = 0; c < kNumCadClasses; ++c) {
    for (std::uint64_t s = 0; s < 100; ++s) {
      const CadModel m = GenerateCadModel(c, s);
      EXPECT_EQ(BoxComponents(m), 1) << m.family << " seed " << s;
    }
  }
  for (int k = 0; k < NumDistractorKinds(); ++k) {
    for (std::uint64_t s = 0; s < 50; ++s) {
      const CadModel m = GenerateDistractor(k, s);
      EXPECT_EQ(BoxComponents(m), 1) << m.family << " seed " << s;
    }
  }
}

TEST(CadLibrary, BadArgumentsThrow) {
  EXPECT_THROW(GenerateCadModel(-1, 0), InvalidArgument);
  EXPECT_THROW(GenerateCadModel(kNumCadClasses, 0), InvalidArgument);
  EXPECT_THROW(GenerateDistractor(NumDistractorKinds(), 0), InvalidArgument);
  EXPECT_THROW(GetDistractorInfo(-1), InvalidArgument);
  EXPECT_THROW(CadFamilies(8), InvalidArgument);
}

bool SameBytes(const CadModel& a, const CadModel& b) {
  if (a.mesh.vertices.size() != b.mesh.vertices.size() ||
      a.mesh.faces.size() != b.mesh.faces.size()) {
    return false;
  }
  return std::memcmp(a.mesh.vertices.data(), b.mesh.vertices.data(),
                     a.mesh.vertices.size() * sizeof(Vec3)) == 0 &&
         std::memcmp(a.mesh.faces.data(), b.mesh.faces.data(),
                     a.mesh.faces.size() * sizeof(geometry::Vec3i)) == 0 &&
         a.model_id == b.model_id && a.family == b.family && a.nominal_size == b.nominal_size &&
         a.part_face_begin == b.part_face_begin && a.part_names == b.part_names;
}

TEST(CadLibrary, DeterministicAndSeedSensitive) {
  for (int c = 0; c < kNumCadClasses; ++c) {
    for (std::uint64_t s : {0ULL, 1ULL, 123456789ULL, ~0ULL}) {
      EXPECT_TRUE(SameBytes(GenerateCadModel(c, s), GenerateCadModel(c, s)));
    }
    std::set<std::string> ids;
    std::set<std::vector<double>> sizes;
    for (std::uint64_t s = 0; s < 100; ++s) {
      const CadModel m = GenerateCadModel(c, s);
      ids.insert(m.model_id);
      sizes.insert({m.nominal_size.x(), m.nominal_size.y(), m.nominal_size.z()});
    }
    EXPECT_EQ(ids.size(), 100u);
    EXPECT_EQ(sizes.size(), 100u);  // continuous parameters: no two models alike
  }
  for (int k = 0; k < NumDistractorKinds(); ++k) {
    EXPECT_TRUE(SameBytes(GenerateDistractor(k, 42), GenerateDistractor(k, 42)));
    EXPECT_FALSE(SameBytes(GenerateDistractor(k, 42), GenerateDistractor(k, 43)));
  }
  // Ids depend on the class too.
  EXPECT_NE(GenerateCadModel(0, 5).model_id, GenerateCadModel(1, 5).model_id);
}

TEST(CadLibrary, ThreadSafeAndIdenticalToSerial) {
  std::vector<CadModel> serial;
  for (int i = 0; i < 64; ++i) serial.push_back(GenerateCadModel(i % kNumCadClasses, 500 + i));
  std::vector<CadModel> parallel(64);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([t, &parallel]() {
      for (int i = t; i < 64; i += 4) parallel[i] = GenerateCadModel(i % kNumCadClasses, 500 + i);
    });
  }
  for (auto& th : threads) th.join();
  for (int i = 0; i < 64; ++i) EXPECT_TRUE(SameBytes(serial[i], parallel[i])) << i;
}

TEST(CadLibrary, IntraClassVariety) {
  for (int c = 0; c < kNumCadClasses; ++c) {
    SCOPED_TRACE(CadClassNames()[c]);
    std::map<std::string, int> families;
    double min_ratio = 1e9, max_ratio = 0, min_h = 1e9, max_h = 0;
    std::set<std::size_t> face_counts;
    for (std::uint64_t s = 0; s < 200; ++s) {
      const CadModel m = GenerateCadModel(c, s);
      ++families[m.family];
      const double ratio = m.nominal_size.y() / m.nominal_size.z();
      min_ratio = std::min(min_ratio, ratio);
      max_ratio = std::max(max_ratio, ratio);
      min_h = std::min(min_h, m.nominal_size.z());
      max_h = std::max(max_h, m.nominal_size.z());
      face_counts.insert(m.mesh.faces.size());
    }
    // Every family occurs, none dominates.
    EXPECT_EQ(families.size(), CadFamilies(c).size());
    for (const auto& [name, n] : families) {
      EXPECT_GE(n, 200 / static_cast<int>(families.size()) / 3) << name;
    }
    EXPECT_GT(max_ratio / min_ratio, 1.6) << min_ratio << " " << max_ratio;
    EXPECT_GT(max_h / min_h, 1.25) << min_h << " " << max_h;
    EXPECT_GE(face_counts.size(), 3u);  // structure (number of parts) varies too
  }
}

TEST(CadLibrary, RealisticNominalSizes) {
  // Heights in metres per class: [min, max] over 100 seeds must lie in realistic ranges.
  const std::map<int, std::pair<double, double>> kHeight = {
      {kCadTable, {0.34, 1.12}},  {kCadChair, {0.42, 1.45}},   {kCadBookshelf, {0.69, 2.21}},
      {kCadSofa, {0.74, 1.0}},    {kCadTrashBin, {0.29, 1.4}}, {kCadCabinet, {0.49, 2.2}},
      {kCadDisplay, {0.25, 1.3}}, {kCadBathtub, {0.44, 0.95}}};
  for (const auto& [c, range] : kHeight) {
    for (std::uint64_t s = 0; s < 100; ++s) {
      const CadModel m = GenerateCadModel(c, s);
      EXPECT_GE(m.nominal_size.z(), range.first) << CadClassNames()[c] << " " << m.family;
      EXPECT_LE(m.nominal_size.z(), range.second) << CadClassNames()[c] << " " << m.family;
    }
  }
  // Width (y): a sofa seats two or more (>= 1.0 m); one seat wide is the chair family's
  // armchair (ScanNet's label for it), and chairs stay within the chair size range.
  double narrowest_sofa = 1e9, widest_chair = 0;
  for (std::uint64_t s = 0; s < 200; ++s) {
    narrowest_sofa = std::min(narrowest_sofa, GenerateCadModel(kCadSofa, s).nominal_size.y());
    widest_chair = std::max(widest_chair, GenerateCadModel(kCadChair, s).nominal_size.y());
  }
  EXPECT_GE(narrowest_sofa, 1.0);
  EXPECT_LE(widest_chair, 1.0);
  Vec3 lo, hi;
  CadSizeRange(kCadSofa, &lo, &hi);
  EXPECT_GE(lo.y(), 1.0);
}

TEST(CadLibrary, ChairAndSofaBacksAtMinusX) {
  for (int c : {kCadChair, kCadSofa}) {
    for (std::uint64_t s = 0; s < 60; ++s) {
      const CadModel m = GenerateCadModel(c, s);
      if (m.family == "stool") continue;
      const int back = FindPart(m, "back");
      ASSERT_GE(back, 0) << m.family;
      const AABB bb = PartBounds(m, back);
      EXPECT_LT(bb.Center().x(), -0.2) << m.family << " seed " << s;
      // The back rises above the seat: its top is the top of the model for chairs / sofas
      // (armrests of armchairs are lower than the back).
      EXPECT_GT(bb.max.z(), 0.3) << m.family;
    }
  }
}

TEST(CadLibrary, DisplayScreenFacesPlusX) {
  std::set<std::string> seen;
  for (std::uint64_t s = 0; s < 80; ++s) {
    const CadModel m = GenerateCadModel(kCadDisplay, s);
    seen.insert(m.family);
    const int screen = FindPart(m, "screen");
    ASSERT_EQ(screen, 0) << m.family;
    const AABB sb = PartBounds(m, screen);
    // Thin panel (real thickness < 6 cm, width > 30 cm) in front of everything else.
    EXPECT_LT(sb.Extent().x() * m.nominal_size.x(), 0.061) << m.family;
    EXPECT_GT(sb.Extent().y() * m.nominal_size.y(), 0.3) << m.family;
    EXPECT_NEAR(sb.max.y() - sb.min.y(), 1.0, 1e-9) << m.family;  // screen spans the width
    for (int p = 1; p < m.NumParts(); ++p) {
      EXPECT_LT(PartBounds(m, p).Center().x(), sb.Center().x())
          << m.family << " " << m.part_names[p];
    }
    if (m.family == "wall_tv") {
      EXPECT_LT(m.nominal_size.x(), 0.14);
    }
  }
  EXPECT_EQ(seen.size(), 4u);
}

TEST(CadLibrary, CabinetFrontsAtPlusX) {
  int fronts = 0;
  for (std::uint64_t s = 0; s < 60; ++s) {
    const CadModel m = GenerateCadModel(kCadCabinet, s);
    for (int p = 0; p < m.NumParts(); ++p) {
      if (m.part_names[p] == "door" || m.part_names[p] == "drawer" || m.part_names[p] == "handle") {
        EXPECT_GT(PartBounds(m, p).Center().x(), 0.35) << m.family;
        ++fronts;
      }
    }
    EXPECT_GE(FindPart(m, "handle"), 0) << m.family;
  }
  EXPECT_GT(fronts, 120);
}

TEST(CadLibrary, BookshelfBackPanelAtMinusXAndShelfCountsVary) {
  std::set<int> shelf_counts;
  int closed = 0;
  for (std::uint64_t s = 0; s < 100; ++s) {
    const CadModel m = GenerateCadModel(kCadBookshelf, s);
    int shelves = 0;
    for (int p = 0; p < m.NumParts(); ++p) {
      if (m.part_names[p] == "shelf") ++shelves;
      if (m.part_names[p] == "back") {
        ++closed;
        EXPECT_LT(PartBounds(m, p).max.x(), -0.45);
      }
    }
    shelf_counts.insert(shelves);
    // The open side: a point just inside the front, mid-compartment, at mid-height of the
    // frame is not enclosed by a front panel (nothing covers x = 0.45 across the width).
    if (m.family != "etagere") {
      EXPECT_GE(FindPart(m, "side"), 0);
    }
  }
  EXPECT_GT(closed, 10);
  EXPECT_GE(shelf_counts.size(), 5u);
}

TEST(CadLibrary, ContainersHaveRealCavity) {
  for (int c : {kCadTrashBin, kCadBathtub}) {
    std::set<std::string> fams;
    for (std::uint64_t s = 0; s < 50; ++s) {
      const CadModel m = GenerateCadModel(c, s);
      fams.insert(m.family);
      int body = FindPart(m, "body");
      if (body < 0) body = FindPart(m, "tub");
      ASSERT_GE(body, 0) << m.family;
      const AABB bb = PartBounds(m, body);
      const Vec3 centre = bb.Center();
      // Just below the rim at the centre: empty space (outside every part), and so is the
      // middle of the cavity.
      EXPECT_FALSE(InsideAnyPart(m, Vec3(centre.x(), centre.y(), bb.max.z() - 0.02)))
          << m.family << " seed " << s;
      EXPECT_FALSE(InsideAnyPart(m, centre)) << m.family << " seed " << s;
      // The wall itself is solid: a point half-way through the wall at mid-height (found
      // by marching in from the outside along +x's opposite) is inside the body.
      bool found_wall = false;
      for (double x = bb.max.x(); x > centre.x(); x -= 0.001) {
        if (InsidePart(m, body, Vec3(x, centre.y(), centre.z()))) {
          found_wall = true;
          break;
        }
      }
      EXPECT_TRUE(found_wall) << m.family;
      // The bottom under the cavity is solid.
      EXPECT_TRUE(InsidePart(m, body, Vec3(centre.x(), centre.y(), bb.min.z() + 0.002)))
          << m.family << " seed " << s;
    }
    EXPECT_EQ(fams.size(), CadFamilies(c).size());
  }
}

TEST(CadLibrary, SymmetryFlags) {
  int sym_bins = 0, sym_stools = 0;
  for (std::uint64_t s = 0; s < 100; ++s) {
    const CadModel bin = GenerateCadModel(kCadTrashBin, s);
    if (bin.symmetric_about_z) {
      ++sym_bins;
      EXPECT_TRUE(bin.family == "round_bin" || bin.family == "tapered_bin") << bin.family;
      // A round bin is as wide as it is deep.
      EXPECT_NEAR(bin.nominal_size.x(), bin.nominal_size.y(), 0.02 * bin.nominal_size.x());
    }
    if (bin.family == "round_bin") {  // round and without side handles
      EXPECT_EQ(bin.symmetric_about_z, FindPart(bin, "handle") < 0);
    }
    if (bin.family == "pedal_bin" || bin.family == "square_bin") {
      EXPECT_FALSE(bin.symmetric_about_z);
    }
    const CadModel chair = GenerateCadModel(kCadChair, s);
    if (chair.symmetric_about_z) {
      ++sym_stools;
      EXPECT_EQ(chair.family, "stool");
    }
    EXPECT_FALSE(GenerateCadModel(kCadSofa, s).symmetric_about_z);
  }
  EXPECT_GT(sym_bins, 20);
  EXPECT_GT(sym_stools, 5);
}

TEST(CadLibrary, GenerationSpeed) {
  const auto t0 = std::chrono::steady_clock::now();
  std::size_t faces = 0;
  int n = 0;
  for (int c = 0; c < kNumCadClasses; ++c) {
    for (std::uint64_t s = 0; s < 100; ++s, ++n) faces += GenerateCadModel(c, s).mesh.faces.size();
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ timing ] %d models in %.3f s (%.0f models/s, mean %.0f triangles)\n", n, secs,
              n / secs, static_cast<double>(faces) / n);
  EXPECT_LT(secs, 20.0);
}

}  // namespace
}  // namespace dimr::data
