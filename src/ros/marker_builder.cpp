// rviz marker deltas (see marker_builder.h).
#include "dimr/ros/marker_builder.h"

#include <geometry_msgs/Point.h>

#include <array>
#include <cmath>
#include <cstdio>

namespace dimr::ros1 {
namespace {

using visualization_msgs::Marker;

std_msgs::ColorRGBA Rgba(double r, double g, double b, double a) {
  std_msgs::ColorRGBA c;
  c.r = static_cast<float>(r);
  c.g = static_cast<float>(g);
  c.b = static_cast<float>(b);
  c.a = static_cast<float>(a);
  return c;
}

std_msgs::ColorRGBA Hsv(double h, double s, double v, double a) {
  h = h - std::floor(h);
  const double i = std::floor(h * 6), f = h * 6 - i;
  const double p = v * (1 - s), q = v * (1 - f * s), t = v * (1 - (1 - f) * s);
  switch (static_cast<int>(i) % 6) {
    case 0:
      return Rgba(v, t, p, a);
    case 1:
      return Rgba(q, v, p, a);
    case 2:
      return Rgba(p, v, t, a);
    case 3:
      return Rgba(p, q, v, a);
    case 4:
      return Rgba(t, p, v, a);
    default:
      return Rgba(v, p, q, a);
  }
}

geometry_msgs::Point Pt(double x, double y, double z) {
  geometry_msgs::Point p;
  p.x = x;
  p.y = y;
  p.z = z;
  return p;
}

}  // namespace

std_msgs::ColorRGBA InstanceColor(std::uint32_t id, double alpha) {
  return Hsv(0.11 + 0.618033988749895 * id, 0.65, 0.95, alpha);
}

std_msgs::ColorRGBA ClassColor(int cad_class, double alpha) {
  // table, chair, bookshelf, sofa, trash bin, cabinet, display, bathtub
  static const std::array<std::array<double, 3>, 8> kPalette = {{{0.90, 0.60, 0.20},
                                                                 {0.25, 0.55, 0.90},
                                                                 {0.55, 0.35, 0.20},
                                                                 {0.85, 0.25, 0.35},
                                                                 {0.45, 0.75, 0.30},
                                                                 {0.60, 0.45, 0.80},
                                                                 {0.20, 0.75, 0.75},
                                                                 {0.95, 0.85, 0.30}}};
  if (cad_class < 0 || cad_class >= 8) return Rgba(0.6, 0.6, 0.6, alpha);
  const auto& c = kPalette[cad_class];
  return Rgba(c[0], c[1], c[2], alpha);
}

std_msgs::ColorRGBA SourceColor(int source, double alpha) {
  switch (source) {
    case InstanceMesh::SOURCE_GENERATED:
      return Rgba(0.30, 0.65, 0.95, alpha);
    case InstanceMesh::SOURCE_PROJECTED:
      return Rgba(0.95, 0.60, 0.20, alpha);
    case InstanceMesh::SOURCE_RETRIEVED:
      return Rgba(0.40, 0.85, 0.40, alpha);
    default:
      return Rgba(0.6, 0.6, 0.6, alpha);
  }
}

MarkerBuilder::MarkerBuilder(const VisualizationConfig& config) : config_(config) {
  config_.Validate();
}

void MarkerBuilder::Reset() {
  state_.clear();
  delete_all_next_ = true;
}

std::vector<Marker> MarkerBuilder::Build(const InstanceMesh& inst,
                                         const std_msgs::Header& header) const {
  std::vector<Marker> out;
  Marker base;
  base.header = header;
  base.id = static_cast<std::int32_t>(inst.id);
  base.action = Marker::ADD;
  base.pose = inst.pose;
  base.scale.x = base.scale.y = base.scale.z = 1.0;
  base.color = inst.color;
  base.frame_locked = false;

  // Mesh (vertices are in the object frame given by the pose). Never an empty TRIANGLE_LIST.
  if (!inst.mesh.triangles.empty()) {
    Marker m = base;
    m.ns = kMeshNs;
    m.type = Marker::TRIANGLE_LIST;
    m.points.reserve(inst.mesh.triangles.size() * 3);
    for (const shape_msgs::MeshTriangle& t : inst.mesh.triangles)
      for (std::uint32_t v : t.vertex_indices)
        if (v < inst.mesh.vertices.size()) m.points.push_back(inst.mesh.vertices[v]);
    m.points.resize(m.points.size() / 3 * 3);
    if (!m.points.empty()) out.push_back(std::move(m));
  }
  if (config_.show_bbox) {
    Marker b = base;
    b.ns = kBoxNs;
    b.type = Marker::LINE_LIST;
    b.scale.x = 0.01;  // line width, m
    b.scale.y = b.scale.z = 0;
    const double hx = inst.bbox_size.x / 2, hy = inst.bbox_size.y / 2, hz = inst.bbox_size.z / 2;
    std::array<geometry_msgs::Point, 8> c;
    for (int k = 0; k < 8; ++k)
      c[k] = Pt((k & 1) ? hx : -hx, (k & 2) ? hy : -hy, (k & 4) ? hz : -hz);
    static const int kEdges[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                                      {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    for (const auto& e : kEdges) {
      b.points.push_back(c[e[0]]);
      b.points.push_back(c[e[1]]);
    }
    out.push_back(std::move(b));
  }
  if (config_.show_labels) {
    Marker l = base;
    l.ns = kLabelNs;
    l.type = Marker::TEXT_VIEW_FACING;
    l.pose.orientation.x = l.pose.orientation.y = l.pose.orientation.z = 0;
    l.pose.orientation.w = 1;
    l.pose.position.z += inst.bbox_size.z / 2 + 0.1;
    l.scale.x = l.scale.y = 0;
    l.scale.z = 0.12;  // text height, m
    l.color.a = 1.0f;
    char buf[96];
    std::snprintf(buf, sizeof(buf), "%s #%u %.2f", inst.class_name.c_str(), inst.id, inst.score);
    l.text = buf;
    out.push_back(std::move(l));
  }
  return out;
}

visualization_msgs::MarkerArray MarkerBuilder::Update(const SceneMeshes& scene) {
  visualization_msgs::MarkerArray arr;
  header_ = scene.header;
  if (delete_all_next_) {
    Marker d;
    d.header = scene.header;
    d.action = Marker::DELETEALL;
    arr.markers.push_back(d);
    state_.clear();
    delete_all_next_ = false;
  }
  std::map<std::uint32_t, Published> next;
  for (const InstanceMesh& inst : scene.instances) {
    auto it = state_.find(inst.id);
    if (it != state_.end() && it->second.revision == inst.revision) {
      next[inst.id] = std::move(it->second);
      state_.erase(it);
      continue;
    }
    Published p;
    p.revision = inst.revision;
    p.markers = Build(inst, scene.header);
    if (it != state_.end()) {
      // A changed instance may lose a namespace (its mesh became empty): delete those.
      for (const Marker& old : it->second.markers) {
        bool kept = false;
        for (const Marker& m : p.markers) kept = kept || m.ns == old.ns;
        if (!kept) {
          Marker d = old;
          d.header = scene.header;
          d.action = Marker::DELETE;
          d.points.clear();
          arr.markers.push_back(d);
        }
      }
      state_.erase(it);
    }
    for (const Marker& m : p.markers) arr.markers.push_back(m);
    next[inst.id] = std::move(p);
  }
  // What is left in state_ vanished.
  for (const auto& [id, pub] : state_) {
    for (const Marker& old : pub.markers) {
      Marker d;
      d.header = scene.header;
      d.ns = old.ns;
      d.id = old.id;
      d.action = Marker::DELETE;
      arr.markers.push_back(d);
    }
  }
  state_ = std::move(next);
  return arr;
}

visualization_msgs::MarkerArray MarkerBuilder::Snapshot() const {
  visualization_msgs::MarkerArray arr;
  Marker d;
  d.header = header_;
  d.action = Marker::DELETEALL;
  arr.markers.push_back(d);
  for (const auto& [id, pub] : state_)
    for (const Marker& m : pub.markers) arr.markers.push_back(m);
  return arr;
}

}  // namespace dimr::ros1
