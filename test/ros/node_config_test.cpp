// Parameters: config/default.yaml, the declarations in code and docs/ros.md agree; reading
// checks types and ranges and reports unknown keys.
#include "dimr/ros/node_config.h"

#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include "dimr/geometry/error.h"
#include "dimr/ros/node_params.h"

namespace dimr::ros1 {
namespace {

const std::string kSource = DIMR_SOURCE_DIR;

std::set<std::string> Declared(const ParamTable& t) {
  std::set<std::string> s;
  for (const ParamEntry& e : t.entries()) s.insert(e.name);
  return s;
}

TEST(NodeConfig, DefaultYamlMatchesTheDeclarationsAndDefaults) {
  NodeConfig defaults, loaded;
  ParamTable td, tl;
  DeclareNodeParams(&defaults, &td);
  DeclareNodeParams(&loaded, &tl);
  // Change a value first so that reading default.yaml must restore it.
  loaded.association.min_iou = 0.9;
  loaded.crop_min = {1, 2, 3};
  const auto src = YamlParamSource(kSource + "/config/default.yaml");
  const std::vector<std::string> unknown = tl.Read(*src);
  // Keys of default.yaml that are not node parameters must be the Reconstructor's.
  for (const std::string& k : unknown)
    EXPECT_TRUE(k.rfind("pipeline/", 0) == 0) << "undeclared key in default.yaml: " << k;
  EXPECT_EQ(tl.Dump(), td.Dump());
  std::set<std::string> keys;
  for (const std::string& k : src->Keys()) keys.insert(k);
  for (const std::string& name : Declared(td)) EXPECT_TRUE(keys.count(name)) << name;
  loaded.Validate();
}

TEST(NodeConfig, DocsListEveryParameter) {
  std::ifstream f(kSource + "/docs/ros.md");
  ASSERT_TRUE(f) << "docs/ros.md missing";
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string doc = ss.str();
  // Parameter rows: "| `name` | type | unit | default | range | ... |"
  std::set<std::string> documented;
  const std::regex row(R"(\n\| `([a-z_/0-9]+)` \| (bool|int|double|string|vector3) \|)");
  for (auto it = std::sregex_iterator(doc.begin(), doc.end(), row); it != std::sregex_iterator();
       ++it)
    documented.insert((*it)[1]);
  NodeParams c;
  PipelineParamText text;
  ParamTable t;
  DeclareNodeParams(&c.node, &t);
  DeclarePipelineParams(&c.pipeline, &text, &t);
  for (const ParamEntry& e : t.entries()) {
    EXPECT_TRUE(documented.count(e.name)) << "not in docs/ros.md: " << e.name;
    // The documented default is the code's default.
    const std::string value = e.get_text();
    const std::string needle = "| `" + e.name + "` |";
    const std::size_t at = doc.find(needle);
    if (at == std::string::npos) continue;
    const std::string line = doc.substr(at, doc.find('\n', at) - at);
    std::string plain = value;
    if (plain.size() > 2 && plain.front() == '"') plain = plain.substr(1, plain.size() - 2);
    EXPECT_NE(line.find("`" + plain + "`"), std::string::npos)
        << e.name << ": default " << value << " not in: " << line;
  }
  for (const std::string& d : documented)
    EXPECT_TRUE(t.Find(d)) << "documented, not declared: " << d;
}

void ExpectReadError(const std::string& yaml, const std::string& needle) {
  NodeConfig c;
  ParamTable t;
  DeclareNodeParams(&c, &t);
  try {
    t.Read(*YamlParamSourceFromString(yaml, "test.yaml"));
    ADD_FAILURE() << "no error for: " << yaml;
  } catch (const InvalidArgument& e) {
    const std::string w = e.what();
    EXPECT_NE(w.find(needle), std::string::npos) << w;
    EXPECT_NE(w.find("test.yaml"), std::string::npos) << w;
  }
}

TEST(NodeConfig, TypeAndRangeErrorsNameKeyAndSource) {
  ExpectReadError("tf_timeout: -1", "'tf_timeout'");
  ExpectReadError("tf_timeout: fast", "expected a number");
  ExpectReadError("association: {min_iou: 1.5}", "outside [0.01, 1]");
  ExpectReadError("input_mode: stream", "not one of accumulated | scans");
  ExpectReadError("visualization: {show_bbox: maybe}", "expected true or false");
  ExpectReadError("tf_queue_size: 2.5", "expected an integer");
  ExpectReadError("crop_box: {min: [0, 0]}", "expected 3 numbers");
  ExpectReadError("crop_box: {max: [0, .nan, 0]}", "'crop_box/max'");
  ExpectReadError("fixed_frame: \"\"", "must not be empty");
  ExpectReadError("max_input_points: 10", "outside [1000, 100000000]");
}

TEST(NodeConfig, UnknownKeysReportedAndValuesRead) {
  NodeConfig c;
  ParamTable t;
  DeclareNodeParams(&c, &t);
  const auto unknown = t.Read(
      *YamlParamSourceFromString(
          "fixed_frame: odom\nassociaton: {min_iou: 0.5}\nscans: {resolution: 0.05, typo: 1}\n"
          "bond/x: 1\ncrop_box: {min: [-1, -2, -3]}\n",
          "t.yaml"),
      {"bond/"});
  EXPECT_EQ(unknown, (std::vector<std::string>{"associaton/min_iou", "scans/typo"}));
  EXPECT_EQ(c.fixed_frame, "odom");
  EXPECT_DOUBLE_EQ(c.scans.resolution, 0.05);
  EXPECT_DOUBLE_EQ(c.crop_min[2], -3.0);
  EXPECT_DOUBLE_EQ(c.association.min_iou, 0.2);  // misspelt: not applied
}

TEST(NodeConfig, ValidateCombinations) {
  NodeConfig c;
  c.Validate();
  c.fixed_frame = "/map";
  EXPECT_THROW(c.Validate(), InvalidArgument);
  c = NodeConfig();
  c.crop_min = {0, 0, 5};
  c.crop_max = {1, 1, 5};
  EXPECT_THROW(c.Validate(), InvalidArgument);
  c = NodeConfig();
  c.scans.max_extent = 0.05;
  EXPECT_THROW(c.Validate(), InvalidArgument);
}

TEST(NodeParams, DefaultYamlHasEveryParameterAndNothingElse) {
  const auto src = YamlParamSource(kSource + "/config/default.yaml");
  const ReadResult r = ReadNodeParams(*src, "/opt/pkg");
  EXPECT_TRUE(r.unknown_keys.empty()) << r.unknown_keys.front();
  std::set<std::string> keys;
  for (const std::string& k : src->Keys()) keys.insert(k);
  for (const std::string& n : DeclaredParamNames()) EXPECT_TRUE(keys.count(n)) << n;
  EXPECT_EQ(keys.size(), DeclaredParamNames().size());
  // Defaults of the pipeline config are the documented ones; relative paths resolved.
  const pipeline::ReconstructorConfig def;
  EXPECT_EQ(r.params.pipeline.stage1_model, "/opt/pkg/" + def.stage1_model);
  EXPECT_EQ(r.params.pipeline.pool, "/opt/pkg/" + def.pool);
  EXPECT_EQ(r.params.pipeline.pool_meshes, "");
  EXPECT_EQ(r.params.pipeline.k, def.k);
  EXPECT_DOUBLE_EQ(r.params.pipeline.score_threshold, def.score_threshold);
  EXPECT_EQ(r.params.pipeline.icp.samples, def.icp.samples);
  EXPECT_EQ(r.params.pipeline.preset, def.preset);
  EXPECT_EQ(r.params.pipeline.mode, def.mode);
  EXPECT_EQ(r.params.pipeline.min_points, def.min_points);
  EXPECT_EQ(r.params.pipeline.score, def.score);
  EXPECT_EQ(r.params.pipeline.icp.backend, def.icp.backend);
  EXPECT_EQ(r.params.pipeline.icp.metric, def.icp.metric);
  EXPECT_NE(r.resolved.find("pipeline/icp/max_tilt_deg: 10"), std::string::npos);
}

TEST(NodeParams, PipelineValuesAndErrors) {
  const ReadResult r = ReadNodeParams(
      *YamlParamSourceFromString("pipeline: {mode: retrieval, preset: fast, k: 4, pool: /p.bin,"
                                 " score: stage2, icp: {enabled: false, backend: pcl,"
                                 " metric: point_to_plane}}\nmax_input_points: 5000000\n",
                                 "t.yaml"),
      "");
  EXPECT_EQ(r.params.pipeline.mode, pipeline::ReconstructionMode::kRetrieval);
  EXPECT_EQ(r.params.pipeline.preset, pipeline::ReconstructionPreset::kFast);
  EXPECT_EQ(r.params.pipeline.k, 4);
  EXPECT_EQ(r.params.pipeline.pool, "/p.bin");
  EXPECT_FALSE(r.params.pipeline.icp.enabled);
  EXPECT_EQ(r.params.pipeline.score, pipeline::ScoreRanking::kStage2);
  EXPECT_EQ(r.params.pipeline.icp.backend, pipeline::IcpBackend::kPcl);
  EXPECT_EQ(r.params.pipeline.icp.metric, pipeline::IcpMetric::kPointToPlane);
  EXPECT_GE(r.params.pipeline.max_points, 5000000u);  // never below what the node hands over
  EXPECT_FALSE(r.params.pipeline.crop);
  auto bad = [](const std::string& yaml, const std::string& needle) {
    try {
      ReadNodeParams(*YamlParamSourceFromString(yaml, "bad.yaml"), "");
      ADD_FAILURE() << yaml;
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  bad("pipeline: {mode: sculpt}", "pipeline/mode");
  bad("pipeline: {k: 0}", "pipeline/k");
  bad("pipeline: {stage1_model: \"\"}", "must not be empty");
  bad("pipeline: {icp: {max_tilt_deg: 95}}", "pipeline/icp/max_tilt_deg");
  bad("pipeline: {nms_iou: high}", "expected a number");
  bad("pipeline: {icp: {backend: open3d}}", "pipeline/icp/backend");
  bad("pipeline: {score: stage1}", "pipeline/score");
}

TEST(ParamTable, DuplicateDeclarationAndRangeText) {
  ParamTable t;
  double x = 0;
  t.AddDouble("a", &x, 0, 1, "m", "a");
  EXPECT_THROW(t.AddDouble("a", &x, 0, 1, "m", "a"), InvalidArgument);
  EXPECT_EQ(ParamTable::RangeText(*t.Find("a")), "[0, 1]");
}

TEST(ParamTable, MalformedYamlIsAParseError) {
  EXPECT_THROW(YamlParamSourceFromString("a: [1, 2", "bad.yaml"), ParseError);
  EXPECT_THROW(YamlParamSourceFromString("- 1\n- 2\n", "list.yaml"), ParseError);
  EXPECT_THROW(YamlParamSource("/no/such/file.yaml"), ParseError);
}

}  // namespace
}  // namespace dimr::ros1
