// Marker deltas: ADD only for new / changed instances, DELETE for vanished ids, DELETEALL after
// Reset(), a full snapshot for late subscribers, stable ids, never an empty TRIANGLE_LIST.
#include "dimr/ros/marker_builder.h"

#include <gtest/gtest.h>

#include <set>

#include "dimr/geometry/error.h"

namespace dimr::ros1 {
namespace {

using visualization_msgs::Marker;

InstanceMesh Inst(std::uint32_t id, std::uint32_t rev, int tris = 2) {
  InstanceMesh m;
  m.id = id;
  m.revision = rev;
  m.class_id = 1;
  m.class_name = "chair";
  m.score = 0.9f;
  m.pose.position.x = id;
  m.pose.orientation.w = 1;
  m.bbox_size.x = 0.5;
  m.bbox_size.y = 0.5;
  m.bbox_size.z = 1.0;
  for (int v = 0; v < 4; ++v) {
    geometry_msgs::Point p;
    p.x = v & 1;
    p.y = (v >> 1) & 1;
    m.mesh.vertices.push_back(p);
  }
  for (int t = 0; t < tris; ++t) {
    shape_msgs::MeshTriangle tri;
    tri.vertex_indices = {0, 1, static_cast<std::uint32_t>(2 + t % 2)};
    m.mesh.triangles.push_back(tri);
  }
  m.color.a = 1;
  return m;
}

SceneMeshes Scene(std::vector<InstanceMesh> inst) {
  SceneMeshes s;
  s.header.frame_id = "map";
  s.header.stamp.sec = 5;
  s.instances = std::move(inst);
  return s;
}

int Count(const visualization_msgs::MarkerArray& a, int action, const std::string& ns = "") {
  int n = 0;
  for (const Marker& m : a.markers) n += m.action == action && (ns.empty() || m.ns == ns);
  return n;
}

TEST(MarkerBuilder, FirstUpdateDeleteAllThenThreeMarkersPerInstance) {
  MarkerBuilder b;
  const auto a = b.Update(Scene({Inst(4, 0), Inst(9, 0)}));
  ASSERT_EQ(a.markers.size(), 7u);
  EXPECT_EQ(a.markers[0].action, Marker::DELETEALL);
  EXPECT_EQ(Count(a, Marker::ADD, MarkerBuilder::kMeshNs), 2);
  EXPECT_EQ(Count(a, Marker::ADD, MarkerBuilder::kBoxNs), 2);
  EXPECT_EQ(Count(a, Marker::ADD, MarkerBuilder::kLabelNs), 2);
  std::set<int> ids;
  for (const Marker& m : a.markers) {
    EXPECT_EQ(m.header.frame_id, "map");
    EXPECT_EQ(m.header.stamp.sec, 5u);
    if (m.action != Marker::ADD) continue;
    ids.insert(m.id);
    if (m.type == Marker::TRIANGLE_LIST) {
      EXPECT_EQ(m.points.size(), 6u);  // 2 triangles
      EXPECT_TRUE(m.colors.empty());
    }
    if (m.type == Marker::LINE_LIST) {
      EXPECT_EQ(m.points.size(), 24u);
    }
    if (m.type == Marker::TEXT_VIEW_FACING) {
      EXPECT_EQ(m.text.find("chair #"), 0u);
      EXPECT_NEAR(m.pose.position.z, 0.6, 1e-9);  // above the box top
    }
  }
  EXPECT_EQ(ids, (std::set<int>{4, 9}));
}

TEST(MarkerBuilder, DeltasOnlyForChangesAndDeletesForVanished) {
  MarkerBuilder b;
  b.Update(Scene({Inst(1, 0), Inst(2, 0), Inst(3, 0)}));
  // 1 unchanged, 2 changed revision, 3 vanished, 5 new.
  const auto a = b.Update(Scene({Inst(1, 0), Inst(2, 1), Inst(5, 0)}));
  EXPECT_EQ(Count(a, Marker::DELETEALL), 0);
  EXPECT_EQ(Count(a, Marker::ADD), 6);
  EXPECT_EQ(Count(a, Marker::DELETE), 3);
  for (const Marker& m : a.markers) {
    if (m.action == Marker::DELETE) {
      EXPECT_EQ(m.id, 3);
    }
    if (m.action == Marker::ADD) {
      EXPECT_TRUE(m.id == 2 || m.id == 5);
    }
  }
  EXPECT_EQ(b.size(), 3u);
  // Nothing changed: nothing sent.
  EXPECT_TRUE(b.Update(Scene({Inst(1, 0), Inst(2, 1), Inst(5, 0)})).markers.empty());
}

TEST(MarkerBuilder, EmptyMeshNeverSentAndItsOldMarkerDeleted) {
  MarkerBuilder b;
  b.Update(Scene({Inst(1, 0)}));
  const auto a = b.Update(Scene({Inst(1, 1, /*tris=*/0)}));
  EXPECT_EQ(Count(a, Marker::DELETE, MarkerBuilder::kMeshNs), 1);
  EXPECT_EQ(Count(a, Marker::ADD, MarkerBuilder::kMeshNs), 0);
  EXPECT_EQ(Count(a, Marker::ADD, MarkerBuilder::kBoxNs), 1);
}

TEST(MarkerBuilder, SnapshotAndReset) {
  MarkerBuilder b;
  b.Update(Scene({Inst(1, 0), Inst(2, 0)}));
  b.Update(Scene({Inst(2, 0)}));
  const auto snap = b.Snapshot();
  ASSERT_EQ(snap.markers.size(), 4u);
  EXPECT_EQ(snap.markers[0].action, Marker::DELETEALL);
  for (std::size_t i = 1; i < snap.markers.size(); ++i) EXPECT_EQ(snap.markers[i].id, 2);
  b.Reset();
  EXPECT_EQ(b.size(), 0u);
  const auto a = b.Update(Scene({Inst(2, 0)}));
  EXPECT_EQ(a.markers[0].action, Marker::DELETEALL);
  EXPECT_EQ(Count(a, Marker::ADD), 3);
}

TEST(MarkerBuilder, OptionalBoxesAndLabels) {
  VisualizationConfig c;
  c.show_bbox = false;
  c.show_labels = false;
  MarkerBuilder b(c);
  const auto a = b.Update(Scene({Inst(1, 0)}));
  EXPECT_EQ(Count(a, Marker::ADD), 1);
  c.color_by = "rainbow";
  EXPECT_THROW(MarkerBuilder{c}, InvalidArgument);
}

TEST(MarkerBuilder, DeterministicDistinctColours) {
  const auto a = InstanceColor(3, 0.5), b = InstanceColor(3, 0.5), c = InstanceColor(4, 0.5);
  EXPECT_EQ(a.r, b.r);
  EXPECT_FLOAT_EQ(a.a, 0.5f);
  EXPECT_GT(std::abs(a.r - c.r) + std::abs(a.g - c.g) + std::abs(a.b - c.b), 0.1f);
  EXPECT_NE(ClassColor(0, 1).r, ClassColor(1, 1).r);
  EXPECT_FLOAT_EQ(ClassColor(99, 1).r, 0.6f);
}

}  // namespace
}  // namespace dimr::ros1
