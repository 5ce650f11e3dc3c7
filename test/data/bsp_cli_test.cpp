// `dimr bsp eval` with the bundled BSP-CVAE: the decoding dilation comes from --dilation, else
// from the model card beside the weights (recommended_dilation), else 0; a malformed card is a
// clear error naming it.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "cli_run.h"

namespace {

namespace fs = std::filesystem;

#ifdef DIMR_CLI
using dimr::testing::RunCli;

double AllIoU(const std::string& out) {
  std::smatch m;
  if (!std::regex_search(out, m, std::regex(R"(\| \*\*all\*\* \| 8 \| \*\*([0-9.]+)\*\*)"))) {
    return -1;
  }
  return std::stod(m[1]);
}

TEST(BspCli, DilationFromOptionOrModelCard) {
  if (RunCli("bsp eval --help").first != 0) GTEST_SKIP() << "dimr built without the nn layer";
  const fs::path dir = fs::temp_directory_path() / ("bsp_cli_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string d = dir.string();
  fs::copy_file(fs::path(DIMR_SOURCE_DIR) / "models/bsp/bsp.pt", dir / "bsp.pt");
  auto [rc, out] = RunCli("bsp prepare --per-class 1 --seed 5 --out " + d + "/data.bin");
  ASSERT_EQ(rc, 0) << out;

  // No card: the reference (0).
  std::tie(rc, out) = RunCli("bsp eval --model " + d + "/bsp.pt --data " + d + "/data.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("dilation 0\n"), std::string::npos) << out;
  const double iou0 = AllIoU(out);
  ASSERT_GE(iou0, 0.0) << out;

  // The card's value.
  std::ofstream(d + "/model.yaml") << "name: bsp_cvae\nrecommended_dilation: 0.3   # chosen\n";
  std::tie(rc, out) = RunCli("bsp eval --model " + d + "/bsp.pt --data " + d + "/data.bin");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("dilation 0.3\n"), std::string::npos) << out;
  const double iou3 = AllIoU(out);
  ASSERT_GE(iou3, 0.0) << out;
  EXPECT_LE(iou3, 1.0);
  EXPECT_NE(iou3, iou0);  // the planes moved: another shape

  // An explicit option wins over the card.
  std::tie(rc, out) =
      RunCli("bsp eval --model " + d + "/bsp.pt --data " + d + "/data.bin --dilation 0");
  ASSERT_EQ(rc, 0) << out;
  EXPECT_DOUBLE_EQ(AllIoU(out), iou0);

  // A malformed card: non-zero exit naming the card.
  std::ofstream(d + "/model.yaml") << "recommended_dilation: wide\n";
  std::tie(rc, out) = RunCli("bsp eval --model " + d + "/bsp.pt --data " + d + "/data.bin");
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("model.yaml"), std::string::npos) << out;
  fs::remove_all(dir);
}
#endif

}  // namespace
