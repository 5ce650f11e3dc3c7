#include "dimr/pipeline/model_card.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include "dimr/core/error.h"

namespace dimr::pipeline {
namespace {

namespace fs = std::filesystem;

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const ParseError& e) {
    return e.what();
  }
  return "";
}

// The shipped BSP card: nested keys, comments after values, inline lists and mappings.
TEST(ModelCard, ReadsTheShippedBspCard) {
  const std::string weights = std::string(DIMR_SOURCE_DIR) + "/models/bsp/bsp.pt";
  const ModelCard card = ModelCard::Load(weights);
  EXPECT_EQ(card.path(), std::string(DIMR_SOURCE_DIR) + "/models/bsp/model.yaml");
  EXPECT_EQ(card.GetString("name"), "bsp_cvae");
  EXPECT_EQ(card.GetString("weights.sha256"),
            "ef8f719efb46ba9672d9e641a701dc49847cc34855e91a056522c6010c9afa39");
  EXPECT_EQ(card.GetString("weights.dtype"), "float16");
  EXPECT_EQ(card.GetInt("phase"), 1);  // "1   # continuous phase 0 ..." : the comment is no value
  EXPECT_EQ(card.GetInt("parameters"), 7803168);
  EXPECT_DOUBLE_EQ(card.GetDouble("recommended_distance_dilation"), 0.0145);
  EXPECT_DOUBLE_EQ(card.GetDouble("recommended_dilation"), 0.0);
  EXPECT_DOUBLE_EQ(card.GetDouble("metrics.test_iou_per_class.chair"), 0.6588);
  EXPECT_EQ(card.GetInt("pool.entries"), 2000);
  const std::vector<std::string> labels = card.GetStringList("label_set");
  ASSERT_EQ(labels.size(), 8u);
  EXPECT_EQ(labels[4], "trash_bin");
  EXPECT_TRUE(card.has("metrics"));
  EXPECT_TRUE(card.has("metrics.test_iou_per_class"));
  EXPECT_FALSE(card.has("metrics.nothing"));
  EXPECT_NE(card.GetString("architecture").find("latent_dim=128"), std::string::npos);
  // Keys in card order, a mapping before its members.
  const std::vector<std::string> keys = card.Keys();
  ASSERT_GE(keys.size(), 10u);
  EXPECT_EQ(keys[0], "name");
  const auto at = [&](const std::string& k) {
    return std::find(keys.begin(), keys.end(), k) - keys.begin();
  };
  EXPECT_LT(at("weights"), at("weights.sha256"));
  EXPECT_LT(at("weights.sha256"), at("recommended_dilation"));
}

TEST(ModelCard, ReadsTheShippedStage1Card) {
  const ModelCard card = ModelCard::Load(std::string(DIMR_SOURCE_DIR) + "/models/stage1/stage1.pt");
  // A quoted value followed by a comment: the text inside the quotes.
  const std::string inf = card.GetString("recommended_inference");
  EXPECT_EQ(inf.rfind("passes=s0.12,s0.2,s0.3 rotations=6", 0), 0u) << inf;
  EXPECT_NE(inf.find(" vote_max_extent=3 "), std::string::npos) << inf;
  // "... wall_opening_contrast=6 wall_opening_shape=1": the quote ends before the comment.
  const std::string tail = " wall_opening_contrast=6 wall_opening_shape=1";
  ASSERT_GT(inf.size(), tail.size()) << inf;
  EXPECT_EQ(inf.substr(inf.size() - tail.size()), tail) << inf;
  EXPECT_EQ(card.GetInt("training.steps"), 9719);
  EXPECT_DOUBLE_EQ(card.GetDouble("metrics_test.instance_ap50_cad"), 0.865);
  EXPECT_DOUBLE_EQ(card.GetDouble("metrics_test.val_60_rooms.cv_heldout_miou"), 0.7696);
  EXPECT_EQ(card.GetString("training.val_data"), "data/stage1_v2_val.bin");
  EXPECT_EQ(card.GetInt("previous_step9.training.steps"), 20423);
  EXPECT_DOUBLE_EQ(card.GetDouble("metrics_test.v2_test.instance_ap50_cad"), 0.581);
}

