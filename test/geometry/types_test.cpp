#include "dimr/geometry/types.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "dimr/geometry/error.h"
#include "geometry/test_meshes.h"

namespace dimr::geometry {
namespace {

using testing::UnitCube;

TEST(TriangleMesh, CubeAreaAndVolume) {
  TriangleMesh m = UnitCube();
  EXPECT_NEAR(m.SurfaceArea(), 6.0, 1e-12);
  EXPECT_NEAR(m.SignedVolume(), 1.0, 1e-12);
  Eigen::Matrix3d S = Eigen::Vector3d(2, 3, 0.5).asDiagonal();
  m.Transform(S, Vec3(5, -1, 2));
  EXPECT_NEAR(m.SignedVolume(), 3.0, 1e-12);
  EXPECT_NEAR(m.SurfaceArea(), 2 * (6 + 1 + 1.5), 1e-12);
  const AABB b = m.Bounds();
  EXPECT_NEAR(b.min.x(), 5, 1e-12);
  EXPECT_NEAR(b.max.y(), 2, 1e-12);
  EXPECT_NEAR(b.Volume(), 3.0, 1e-12);
}

TEST(PointCloud, TransformMovesPointsAndTurnsNormals) {
  PointCloud c;
  c.points = {Vec3(1, 0, 0), Vec3(0, 2, 3)};
  c.normals = {Vec3(0, 0, 1), Vec3(1, 0, 0)};
  c.colors = {Color(1, 2, 3), Color(4, 5, 6)};
  const Eigen::Matrix3d r = Eigen::AngleAxisd(M_PI / 2, Vec3::UnitX()).toRotationMatrix();
  c.Transform(r, Vec3(0, 0, 10));
  EXPECT_TRUE(c.points[0].isApprox(Vec3(1, 0, 10)));
  EXPECT_TRUE(c.points[1].isApprox(Vec3(0, -3, 12)));
  EXPECT_TRUE(c.normals[0].isApprox(Vec3(0, -1, 0)));  // no translation on normals
  EXPECT_TRUE(c.normals[1].isApprox(Vec3(1, 0, 0)));
  EXPECT_EQ(c.colors[1], Color(4, 5, 6));
  c.Transform(r.transpose(), Vec3::Zero());
  EXPECT_TRUE(c.points[0].isApprox(Vec3(1, 10, 0)));
}

TEST(TriangleMesh, AppendOffsetsIndices) {
  TriangleMesh a = UnitCube(), b = UnitCube();
  b.Transform(Eigen::Matrix3d::Identity(), Vec3(3, 0, 0));
  a.Append(b);
  EXPECT_EQ(a.vertices.size(), 16u);
  EXPECT_EQ(a.faces.size(), 24u);
  EXPECT_NEAR(a.SignedVolume(), 2.0, 1e-12);
  EXPECT_NO_THROW(a.Validate("appended"));
}

TEST(TriangleMesh, ValidateNamesTheProblem) {
  TriangleMesh m = UnitCube();
  m.faces.emplace_back(0, 1, 8);
  try {
    m.Validate("cube.ply");
    FAIL() << "expected an error";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("cube.ply: face 12 references vertex 8 of 8"),
              std::string::npos)
        << e.what();
  }
  m = UnitCube();
  m.vertices[3].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(m.Validate("nan"), InvalidArgument);
}

TEST(PointCloud, AttributesMustMatchSize) {
  PointCloud c;
  c.points = {Vec3(0, 0, 0), Vec3(1, 2, 3)};
  c.SetAttribute("label", ScalarType::kUInt16, {3, 4});
  ASSERT_NE(c.FindAttribute("label"), nullptr);
  EXPECT_EQ(c.FindAttribute("label")->values[1], 4);
  EXPECT_THROW(c.SetAttribute("bad", ScalarType::kInt32, {1}), InvalidArgument);
  c.normals.push_back(Vec3::UnitZ());
  EXPECT_THROW(c.Validate("cloud"), InvalidArgument);
  EXPECT_EQ(ScalarSize(ScalarType::kFloat64), 8);
  EXPECT_STREQ(ScalarName(ScalarType::kUInt16), "ushort");
}

}  // namespace
}  // namespace dimr::geometry
