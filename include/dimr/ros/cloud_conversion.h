// sensor_msgs/PointCloud2 -> points in the fixed frame, with full validation of the message
// layout. A malformed message throws CloudError with a stable code (shown in diagnostics and
// the node's warnings) and a message naming the field / size / frame; it never reads outside
// `data`. Non-finite points are dropped and counted; points outside the crop box are dropped;
// more than `max_points` points are subsampled with a uniform stride.
#pragma once

#include <sensor_msgs/PointCloud2.h>

#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

#include "dimr/geometry/error.h"

namespace dimr::ros1 {

enum class CloudIssue {
  kEmpty,             // width or height 0, or no data
  kBigEndian,         // is_bigendian set (the host is little-endian)
  kMissingField,      // no x, y or z field
  kBadFieldType,      // x/y/z not FLOAT32/FLOAT64, count 0, an unknown datatype
  kFieldOutOfBounds,  // a field's offset + size beyond point_step
  kSizeMismatch,      // point_step / row_step / data size inconsistent
  kTooLarge,          // width x height beyond the hard limit of the node
  kNoValidPoints,     // every point is NaN/Inf or outside the crop box
};

// Stable snake_case name ("missing_field", ...), used as the diagnostic key.
const char* CloudIssueName(CloudIssue issue);

class CloudError : public InvalidArgument {
 public:
  CloudError(CloudIssue issue, const std::string& what)
      : InvalidArgument(std::string(CloudIssueName(issue)) + ": " + what), issue_(issue) {}
  CloudIssue issue() const { return issue_; }

 private:
  CloudIssue issue_;
};

struct DecodeOptions {
  std::array<double, 3> crop_min = {-1e300, -1e300, -1e300};  // in the target frame
  std::array<double, 3> crop_max = {1e300, 1e300, 1e300};
  std::size_t max_points = 2000000;            // subsample (stride) above this
  std::size_t max_message_points = 200000000;  // reject (kTooLarge) above this
};

struct DecodedCloud {
  std::vector<Eigen::Vector3f> points;   // target frame, metres
  std::vector<Eigen::Vector3f> colors;   // [0, 1]; empty when the message has no rgb/rgba
  std::vector<Eigen::Vector3f> normals;  // target frame; empty without normal_x/y/z
  std::size_t message_points = 0;        // width x height
  std::size_t non_finite = 0;            // dropped NaN/Inf points (of the visited ones)
  std::size_t cropped = 0;               // dropped outside the crop box
  std::size_t stride = 1;                // > 1 when subsampled
  std::vector<std::string> warnings;     // non-fatal problems (e.g. unusable rgb field)
};

// Decodes `msg`, mapping points (and normals) with `to_target` (target <- cloud frame).
DecodedCloud DecodeCloud(const sensor_msgs::PointCloud2& msg, const Eigen::Isometry3d& to_target,
                         const DecodeOptions& options = {});

}  // namespace dimr::ros1
