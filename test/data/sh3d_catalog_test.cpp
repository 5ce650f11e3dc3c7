// Real-furniture import: zip reader, .properties parser, class map, canonical frame,
// watertightness repair, held-out split, library round trip and room mixing.
#include "dimr/data/sh3d_catalog.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "cli_run.h"
#include "dimr/core/error.h"
#include "dimr/data/labels.h"
#include "dimr/data/real_furniture.h"
#include "dimr/data/room.h"
#include "dimr/geometry/crc32.h"

namespace dimr::data {
namespace {

namespace fs = std::filesystem;
using geometry::Vec3;

// ---------------------------------------------------------------- a hand-made zip (stored)
void Put16(std::vector<std::uint8_t>* b, std::uint32_t v) {
  b->push_back(v & 0xFF);
  b->push_back((v >> 8) & 0xFF);
}
void Put32(std::vector<std::uint8_t>* b, std::uint32_t v) {
  Put16(b, v & 0xFFFF);
  Put16(b, v >> 16);
}
struct ZipFile {
  std::string name, data;
  std::uint16_t method = 0;  // 0 stored; 8 = deflate with `data` as the (raw) stream
  std::uint32_t usize = 0;   // for method 8
  std::uint32_t crc = 0;     // for method 8
};
std::vector<std::uint8_t> MakeZip(const std::vector<ZipFile>& files) {
  std::vector<std::uint8_t> out, cd;
  for (const ZipFile& f : files) {
    const std::uint32_t crc = f.method == 0 ? geometry::Crc32(f.data.data(), f.data.size()) : f.crc;
    const std::uint32_t usize = f.method == 0 ? static_cast<std::uint32_t>(f.data.size()) : f.usize;
    const std::uint32_t off = static_cast<std::uint32_t>(out.size());
    Put32(&out, 0x04034b50);
    Put16(&out, 20);
    Put16(&out, 0);
    Put16(&out, f.method);
    Put32(&out, 0);
    Put32(&out, crc);
    Put32(&out, static_cast<std::uint32_t>(f.data.size()));
    Put32(&out, usize);
    Put16(&out, static_cast<std::uint32_t>(f.name.size()));
    Put16(&out, 0);
    out.insert(out.end(), f.name.begin(), f.name.end());
    out.insert(out.end(), f.data.begin(), f.data.end());
    Put32(&cd, 0x02014b50);
    Put16(&cd, 20);
    Put16(&cd, 20);
    Put16(&cd, 0);
    Put16(&cd, f.method);
    Put32(&cd, 0);
    Put32(&cd, crc);
    Put32(&cd, static_cast<std::uint32_t>(f.data.size()));
    Put32(&cd, usize);
    Put16(&cd, static_cast<std::uint32_t>(f.name.size()));
    Put16(&cd, 0);
    Put16(&cd, 0);
    Put16(&cd, 0);
    Put16(&cd, 0);
    Put32(&cd, 0);
    Put32(&cd, off);
    cd.insert(cd.end(), f.name.begin(), f.name.end());
  }
  const std::uint32_t cd_off = static_cast<std::uint32_t>(out.size());
  out.insert(out.end(), cd.begin(), cd.end());
  Put32(&out, 0x06054b50);
  Put16(&out, 0);
  Put16(&out, 0);
  Put16(&out, static_cast<std::uint32_t>(files.size()));
  Put16(&out, static_cast<std::uint32_t>(files.size()));
  Put32(&out, static_cast<std::uint32_t>(cd.size()));
  Put32(&out, cd_off);
  Put16(&out, 0);
  return out;
}

// An asymmetric box OBJ: x in [0, 2], y in [0, 1], z in [0, 3] (Sweet Home 3D units).
std::string BoxObj() {
  std::string s = "mtllib box.mtl\nusemtl red\n";
  for (int i = 0; i < 8; ++i) {
    s += "v " + std::to_string((i & 1) ? 2 : 0) + " " + std::to_string((i & 2) ? 1 : 0) + " " +
         std::to_string((i & 4) ? 3 : 0) + "\n";
  }
  // Outward faces (1-based), quads.
  s += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\nf 1 2\n";
  return s;
}

Sh3dEntry BoxEntry() {
  Sh3dEntry e;
  e.catalog = "test";
  e.index = 1;
  e.id = "test#box";
  e.name = "Chair";
  e.category = "Living room";
  e.model_path = "/m/box.obj";
  e.width_cm = 40;
  e.depth_cm = 50;
  e.height_cm = 90;
  return e;
}

// ---------------------------------------------------------------- properties
TEST(JavaProperties, EscapesContinuationsAndSeparators) {
  const std::string text =
      "# comment\r\n"
      "! also a comment\n"
      "name#1=Bill 10\\u20ac\n"
      "  key2 : spaced value  \n"
      "key3 plain words\n"
      "multi=first \\\n"
      "      second \\\n"
      "   third\n"
      "esc\\=key=a\\tb\\\\c\n"
      "latin=caf\xe9\n"
      "pair=\\ud83d\\ude00\n"
      "trailing=ends with even \\\\\n"
      "next=after\n"
      "empty=\n"
      "name#1=replaced later? no: same key twice keeps the last\n";
  const auto p = ParseJavaProperties(text, "mem");
  EXPECT_EQ(p.at("name#1"), "replaced later? no: same key twice keeps the last");
  EXPECT_EQ(p.at("key2"), "spaced value  ");
  EXPECT_EQ(p.at("key3"), "plain words");
  EXPECT_EQ(p.at("multi"), "first second third");
  EXPECT_EQ(p.at("esc=key"), "a\tb\\c");
  EXPECT_EQ(p.at("latin"), "caf\xc3\xa9");           // ISO 8859-1 -> UTF-8
  EXPECT_EQ(p.at("pair"), "\xf0\x9f\x98\x80");       // surrogate pair joined
  EXPECT_EQ(p.at("trailing"), "ends with even \\");  // even backslashes: no continuation
  EXPECT_EQ(p.at("next"), "after");
  EXPECT_EQ(p.at("empty"), "");
  EXPECT_EQ(p.count("#"), 0u);
  const auto euro = ParseJavaProperties("a=10\\u20AC", "mem");
  EXPECT_EQ(euro.at("a"), "10\xe2\x82\xac");
}

TEST(JavaProperties, BadUnicodeEscapeNamesSourceAndLine) {
  try {
    ParseJavaProperties("ok=1\nbad=x\\u12G4\n", "cat.properties");
    FAIL() << "no error";
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("cat.properties:2"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ParseJavaProperties("bad=\\u12", "x"), ParseError);
}

TEST(Sh3dCatalog, EntriesSizesAndRotation) {
  const auto props = ParseJavaProperties(
      "license=CC-BY\nname=Cat\n"
      "id#2=c#two\nname#2=Sofa\ncategory#2=Living room\nmodel#2=/a/s.obj\nwidth#2=200\n"
      "depth#2=90.5\nheight#2=80\nmodelRotation#2=1 0 0 0 0 1 0 -1 0\ncreator#2=Someone\n"
      "id#1=c#one\nname#1=Chair\nmodel#1=/a/c.obj\nwidth#1=40\ndepth#1=45\nheight#1=90\n"
      "license#1=CC0\n"
      "name#3=no model\n",
      "mem");
  const auto entries = ParseSh3dCatalog(props, "Cat", "mem");
  ASSERT_EQ(entries.size(), 2u);
  EXPECT_EQ(entries[0].index, 1);
  EXPECT_EQ(entries[0].license, "CC0");
  EXPECT_EQ(entries[1].license, "CC-BY");  // the catalogue's
  EXPECT_DOUBLE_EQ(entries[1].depth_cm, 90.5);
  EXPECT_TRUE(entries[1].has_rotation);
  EXPECT_EQ(entries[1].model_rotation(1, 2), 1.0);  // row-major
  EXPECT_EQ(entries[1].model_rotation(2, 1), -1.0);
  EXPECT_EQ(entries[1].creator, "Someone");
  const auto bad =
      ParseJavaProperties("name#1=x\nmodel#1=/m.obj\nwidth#1=-3\ndepth#1=1\nheight#1=1\n", "m");
  try {
    ParseSh3dCatalog(bad, "Cat", "cat.properties");
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("width#1"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------- class map
TEST(Sh3dClassMap, RulesOnNames) {
  struct Case {
    const char *name, *category, *label;
    int cad;
  };
  const Case cases[] = {
      {"Armchair", "Office", "chair", kCadChair},
      {"Bar stool", "Living room", "chair", kCadChair},
      {"Corner bathtub", "Bathroom", "bathtub", kCadBathtub},
      {"Bathmat", "Bathroom", "", -1},
      {"Dustbin", "Office", "trash_bin", kCadTrashBin},
      {"Bullet trash can", "Kitchen", "trash_bin", kCadTrashBin},
      {"Wall flat TV", "Living room", "wall_display", kCadDisplay},
      {"Apple iMac 2004", "Office", "display", kCadDisplay},
      {"TV remote control", "Living room", "", -1},
      {"Television cabinet", "Living room", "cabinet", kCadCabinet},
      {"Corner sofa", "Living room", "sofa", kCadSofa},
      {"Convertible sofa BZ", "Bedroom", "sofa", kCadSofa},
      {"Wooden desk", "Office", "desk", kCadTable},
      {"Desk lamp", "Lights", "table_lamp", -1},
      {"Coffee table", "Living room", "table", kCadTable},
      {"Table tennis", "Miscellaneous", "", -1},
      {"Bookcase", "Office", "bookshelf", kCadBookshelf},
      {"Wardrobe", "Bedroom", "cabinet", kCadCabinet},
      {"Large fridge", "Kitchen", "fridge", kCadCabinet},
      {"Lower cabinet", "Kitchen", "kitchen_cabinet", -1},
      {"Bedside table", "Bedroom", "nightstand", -1},
      {"Bunk bed", "Bedroom", "bed", -1},
      {"Toilets unit", "Bathroom", "toilet", -1},
      {"Toilet brush", "Bathroom", "", -1},
      {"Washbasin", "Bathroom", "sink", -1},
      {"Door", "Doors and windows", "door", -1},
      {"Double-hung window", "Doors and windows", "window", -1},
      {"Park trashcan", "Exterior", "trash_bin", kCadTrashBin},
      {"Cafe chair", "Exterior", "chair", kCadChair},
      {"Palm tree", "Exterior", "", -1},
      {"Bench", "Exterior", "", -1},
      {"Ficus", "Living room", "plant", -1},
      {"Screen", "Miscellaneous", "", -1},
      {"Opened convertible sofa BZ", "Bedroom", "bed", -1},
  };
  for (const Case& c : cases) {
    const Sh3dClass k = ClassifySh3dEntry(c.name, c.category);
    EXPECT_EQ(k.label, c.label) << c.name;
    EXPECT_EQ(k.cad_class, c.cad) << c.name;
    if (c.cad >= 0) {
      EXPECT_EQ(RfsToCad(k.rfs_class), c.cad) << c.name;
    }
  }
  EXPECT_EQ(ClassifySh3dEntry("Wooden desk", "Office").rfs_class, kDesk);
  EXPECT_EQ(ClassifySh3dEntry("Toilets unit", "Bathroom").rfs_class, kToilet);
  EXPECT_EQ(ClassifySh3dEntry("Bunk bed", "Bedroom").rfs_class, kBed);
  EXPECT_EQ(GetDistractorInfo(ClassifySh3dEntry("Bunk bed", "Bedroom").distractor_kind).rfs_class,
            kBed);
}

// ---------------------------------------------------------------- zip + model loading
TEST(ZipArchive, StoredEntriesAndCorruption) {
  const auto bytes = MakeZip({{"a/one.txt", "hello"}, {"b.txt", std::string(300, 'x')}});
  const ZipArchive z = ZipArchive::FromBytes(bytes, "mem.zip");
  EXPECT_EQ(z.Names(), (std::vector<std::string>{"a/one.txt", "b.txt"}));
  const auto one = z.Read("/A/ONE.TXT");  // leading '/' and case ignored
  EXPECT_EQ(std::string(one.begin(), one.end()), "hello");
  try {
    z.Read("missing.obj");
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("mem.zip:missing.obj"), std::string::npos) << e.what();
  }
  // A flipped data byte: CRC mismatch naming archive and entry.
  auto bad = bytes;
  bad[30 + 9 + 1] ^= 0x20;
  try {
    ZipArchive::FromBytes(bad, "bad.zip").Read("a/one.txt");
    FAIL();
  } catch (const ParseError& e) {
    const std::string w = e.what();
    EXPECT_NE(w.find("bad.zip:a/one.txt"), std::string::npos) << w;
    EXPECT_NE(w.find("CRC"), std::string::npos) << w;
  }
  // A deflate entry with garbage data.
  const auto garbage = MakeZip({{"m.obj", std::string("\xff\xff\xff\xff\x00\x01", 6), 8, 100, 0}});
  try {
    ZipArchive::FromBytes(garbage, "g.sh3f").Read("m.obj");
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("g.sh3f:m.obj"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("deflate"), std::string::npos) << e.what();
  }
  // A size claim deflate cannot reach is refused before allocating.
  const auto bomb = MakeZip({{"m.obj", std::string("\x03\x00", 2), 8, 1u << 30, 0}});
  try {
    ZipArchive::FromBytes(bomb, "b.sh3f").Read("m.obj");
    FAIL();
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("impossible"), std::string::npos) << e.what();
  }
  // Truncated / not a zip / directory out of range.
  EXPECT_THROW(ZipArchive::FromBytes({1, 2, 3}, "t.zip"), ParseError);
  std::vector<std::uint8_t> cut(bytes.begin(), bytes.begin() + bytes.size() / 2);
  EXPECT_THROW(ZipArchive::FromBytes(cut, "t.zip"), ParseError);
  auto moved = bytes;
  moved[moved.size() - 3] = 0x7F;  // central directory offset beyond the file
  EXPECT_THROW(ZipArchive::FromBytes(moved, "t.zip"), ParseError);
  EXPECT_THROW(ZipArchive::Open("/nonexistent/x.sh3f"), ParseError);
}

TEST(Sh3dModel, CanonicalFrameAndColours) {
  const auto zip = ZipArchive::FromBytes(
      MakeZip({{"m/box.obj", BoxObj()}, {"m/box.mtl", "newmtl red\nKd 1 0 0\n"}}), "box.sh3f");
  Sh3dEntry e = BoxEntry();
  const Sh3dClass cls = ClassifySh3dEntry(e.name, e.category);
  Sh3dLoadStats st;
  const CadModel m = LoadSh3dModel(zip, e, cls, &st);
  EXPECT_EQ(m.cad_class, kCadChair);
  EXPECT_EQ(m.synset, CadSynsets()[kCadChair]);
  ASSERT_EQ(m.mesh.vertices.size(), 8u);
  EXPECT_EQ(m.mesh.faces.size(), 12u);  // 6 quads; the 2-corner face line is skipped
  EXPECT_EQ(st.boundary_edges, 0);
  EXPECT_NEAR(m.mesh.SignedVolume(), 1.0, 1e-12);  // unit box, orientation kept
  const geometry::AABB b = m.mesh.Bounds();
  EXPECT_EQ(b.min, Vec3::Constant(-0.5));
  EXPECT_EQ(b.max, Vec3::Constant(0.5));
  // Catalogue size -> nominal (depth, width, height) in metres.
  EXPECT_EQ(m.nominal_size, Vec3(0.5, 0.4, 0.9));
  // (x, y, z)_canonical = (z, x, y)_sh3d: the OBJ corner (2, 0, 0) -> (-0.5, +0.5, -0.5),
  // (0, 1, 3) -> (+0.5, -0.5, +0.5).
  auto has = [&](const Vec3& p) {
    return std::any_of(m.mesh.vertices.begin(), m.mesh.vertices.end(),
                       [&](const Vec3& v) { return (v - p).norm() < 1e-12; });
  };
  EXPECT_TRUE(has(Vec3(-0.5, 0.5, -0.5)));
  EXPECT_TRUE(has(Vec3(0.5, -0.5, 0.5)));
  ASSERT_EQ(m.mesh.vertex_colors.size(), 8u);
  EXPECT_EQ(m.mesh.vertex_colors[0][0], 255);
  EXPECT_EQ(m.mesh.vertex_colors[0][1], 0);
  // A model rotation of 90 degrees about y (x -> -z): OBJ x now runs along -z_sh3d = -x_canon.
  e.has_rotation = true;
  e.model_rotation << 0, 0, 1, 0, 1, 0, -1, 0, 0;
  const CadModel r = LoadSh3dModel(zip, e, cls);
  // OBJ corner (2, 0, 0) -> sh3d (0, 0, -2) -> canonical (-2, 0, 0) -> the -x face.
  // OBJ corner (0, 1, 3) -> (3, 1, 0) -> canonical (0, 3, 1): +y, +z, +x side.
  EXPECT_NEAR(r.mesh.SignedVolume(), 1.0, 1e-12);
  auto rhas = [&](const Vec3& p) {
    return std::any_of(r.mesh.vertices.begin(), r.mesh.vertices.end(),
                       [&](const Vec3& v) { return (v - p).norm() < 1e-12; });
  };
  EXPECT_TRUE(rhas(Vec3(-0.5, -0.5, -0.5)));  // from (2, 0, 0)
  EXPECT_TRUE(rhas(Vec3(0.5, 0.5, 0.5)));     // from (0, 1, 3)
  // Determinism: the same bytes twice.
  const CadModel again = LoadSh3dModel(zip, e, cls);
  EXPECT_EQ(again.mesh.vertices, r.mesh.vertices);
  EXPECT_EQ(again.mesh.faces, r.mesh.faces);
  EXPECT_EQ(again.model_id, r.model_id);
  // A broken OBJ names archive and entry.
  const auto broken =
      ZipArchive::FromBytes(MakeZip({{"m/box.obj", "v 0 0 0\nf 1 2 3\n"}}), "b.sh3f");
  try {
    LoadSh3dModel(broken, e, cls);
    FAIL();
  } catch (const ParseError& ex) {
    EXPECT_NE(std::string(ex.what()).find("b.sh3f:m/box.obj"), std::string::npos) << ex.what();
  }
}

// ---------------------------------------------------------------- watertightness
// Box [-0.4, 0.4]^3 whose top face has a slit of `gap` (unit-box units) across it.
geometry::TriangleMesh SlitBox(double gap) {
  geometry::TriangleMesh m;
  auto quad = [&](Vec3 a, Vec3 b, Vec3 c, Vec3 d) {
    const int i = static_cast<int>(m.vertices.size());
    m.vertices.insert(m.vertices.end(), {a, b, c, d});
    m.faces.emplace_back(i, i + 1, i + 2);
    m.faces.emplace_back(i, i + 2, i + 3);
  };
  const double s = 0.4;
  quad({-s, -s, -s}, {-s, s, -s}, {s, s, -s}, {s, -s, -s});  // bottom
  quad({-s, -s, -s}, {s, -s, -s}, {s, -s, s}, {-s, -s, s});
  quad({-s, s, -s}, {-s, s, s}, {s, s, s}, {s, s, -s});
  quad({-s, -s, -s}, {-s, -s, s}, {-s, s, s}, {-s, s, -s});
  quad({s, -s, -s}, {s, s, -s}, {s, s, s}, {s, -s, s});
  const double g = gap / 2;
  quad({-s, -s, s}, {-g, -s, s}, {-g, s, s}, {-s, s, s});  // top, two halves
  quad({g, -s, s}, {s, -s, s}, {s, s, s}, {g, s, s});
  return m;
}

TEST(Watertight, ClosingFillsSmallHolesAndMeshIsClosed) {
  const int res = 32;
  const double cell = 1.0 / res;
  // Closed box: ~0.8^3 of the unit box is solid with or without closing.
  const auto closed = ClosedOccupancy(SlitBox(0.0), res, 1);
  const double full = closed.Count() * std::pow(cell, 3);
  EXPECT_NEAR(full, 0.512, 0.08);
  // A slit of 3.2 cells: the plain flood fill leaks into the box (only the shell is solid),
  // a closing of 2 cells repairs it.
  geometry::VoxelGrid open;
  open.voxel_size = cell;
  open.origin = Vec3::Constant(-0.5 - cell);
  open.dims = geometry::Vec3i::Constant(res + 2);
  open.occupied.assign(static_cast<std::size_t>(res + 2) * (res + 2) * (res + 2), 0);
  geometry::VoxelizeFilled(SlitBox(3.2 * cell), &open);
  const double leaky = open.Count() * std::pow(cell, 3);
  EXPECT_LT(leaky, 0.3 * full);
  const auto repaired = ClosedOccupancy(SlitBox(3.2 * cell), res, 2);
  EXPECT_NEAR(repaired.Count() * std::pow(cell, 3), full, 0.03);
  // A wide opening (a third of the top) stays open: a cup is not filled.
  const auto cup = ClosedOccupancy(SlitBox(0.3), res, 2);
  EXPECT_LT(cup.Count() * std::pow(cell, 3), 0.4 * full);
  // The voxel mesh is closed and outward-oriented with the cells' volume.
  const geometry::TriangleMesh vm = OccupancyToMesh(repaired);
  std::map<std::pair<int, int>, int> directed;
  for (const auto& f : vm.faces)
    for (int k = 0; k < 3; ++k) ++directed[{f[k], f[(k + 1) % 3]}];
  for (const auto& [e, n] : directed) {
    auto it = directed.find({e.second, e.first});
    ASSERT_NE(it, directed.end());
    EXPECT_EQ(it->second, n);
  }
  EXPECT_NEAR(vm.SignedVolume(), repaired.Count() * std::pow(cell, 3), 1e-9);
  EXPECT_THROW(ClosedOccupancy(SlitBox(0), 2, 0), InvalidArgument);
}

// ---------------------------------------------------------------- split + ids
TEST(Sh3dSplit, FixedAndAboutOneFifth) {
  int held = 0;
  std::set<std::string> ids;
  for (int i = 0; i < 2000; ++i) {
    Sh3dEntry e = BoxEntry();
    e.id = "x#" + std::to_string(i);
    const std::string id = Sh3dModelId(e);
    EXPECT_EQ(id.size(), 32u);
    ids.insert(id);
    held += IsHeldOutModel(id);
  }
  EXPECT_EQ(ids.size(), 2000u);
  EXPECT_GT(held, 320);
  EXPECT_LT(held, 480);
  Sh3dEntry e = BoxEntry();
  EXPECT_EQ(Sh3dModelId(e), Sh3dModelId(BoxEntry()));
}

// ---------------------------------------------------------------- library + mixing
TEST(RealFurniture, WriteLoadAndMixIntoRooms) {
  const auto zip = ZipArchive::FromBytes(
      MakeZip({{"m/box.obj", BoxObj()}, {"m/box.mtl", "newmtl red\nKd 1 0 0\n"}}), "box.sh3f");
  std::vector<ImportedModel> models;
  for (int i = 0; i < 12; ++i) {
    ImportedModel im;
    im.entry = BoxEntry();
    im.entry.id = "box#" + std::to_string(i);
    im.entry.creator = "Creator" + std::to_string(i);
    im.entry.license = "CC0";
    im.entry.name = i % 2 ? "Chair" : "Bed";
    im.cls = ClassifySh3dEntry(im.entry.name, "Bedroom");
    im.model = LoadSh3dModel(zip, im.entry, im.cls);
    im.held_out = IsHeldOutModel(im.model.model_id);
    im.mean_color = Vec3(1, 0, 0);
    im.model.mesh.vertex_colors[3] = geometry::Color(0, 0, 255);  // a per-vertex pattern
    models.push_back(std::move(im));
  }
  const fs::path dir = testing::FreshTempDir("real_furniture");
  WriteRealFurniture(dir.string(), models);
  const std::string attribution = testing::ReadFileText(dir / "ATTRIBUTION.md");
  EXPECT_NE(attribution.find("Creator7"), std::string::npos);
  EXPECT_NE(attribution.find("CC0"), std::string::npos);
  int train_chairs = 0, train_beds = 0;
  for (const auto& im : models) {
    if (im.held_out) continue;
    (im.cls.cad_class >= 0 ? train_chairs : train_beds) += 1;
  }
  const auto lib = std::make_shared<RealFurnitureLibrary>(LoadRealFurniture(dir.string(), "train"));
  EXPECT_EQ(static_cast<int>(lib->cad[kCadChair].size()), train_chairs);
  const int bed_kind = ClassifySh3dEntry("Bed", "Bedroom").distractor_kind;
  EXPECT_EQ(static_cast<int>(lib->distractors[bed_kind].size()), train_beds);
  ASSERT_GT(train_chairs, 0);
  const CadModel& c0 = lib->cad[kCadChair][0];
  EXPECT_EQ(c0.mesh.Bounds().max, Vec3::Constant(0.5));
  ASSERT_EQ(c0.mesh.vertex_colors.size(), c0.mesh.vertices.size());
  EXPECT_EQ(c0.mesh.vertex_colors[0][0], 255);  // per-vertex colours, same vertex order
  const auto src = std::find_if(models.begin(), models.end(), [&](const ImportedModel& im) {
    return im.model.model_id == c0.model_id;
  });
  ASSERT_NE(src, models.end());
  EXPECT_EQ(c0.mesh.vertex_colors, src->model.mesh.vertex_colors);
  EXPECT_EQ(c0.mesh.vertex_colors[3], geometry::Color(0, 0, 255));
  EXPECT_THROW(LoadRealFurniture((dir / "nope").string(), "train"), ParseError);
  EXPECT_THROW(LoadRealFurniture(dir.string(), "val"), InvalidArgument);

  // Mixing: fraction 0 = the procedural rooms exactly; fraction 1 = every chair is real.
  EXPECT_THROW(MixedModelSource(lib, 1.5), InvalidArgument);
  RoomConfig cfg;
  const Room base = ComposeRoom(cfg, 11);
  const Room zero = ComposeRoom(cfg, 11, MixedModelSource(lib, 0.0));
  ASSERT_EQ(base.objects.size(), zero.objects.size());
  for (std::size_t i = 0; i < base.objects.size(); ++i) {
    EXPECT_EQ(base.objects[i].model_id, zero.objects[i].model_id);
    EXPECT_EQ(base.objects[i].translation, zero.objects[i].translation);
  }
  int real = 0, chairs = 0;
  for (std::uint64_t seed = 0; seed < 6; ++seed) {
    const Room r = ComposeRoom(cfg, seed, MixedModelSource(lib, 1.0));
    for (const auto& o : r.objects) {
      if (o.cad_class != kCadChair) continue;
      ++chairs;
      if (o.family == "sh3d_chair") {
        ++real;
        // The model's own colour: 7 red and 1 blue vertex -> albedo (7/8, 0, 1/8); the placed
        // mesh keeps the vertex colours.
        EXPECT_NEAR(o.material.albedo.x(), 7.0 / 8, 1e-9);
        EXPECT_NEAR(o.material.albedo.y(), 0.0, 1e-9);
        EXPECT_NEAR(o.material.albedo.z(), 1.0 / 8, 1e-9);
        EXPECT_EQ(o.mesh.vertex_colors.size(), o.mesh.vertices.size());
      }
    }
  }
  EXPECT_GT(chairs, 0);
  EXPECT_EQ(real, chairs);
}

// ---------------------------------------------------------------- the CLI
TEST(Sh3dCli, ImportIsDeterministicAndWritesAttribution) {
  const std::string props =
      "name=Test catalogue\nlicense=CC-BY 3.0\nprovider=tests\n"
      "id#1=t#chair\nname#1=Chair\ncategory#1=Living room\nmodel#1=/m/box.obj\nwidth#1=40\n"
      "depth#1=50\nheight#1=90\ncreator#1=Alice\n"
      "id#2=t#bed\nname#2=Bed\ncategory#2=Bedroom\nmodel#2=/m/box.obj\nwidth#2=140\n"
      "depth#2=200\nheight#2=60\ncreator#2=Bob\n"
      "id#3=t#car\nname#3=Car\ncategory#3=Vehicles\nmodel#3=/m/box.obj\nwidth#3=1\ndepth#3=1\n"
      "height#3=1\n"
      "id#4=t#broken\nname#4=Table\ncategory#4=Office\nmodel#4=/m/missing.obj\nwidth#4=100\n"
      "depth#4=60\nheight#4=75\n";
  const auto zip = MakeZip({{"PluginFurnitureCatalog.properties", props},
                            {"m/box.obj", BoxObj()},
                            {"m/box.mtl", "newmtl red\nKd 1 0 0\n"}});
  const fs::path dir = testing::FreshTempDir("sh3d_cli");
  {
    std::ofstream f(dir / "Test.sh3f", std::ios::binary);
    f.write(reinterpret_cast<const char*>(zip.data()), static_cast<std::streamsize>(zip.size()));
  }
  std::string first;
  for (int run = 0; run < 2; ++run) {
    const std::string out = (dir / ("out" + std::to_string(run))).string();
    auto [rc, text] = testing::RunCli("cad import --dir " + dir.string() + " --out " + out +
                                      " --watertight-res 16");
    ASSERT_EQ(rc, 0) << text;
    EXPECT_NE(text.find("imported 2 models"), std::string::npos) << text;
    EXPECT_NE(text.find("1 skipped"), std::string::npos) << text;  // the missing OBJ
    EXPECT_NE(text.find("Test.sh3f:m/missing.obj"), std::string::npos) << text;
    const std::string cat = testing::ReadFileText(fs::path(out) / "catalog.json");
    EXPECT_NE(cat.find("\"rule\": \"chair\""), std::string::npos);
    EXPECT_NE(cat.find("\"rule\": \"bed\""), std::string::npos);
    const std::string att = testing::ReadFileText(fs::path(out) / "ATTRIBUTION.md");
    EXPECT_NE(att.find("Alice"), std::string::npos);
    EXPECT_NE(att.find("CC-BY 3.0"), std::string::npos);
    if (run == 0) {
      first = cat;
    } else {
      EXPECT_EQ(cat, first);  // deterministic bytes
    }
  }
  // A corrupt catalogue: a clear error naming the file, exit code != 0.
  {
    std::ofstream f(dir / "Bad.sh3f", std::ios::binary);
    f << "not a zip at all, just text";
  }
  auto [rc, text] = testing::RunCli("cad import --catalog " + (dir / "Bad.sh3f").string() +
                                    " --out " + (dir / "bad").string());
  EXPECT_NE(rc, 0);
  EXPECT_NE(text.find("Bad.sh3f"), std::string::npos) << text;
}

// ---------------------------------------------------------------- the installed catalogues
TEST(Sh3dInstalled, ClassMapFrameAndCounts) {
  const std::string dir = DefaultSh3dFurnitureDir();
  if (!fs::exists(dir)) GTEST_SKIP() << "sweethome3d-furniture is not installed (scripts/setup.sh)";
  const auto files = ListSh3dCatalogs(dir);
  ASSERT_EQ(files.size(), 5u);
  // Class map on real entries of BlendSwap-CC-0.
  const ZipArchive z = ZipArchive::Open(files[0]);
  const auto bytes = z.Read("PluginFurnitureCatalog.properties");
  const auto entries = ParseSh3dCatalog(
      ParseJavaProperties(std::string(bytes.begin(), bytes.end()), "p"), "BlendSwap-CC-0", "p");
  std::map<std::string, const Sh3dEntry*> by_id;
  for (const auto& e : entries) by_id[e.id] = &e;
  ASSERT_TRUE(by_id.count("Blend Swap CC-0#armchair"));
  const Sh3dEntry& arm = *by_id["Blend Swap CC-0#armchair"];
  EXPECT_EQ(arm.name, "Armchair");
  EXPECT_DOUBLE_EQ(arm.width_cm, 59.4);
  const Sh3dClass cls = ClassifySh3dEntry(arm.name, arm.category);
  EXPECT_EQ(cls.cad_class, kCadChair);
  EXPECT_EQ(ClassifySh3dEntry(by_id.at("Blend Swap CC-0#bed1")->name, "Bedroom").label, "bed");
  // The armchair in the canonical frame: catalogue extents, backrest at -x (the top of the
  // model lies behind its centre), seat front at +x.
  const CadModel m = LoadSh3dModel(z, arm, cls);
  EXPECT_EQ(m.mesh.Bounds().min, Vec3::Constant(-0.5));
  EXPECT_EQ(m.mesh.Bounds().max, Vec3::Constant(0.5));
  const Vec3 ext = m.mesh.Bounds().Extent().cwiseProduct(m.nominal_size);
  EXPECT_NEAR(ext.x(), 0.627, 1e-9);
  EXPECT_NEAR(ext.y(), 0.594, 1e-9);
  EXPECT_NEAR(ext.z(), 1.05, 1e-9);
  double top_x = 0;
  int top_n = 0;
  for (const Vec3& v : m.mesh.vertices) {
    if (v.z() > 0.35) {
      top_x += v.x();
      ++top_n;
    }
  }
  ASSERT_GT(top_n, 10);
  EXPECT_LT(top_x / top_n, -0.1) << "backrest should be at -x";
  // Whole import: enough models per class, ~20 % held out, every CAD class present.
  ImportOptions opt;
  opt.watertight_res = 0;
  opt.include_distractors = false;
  std::vector<std::string> errors;
  const auto all = ImportSh3dCatalogs(files, opt, &errors);
  std::map<int, int> per_class;
  int held = 0, cad = 0;
  for (const auto& im : all) {
    if (im.model.cad_class >= 0) {
      ++per_class[im.model.cad_class];
      ++cad;
      held += im.held_out;
    }
  }
  EXPECT_GE(cad, 140);
  for (int c = 0; c < kNumCadClasses; ++c) EXPECT_GE(per_class[c], 3) << CadClassNames()[c];
  EXPECT_GT(held, cad / 10);
  EXPECT_LT(held, cad * 3 / 10);
  EXPECT_LT(errors.size(), 5u);
}

}  // namespace
}  // namespace dimr::data
