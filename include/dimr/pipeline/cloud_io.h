// Reading a user's point cloud file for the Reconstructor: PLY (geometry/ply_io.h, any
// encoding) or PCD (PCL's format, an own bounded reader: ascii, binary, binary_compressed;
// x y z, optional rgb/rgba and normal_x/y/z). LibTorch-free.
#pragma once

#include <cstddef>
#include <string>

#include "dimr/geometry/types.h"

namespace dimr::pipeline {

// Reads `path` by extension (.ply / .pcd, case-insensitive). Points that are not finite are
// kept (the Reconstructor reports them). Throws dimr::ParseError naming the file for a
// missing, malformed or unsupported file; counts are checked against the file size before
// anything is allocated.
geometry::PointCloud ReadPointCloudFile(const std::string& path);

// Drops every point with a non-finite coordinate together with its colour, normal and
// attribute values (order kept) and returns how many: organised clouds (PCL's depth-camera
// PCDs, is_dense false) mark pixels without a return by NaN, as the ROS node's input does.
// Throws dimr::InvalidArgument when an optional array's length differs from the points'.
std::size_t DropNonFinitePoints(geometry::PointCloud* cloud);

}  // namespace dimr::pipeline
