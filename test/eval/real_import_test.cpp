#include "dimr/eval/real_import.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include "dimr/core/error.h"
#include "dimr/core/labels.h"
#include "dimr/data/scannet_io.h"
#include "npy_bytes.h"

namespace dimr::eval {
namespace {

namespace fs = std::filesystem;

TEST(RealImport, Nyu40NamesReadBackAsTheirRfsClass) {
  EXPECT_STREQ(Nyu40ClassName(1), "wall");
  EXPECT_STREQ(Nyu40ClassName(14), "desk");
  EXPECT_STREQ(Nyu40ClassName(40), "otherprop");
  EXPECT_STREQ(Nyu40ClassName(0), "");
  EXPECT_STREQ(Nyu40ClassName(41), "");
  int with_rfs = 0;
  for (int k = 1; k <= 40; ++k) {
    EXPECT_EQ(data::RfsFromCategory(Nyu40ClassName(k)), data::Nyu40ToRfs(k)) << Nyu40ClassName(k);
    with_rfs += data::Nyu40ToRfs(k) >= 0;
  }
  EXPECT_EQ(with_rfs, 22);  // the NYU40 ids of labels.ply that have an RFS class
}

// 7 vertices: object 1 = wall (2 vertices), object 2 = a chair of 3 vertices one of which is
// labelled cabinet (the majority wins), object 5 = otherprop (no RFS class), one unannotated
// vertex and one labelled table without an object.
struct Arrays {
  NpyArray v{"f4", {7, 6}, {}}, nyu{"u4", {7}, {1, 1, 5, 3, 5, 40, 0}},
      obj{"u4", {7}, {1, 1, 2, 2, 2, 5, 0}};
  Arrays() {
    for (int i = 0; i < 7; ++i) {
      v.values.insert(v.values.end(), {0.5 * i, -0.25 * i, 0.1 * i, 10.0 * i, 20.0, 255.0});
    }
  }
};

TEST(RealImport, ObjectsTakeTheirMajorityClassAndRoundTripAsAScanNetFolder) {
  Arrays a;
  a.nyu.values[6] = 7;  // the object-less vertex is a table point
  const data::SynthScene s = SceneFromLabelledVertices("scene9000_00", a.v, a.nyu, a.obj);
  ASSERT_EQ(s.points.size(), 7u);
  EXPECT_NEAR(s.points[3].x(), 1.5, 1e-12);
  EXPECT_NEAR(s.points[3].y(), -0.75, 1e-12);
  EXPECT_EQ(s.colors[3], geometry::Color(30, 20, 255));
  ASSERT_EQ(s.instances.size(), 3u);
  EXPECT_EQ(s.instances[0].category, "wall");
  EXPECT_EQ(s.instances[1].category, "chair");
  EXPECT_EQ(s.instances[1].cad_class, labels::kCadChair);
  EXPECT_EQ(s.instances[1].num_points, 3);
  EXPECT_EQ(s.instances[2].category, "otherprop");
  EXPECT_EQ(s.instances[2].rfs_class, -1);
  const int I = data::kSemanticIgnore;
  EXPECT_EQ(s.semantic, (std::vector<int>{labels::kWall, labels::kWall, labels::kChair,
                                          labels::kChair, labels::kChair, I, labels::kTable}));
  EXPECT_EQ(s.segment, (std::vector<int>{1, 1, 2, 2, 2, 5, 0}));

  const fs::path dir = fs::path(::testing::TempDir()) / "real_import";
  fs::remove_all(dir);
  data::WriteScanNetScene(dir.string(), s);
  const data::SynthScene back = data::ReadScanNetScene((dir / "scene9000_00").string());
  EXPECT_EQ(back.instance, s.instance);
  // Read back through the aggregation: the object-less table vertex has no label there.
  std::vector<int> want = s.semantic;
  want[6] = I;
  EXPECT_EQ(back.semantic, want);
  ASSERT_EQ(back.instances.size(), 3u);
  EXPECT_EQ(back.instances[1].cad_class, labels::kCadChair);
}

TEST(RealImport, ThreeColumnVerticesAreGrey) {
  Arrays a;
  NpyArray xyz{"f8", {7, 3}, {}};
  for (int i = 0; i < 7; ++i) xyz.values.insert(xyz.values.end(), {1.0 * i, 0.0, 0.0});
  const data::SynthScene s = SceneFromLabelledVertices("s", xyz, a.nyu, a.obj);
  EXPECT_EQ(s.colors[4], geometry::Color(128, 128, 128));
  EXPECT_NEAR(s.points[4].x(), 4.0, 1e-12);
}

// Every malformed input is refused with the array's name in the message.
TEST(RealImport, BadArraysAreRefusedByName) {
  const LabelledVertexSources src{"V.npy", "L.npy", "O.npy"};
  auto expect_error = [&](const Arrays& a, const std::string& file, const std::string& part) {
    try {
      SceneFromLabelledVertices("s", a.v, a.nyu, a.obj, src);
      ADD_FAILURE() << "accepted: " << part;
    } catch (const ParseError& e) {
      EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  {
    Arrays a;
    a.v.shape = {14, 3};  // fine shape, wrong count for the labels
    expect_error(a, "L.npy", "expected 14 NYU40 id");
  }
  {
    Arrays a;
    a.v.shape = {7, 4};
    a.v.values.resize(28);
    expect_error(a, "V.npy", "N x 3");
  }
  {
    Arrays a;
    a.v.values[7] = std::numeric_limits<double>::quiet_NaN();
    expect_error(a, "V.npy", "vertex 1 has a non-finite");
  }
  {
    Arrays a;
    a.v.values[6 * 2 + 4] = 300;
    expect_error(a, "V.npy", "outside [0, 255]");
  }
  {
    Arrays a;
    a.nyu.values[3] = 41;
    expect_error(a, "L.npy", "NYU40 id of vertex 3");
  }
  {
    Arrays a;
    a.obj.values[2] = 1.5;
    expect_error(a, "O.npy", "object id of vertex 2");
  }
  {
    Arrays a;
    a.obj.shape = {7, 2};
    expect_error(a, "O.npy", "shape [7 x 2]");
  }
  {
    Arrays a;
    a.v.shape = {0, 6};
    a.v.values.clear();
    expect_error(a, "V.npy", "no vertices");
  }
}

TEST(RealImport, ReadNpyReadsAFileAndNamesItInErrors) {
  const fs::path dir = fs::path(::testing::TempDir()) / "real_import_npy";
  fs::create_directories(dir);
  // numpy.save(np.array([[1, 2, 3], [4, 5, 6]], dtype="<u4")).
  const std::vector<std::uint32_t> values = {1, 2, 3, 4, 5, 6};
  const std::string bytes = testing::NpyBytes("<u4", {2, 3}, values.data(), 24);
  const fs::path good = dir / "good.npy";
  std::ofstream(good, std::ios::binary) << bytes;
  const NpyArray a = ReadNpy(good.string());
  EXPECT_EQ(a.dtype, "u4");
  EXPECT_EQ(a.shape, (std::vector<std::int64_t>{2, 3}));
  EXPECT_EQ(a.values, (std::vector<double>{1, 2, 3, 4, 5, 6}));
  const fs::path cut = dir / "cut.npy";
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() - 5);
  try {
    ReadNpy(cut.string());
    ADD_FAILURE() << "a truncated array was accepted";
  } catch (const ParseError& e) {
    EXPECT_NE(std::string(e.what()).find("cut.npy"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ReadNpy((dir / "missing.npy").string()), ParseError);
}

}  // namespace
}  // namespace dimr::eval
