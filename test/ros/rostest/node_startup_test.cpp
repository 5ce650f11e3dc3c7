// rostest: the standalone dimr_node (the nodelet loaded in-process) fails loudly at start-up -
// exit status 1 and a FATAL line naming the problem - for a bad parameter value, a missing
// model file and a corrupt model file (stage 1, the first model loaded); it never runs
// half-configured.
#include <gtest/gtest.h>
#include <ros/package.h>
#include <ros/ros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace {

namespace fs = std::filesystem;

// Runs dimr_node with private parameters given as _key:=value arguments; returns the exit
// status and the output.
// Each run gets its own node name: private parameters stay on the master after a node exits,
// so a shared name would carry one test's bad value into the next.
int RunNode(const std::string& args, std::string* out) {
  static int runs = 0;
  const std::string cmd = std::string("timeout 120 ") + DIMR_NODE_PATH + " __name:=startup_" +
                          std::to_string(getpid()) + "_" + std::to_string(++runs) + " " + args +
                          " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return -1;
  char buf[4096];
  while (fgets(buf, sizeof(buf), p)) *out += buf;
  const int st = pclose(p);
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

TEST(NodeStartup, BadParameterValue) {
  std::string out;
  EXPECT_EQ(RunNode("_tf_timeout:=-3.0", &out), 1) << out;
  EXPECT_NE(out.find("tf_timeout"), std::string::npos) << out;
  EXPECT_NE(out.find("cannot start"), std::string::npos) << out;
}

TEST(NodeStartup, MissingModelFile) {
  std::string out;
  EXPECT_EQ(RunNode("_pipeline/stage1_model:=/nonexistent/stage1.pt", &out), 1) << out;
  EXPECT_NE(out.find("/nonexistent/stage1.pt"), std::string::npos) << out;
}

TEST(NodeStartup, CorruptModelFile) {
  const fs::path bad =
      fs::temp_directory_path() / ("dimr_corrupt_" + std::to_string(getpid()) + ".pt");
  std::ofstream(bad) << "this is not a model";
  std::string out;
  EXPECT_EQ(RunNode("_pipeline/stage1_model:=" + bad.string(), &out), 1) << out;
  EXPECT_NE(out.find(bad.string()), std::string::npos) << out;
  fs::remove(bad);
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "dimr_node_startup_test");
  return RUN_ALL_TESTS();
}
