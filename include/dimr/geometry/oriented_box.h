// 7-DoF oriented boxes (centre, size, heading about +z), as used for DIMR/Scan2CAD boxes:
// size = (forward, left, up) extents along the box's local x, y, z axes; heading rotates
// local x towards +y (counter-clockwise seen from above).
#pragma once

#include <array>

#include "dimr/geometry/types.h"

namespace dimr::geometry {

struct OrientedBox {
  Vec3 center = Vec3::Zero();
  Vec3 size = Vec3::Zero();
  double heading = 0.0;

  Eigen::Matrix3d Rotation() const;
  // 8 corners: bottom face counter-clockwise from (-x,-y), then the top face in the same order.
  std::array<Vec3, 8> Corners() const;
  double Volume() const { return size.x() * size.y() * size.z(); }
  bool Contains(const Vec3& p, double margin = 0.0) const;
  AABB Bounds() const;
  // Closed triangle mesh of the box (12 triangles, outward normals).
  TriangleMesh ToMesh() const;
};

// Exact 3-D IoU of two z-rotated boxes: (bird's-eye polygon intersection area) x (height
// overlap) / union volume.
double BoxIoU(const OrientedBox& a, const OrientedBox& b);
// IoU of axis-aligned boxes.
double AabbIoU(const AABB& a, const AABB& b);
// Area of the intersection of two convex polygons (counter-clockwise vertex lists).
double ConvexPolygonIntersectionArea(const std::vector<Eigen::Vector2d>& a,
                                     const std::vector<Eigen::Vector2d>& b);

}  // namespace dimr::geometry
