// Standalone `dimr_node`: loads the dimr/ReconstructionNodelet in-process (same class, same
// parameters as the nodelet). Exits with status 1 when the nodelet cannot start (bad
// parameter, missing or corrupt model); the reason is logged.
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "dimr");
  nodelet::Loader loader;
  nodelet::M_string remap(ros::names::getRemappings());
  nodelet::V_string nargv;
  bool ok = false;
  try {
    ok = loader.load(ros::this_node::getName(), "dimr/ReconstructionNodelet", remap, nargv);
  } catch (const std::exception& e) {
    ROS_FATAL("dimr_node: %s", e.what());
  }
  if (!ok) {
    ROS_FATAL("dimr_node: the reconstruction nodelet did not start (see the error above)");
    return 1;
  }
  ros::AsyncSpinner spinner(4);
  spinner.start();
  ros::waitForShutdown();
  loader.clear();
  return 0;
}
