#include "dimr/core/allocator.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>

#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace dimr {
namespace {

TEST(Allocator, EnvironmentKeepsGlibcDefaults) {
#ifdef __GLIBC__
  ASSERT_EQ(getenv("GLIBC_TUNABLES"), nullptr) << "run without GLIBC_TUNABLES";
  setenv("DIMR_DEFAULT_MALLOC", "1", 1);
  EXPECT_EQ(TuneAllocatorForTensors(), AllocatorTuning::kUserSettings);
  unsetenv("DIMR_DEFAULT_MALLOC");
#else
  EXPECT_EQ(TuneAllocatorForTensors(), AllocatorTuning::kUnsupported);
#endif
}

#if defined(__GLIBC__) && __GLIBC_PREREQ(2, 33)
// Tuned, a 64 MB block comes from the heap, not from mmap (glibc maps anything above its
// dynamic threshold, 32 MB at most, by default).
TEST(Allocator, LargeBlocksStayInTheHeap) {
  unsetenv("DIMR_DEFAULT_MALLOC");
  ASSERT_EQ(TuneAllocatorForTensors(), AllocatorTuning::kTuned);
  const std::size_t mapped_before = mallinfo2().hblkhd;
  void* p = std::malloc(64u << 20);
  ASSERT_NE(p, nullptr);
  std::memset(p, 1, 4096);
  const std::size_t mapped_during = mallinfo2().hblkhd;
  std::free(p);
  EXPECT_LT(mapped_during, mapped_before + (64u << 20));
}
#endif

}  // namespace
}  // namespace dimr
