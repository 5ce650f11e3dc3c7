#include <gtest/gtest.h>

#include <string>

#include "dimr/core/error.h"
#include "dimr/core/hash.h"
#include "dimr/core/labels.h"

namespace dimr {
namespace {

// The numbering is in every shipped model, pool and dataset: pinned.
TEST(Labels, FixedNumberingAndMaps) {
  using namespace labels;  // NOLINT
  EXPECT_STREQ(CadClassNames()[kCadTrashBin], "trash_bin");
  EXPECT_STREQ(CadClassNames()[kCadBathtub], "bathtub");
  EXPECT_STREQ(RfsClassNames()[kOtherTable], "other_table");
  EXPECT_STREQ(CadSynsets()[kCadChair], "03001627");
  EXPECT_EQ(CadClassFromName("trash"), kCadTrashBin);
  EXPECT_EQ(CadClassFromName("display"), 6);
  EXPECT_EQ(CadClassFromName("bed"), -1);
  EXPECT_EQ(RfsClassFromName("shower curtain"), 15);
  EXPECT_EQ(CadClassFromSynset("02808440"), kCadBathtub);
  EXPECT_EQ(RfsToCad(kToilet), kCadChair);
  EXPECT_EQ(RfsToCad(kSink), kCadBathtub);
  EXPECT_EQ(RfsToCad(kCounter), kCadCabinet);
  EXPECT_EQ(RfsToCad(kKitchenCabinet), kNonCad);
  EXPECT_EQ(RfsToCad(kRefridgerator), kNonCad);
  EXPECT_EQ(CadToRfs(kCadTrashBin), kTrashBin);
  int cad_of_rfs = 0;
  for (int r = 0; r < kNumRfsClasses; ++r) cad_of_rfs += RfsToCad(r) >= 0;
  EXPECT_EQ(cad_of_rfs, 14);
  for (int c = 0; c < kNumCadClasses; ++c) EXPECT_EQ(RfsToCad(CadToRfs(c)), c);
  EXPECT_THROW(RfsToCad(25), InvalidArgument);
  EXPECT_THROW(CadToRfs(-1), InvalidArgument);
}

TEST(Hash, StringOverloadIsTheBytes) {
  const std::string id = "1a2b3c";
  EXPECT_EQ(Fnv1a(id), Fnv1a(id.data(), id.size()));
  EXPECT_EQ(Fnv1a(std::string_view("foobar"), kFnv1aStandardOffset), 0x85944171f73967e8ull);
  EXPECT_EQ(Fnv1a(std::string_view("bar"), Fnv1a(std::string_view("foo"))),
            Fnv1a(std::string_view("foobar")));
  EXPECT_EQ(Fnv1a("foobar", 6), 9870438755804841970ull);  // the project basis, pinned
}

}  // namespace
}  // namespace dimr
