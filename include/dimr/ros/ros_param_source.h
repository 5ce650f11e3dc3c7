// The ROS parameter server under a private node handle, as a ParamSource (param_table.h):
// leaf keys relative to the handle's namespace; type mismatches throw dimr::InvalidArgument
// naming the key.
#pragma once

#include <ros/node_handle.h>

#include <string>
#include <vector>

#include "dimr/ros/param_table.h"

namespace dimr::ros1 {

class RosParamSource : public ParamSource {
 public:
  explicit RosParamSource(const ros::NodeHandle& pnh);
  std::vector<std::string> Keys() const override { return keys_; }
  bool GetBool(const std::string& key, bool* v) const override;
  bool GetDouble(const std::string& key, double* v) const override;
  bool GetInt(const std::string& key, long long* v) const override;
  bool GetString(const std::string& key, std::string* v) const override;
  bool GetDoubleList(const std::string& key, std::vector<double>* v) const override;
  std::string Describe() const override { return "ROS parameters of " + pnh_.getNamespace(); }

 private:
  [[noreturn]] void Fail(const std::string& key, const std::string& what) const;
  ros::NodeHandle pnh_;
  std::vector<std::string> keys_;
};

}  // namespace dimr::ros1
