// ROS parameter server as a ParamSource (see ros_param_source.h).
#include "dimr/ros/ros_param_source.h"

#include <ros/param.h>

#include "dimr/geometry/error.h"

namespace dimr::ros1 {

RosParamSource::RosParamSource(const ros::NodeHandle& pnh) : pnh_(pnh) {
  std::vector<std::string> all;
  ros::param::getParamNames(all);
  const std::string prefix = pnh_.getNamespace() + "/";
  for (const std::string& n : all)
    if (n.rfind(prefix, 0) == 0) keys_.push_back(n.substr(prefix.size()));
}

bool RosParamSource::GetBool(const std::string& key, bool* v) const {
  XmlRpc::XmlRpcValue x;
  if (!pnh_.getParam(key, x)) return false;
  if (x.getType() != XmlRpc::XmlRpcValue::TypeBoolean)
    Fail(key, "expected true or false, got " + x.toXml());
  *v = static_cast<bool>(x);
  return true;
}

bool RosParamSource::GetDouble(const std::string& key, double* v) const {
  XmlRpc::XmlRpcValue x;
  if (!pnh_.getParam(key, x)) return false;
  if (x.getType() == XmlRpc::XmlRpcValue::TypeDouble)
    *v = static_cast<double>(x);
  else if (x.getType() == XmlRpc::XmlRpcValue::TypeInt)
    *v = static_cast<int>(x);
  else
    Fail(key, "expected a number, got " + x.toXml());
  return true;
}

bool RosParamSource::GetInt(const std::string& key, long long* v) const {
  XmlRpc::XmlRpcValue x;
  if (!pnh_.getParam(key, x)) return false;
  if (x.getType() != XmlRpc::XmlRpcValue::TypeInt)
    Fail(key, "expected an integer, got " + x.toXml());
  *v = static_cast<int>(x);
  return true;
}

bool RosParamSource::GetString(const std::string& key, std::string* v) const {
  XmlRpc::XmlRpcValue x;
  if (!pnh_.getParam(key, x)) return false;
  if (x.getType() != XmlRpc::XmlRpcValue::TypeString)
    Fail(key, "expected a string, got " + x.toXml());
  *v = static_cast<std::string>(x);
  return true;
}

bool RosParamSource::GetDoubleList(const std::string& key, std::vector<double>* v) const {
  XmlRpc::XmlRpcValue x;
  if (!pnh_.getParam(key, x)) return false;
  if (x.getType() != XmlRpc::XmlRpcValue::TypeArray)
    Fail(key, "expected a list of numbers, got " + x.toXml());
  v->clear();
  for (int i = 0; i < x.size(); ++i) {
    if (x[i].getType() == XmlRpc::XmlRpcValue::TypeDouble)
      v->push_back(static_cast<double>(x[i]));
    else if (x[i].getType() == XmlRpc::XmlRpcValue::TypeInt)
      v->push_back(static_cast<int>(x[i]));
    else
      Fail(key, "expected a list of numbers, got " + x.toXml());
  }
  return true;
}

void RosParamSource::Fail(const std::string& key, const std::string& what) const {
  throw InvalidArgument("parameter '" + key + "' (" + Describe() + "): " + what);
}

}  // namespace dimr::ros1