TEST(ModelCard, DefaultsOnlyForMissingKeys) {
  const ModelCard card = ModelCard::Parse(
      "a: 3\nb: 2.5\nflag: yes\noff_flag: Off\ns: \"x # y\"\nempty:\nlist: [1, 2.5, -3]\n"
      "nested:\n  deeper:\n    v: 7\n",
      "mem.yaml");
  EXPECT_EQ(card.GetInt("a", 9), 3);
  EXPECT_EQ(card.GetInt("missing", 9), 9);
  EXPECT_DOUBLE_EQ(card.GetDouble("b", 1.0), 2.5);
  EXPECT_DOUBLE_EQ(card.GetDouble("a"), 3.0);
  EXPECT_DOUBLE_EQ(card.GetDouble("missing", -1.5), -1.5);
  EXPECT_TRUE(card.GetBool("flag"));
  EXPECT_FALSE(card.GetBool("off_flag", true));
  EXPECT_TRUE(card.GetBool("missing", true));
  EXPECT_EQ(card.GetString("s"), "x # y");
  EXPECT_EQ(card.GetString("empty", "fallback"), "");  // present, empty
  EXPECT_EQ(card.GetString("missing", "fallback"), "fallback");
  EXPECT_EQ(card.GetInt("nested.deeper.v"), 7);
  const std::vector<double> list = card.GetDoubleList("list");
  ASSERT_EQ(list.size(), 3u);
  EXPECT_DOUBLE_EQ(list[1], 2.5);
  EXPECT_DOUBLE_EQ(list[2], -3.0);
  // A present value of the wrong type is an error even with a default.
  EXPECT_THROW(card.GetInt("b", 0), ParseError);
  EXPECT_THROW(card.GetDouble("s", 0.0), ParseError);
  EXPECT_THROW(card.GetDouble("empty", 0.0), ParseError);
  EXPECT_THROW(card.GetBool("a", false), ParseError);
  EXPECT_THROW(card.GetString("nested", ""), ParseError);
  EXPECT_THROW(card.GetString("list"), ParseError);
  EXPECT_THROW(card.GetStringList("a"), ParseError);
  // An empty card: every default.
  const ModelCard none;
  EXPECT_FALSE(none.has("a"));
  EXPECT_EQ(none.GetInt("a", 4), 4);
  EXPECT_THROW(none.GetInt("a"), ParseError);
}

TEST(ModelCard, ErrorsNameTheCardTheKeyAndTheLine) {
  const ModelCard card = ModelCard::Parse(
      "name: x\nrecommended_dilation: wide\nbig: 99999999999\nnan: .nan\n", "dir/model.yaml");
  std::string e = ErrorOf([&] { card.GetDouble("recommended_dilation"); });
  EXPECT_NE(e.find("dir/model.yaml"), std::string::npos) << e;
  EXPECT_NE(e.find("recommended_dilation (line 2)"), std::string::npos) << e;
  EXPECT_NE(e.find("'wide'"), std::string::npos) << e;
  e = ErrorOf([&] { card.GetString("weights.sha256"); });
  EXPECT_NE(e.find("dir/model.yaml"), std::string::npos) << e;
  EXPECT_NE(e.find("missing key 'weights.sha256'"), std::string::npos) << e;
  e = ErrorOf([&] { card.GetInt("big"); });
  EXPECT_NE(e.find("big (line 3) must be an integer"), std::string::npos) << e;
  EXPECT_NE(ErrorOf([&] { card.GetDouble("nan"); }).find("finite"), std::string::npos);

  e = ErrorOf([] { ModelCard::Parse("a: [1, 2\nb: 3\n", "bad.yaml"); });
  EXPECT_NE(e.find("bad.yaml: malformed YAML"), std::string::npos) << e;
  e = ErrorOf([] { ModelCard::Parse("- a\n- b\n", "list.yaml"); });
  EXPECT_NE(e.find("list.yaml"), std::string::npos) << e;
  EXPECT_NE(e.find("mapping"), std::string::npos) << e;
  EXPECT_EQ(ModelCard::Parse("", "empty.yaml").Keys().size(), 0u);
  EXPECT_EQ(ModelCard::Parse("# only a comment\n", "c.yaml").Keys().size(), 0u);
}

TEST(ModelCard, LoadFindsTheCardBesideTheWeights) {
  const fs::path dir = fs::temp_directory_path() / "dimr_model_card_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string weights = (dir / "net.pt").string();
  EXPECT_EQ(ModelCard::CardPath(weights), (dir / "model.yaml").string());
  EXPECT_EQ(ModelCard::CardPath("other/card.yml"), "other/card.yml");
  EXPECT_FALSE(ModelCard::LoadIfExists(weights).has_value());
  std::string e = ErrorOf([&] { ModelCard::Load(weights); });
  EXPECT_NE(e.find((dir / "model.yaml").string()), std::string::npos) << e;

  std::ofstream(dir / "model.yaml") << "weights:\n  sha256: abc\n  file: net.pt\n";
  const ModelCard card = ModelCard::Load(weights);
  EXPECT_EQ(card.GetString("weights.file"), "net.pt");
  EXPECT_EQ(ModelCard::Load((dir / "model.yaml").string()).GetString("weights.sha256"), "abc");
  ASSERT_TRUE(ModelCard::LoadIfExists(weights).has_value());

  std::ofstream(dir / "model.yaml") << "weights: {sha256: abc\n";
  e = ErrorOf([&] { ModelCard::LoadIfExists(weights); });  // exists but malformed: an error
  EXPECT_NE(e.find((dir / "model.yaml").string()), std::string::npos) << e;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace dimr::pipeline
