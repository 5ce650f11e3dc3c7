// Voxel-mean density normalisation of the node's input (see density_filter.h): a thin wrapper
// of pipeline::VoxelMeanDownsample that leaves the cloud alone where that refuses it.
#include "dimr/ros/density_filter.h"

#include "dimr/geometry/error.h"
#include "dimr/pipeline/ceiling.h"
#include "dimr/pipeline/voxel_downsample.h"

namespace dimr::ros1 {

VoxelFilterStats VoxelMeanFilter(BackendCloud* cloud, double voxel_size) {
  VoxelFilterStats stats;
  const std::size_t n = cloud->points.size();
  stats.input_points = stats.output_points = n;
  if (!(voxel_size > 0) || n == 0) return stats;
  pipeline::PointCloudInput in;
  in.name = cloud->name;
  in.points = cloud->points;
  if (cloud->colors.size() == n) in.colors = cloud->colors;
  if (cloud->normals.size() == n) in.normals = cloud->normals;
  pipeline::VoxelDownsample out;
  try {
    out = pipeline::VoxelMeanDownsample(in, voxel_size);
  } catch (const InvalidArgument&) {
    return stats;  // e.g. more than 2^21 cells along an axis: the pipeline refuses it later
  }
  cloud->points = std::move(out.cloud.points);
  cloud->colors = std::move(out.cloud.colors);
  cloud->normals = std::move(out.cloud.normals);
  stats.output_points = cloud->points.size();
  stats.applied = true;
  return stats;
}

CeilingFilterStats CeilingFilter(BackendCloud* cloud) {
  CeilingFilterStats stats;
  const std::size_t n = cloud->points.size();
  if (n == 0) return stats;
  pipeline::PointCloudInput in;
  in.name = cloud->name;
  in.points = std::move(cloud->points);
  if (cloud->colors.size() == n) in.colors = std::move(cloud->colors);
  if (cloud->normals.size() == n) in.normals = std::move(cloud->normals);
  pipeline::CeilingRemoval out;
  try {
    out = pipeline::RemoveCeiling(std::move(in), pipeline::CeilingConfig());
  } catch (const InvalidArgument&) {
    out.cloud = std::move(in);  // untouched on a throw (a non-finite point: the pipeline names it)
  }
  cloud->points = std::move(out.cloud.points);
  if (!out.cloud.colors.empty()) cloud->colors = std::move(out.cloud.colors);
  if (!out.cloud.normals.empty()) cloud->normals = std::move(out.cloud.normals);
  if (out.found) {
    stats.found = true;
    stats.ceiling_z = out.ceiling_z;
    stats.removed = out.removed;
  }
  return stats;
}

}  // namespace dimr::ros1
