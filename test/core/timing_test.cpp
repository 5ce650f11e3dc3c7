#include "dimr/core/timing.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <thread>

#include "dimr/core/error.h"

namespace dimr {
namespace {

TEST(Timings, KeepsFirstAppearanceOrderAndAccumulates) {
  Timings t;
  t.Add("voxelise", 2.0);
  t.Add("unet", 10.0);
  t.Add("voxelise", 0.5);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t.entries()[0].first, "voxelise");
  EXPECT_EQ(t.entries()[1].first, "unet");
  EXPECT_DOUBLE_EQ(t.ms("voxelise"), 2.5);
  EXPECT_EQ(t.count("voxelise"), 2);
  EXPECT_EQ(t.count("unet"), 1);
  EXPECT_EQ(t.count("cluster"), 0);
  EXPECT_DOUBLE_EQ(t.ms("cluster"), 0.0);
  EXPECT_FALSE(t.has("cluster"));
  EXPECT_DOUBLE_EQ(t.total_ms(), 12.5);
  EXPECT_EQ(t.ToString(), "voxelise 2.5 ms, unet 10.0 ms");
  EXPECT_EQ(t.ToString(0), "voxelise 2 ms, unet 10 ms");
  int n = 0;
  for (const auto& [name, ms] : t) n += static_cast<int>(ms) + static_cast<int>(name.size());
  EXPECT_EQ(n, 2 + 8 + 10 + 4);
  t.clear();
  EXPECT_TRUE(t.empty());
  EXPECT_EQ(t.ToString(), "");
}

TEST(Timings, MergeAddsCountsAndAppendsNewNames) {
  Timings a, b;
  a.Add("x", 1.0);
  b.Add("y", 3.0);
  b.Add("x", 2.0);
  b.Add("x", 2.0);
  a.Merge(b);
  ASSERT_EQ(a.size(), 2u);
  EXPECT_EQ(a.entries()[1].first, "y");
  EXPECT_DOUBLE_EQ(a.ms("x"), 5.0);
  EXPECT_EQ(a.count("x"), 3);
  EXPECT_DOUBLE_EQ(a.ms("y"), 3.0);
}

TEST(Timings, RejectsBadInput) {
  Timings t;
  EXPECT_THROW(t.Add("", 1.0), InvalidArgument);
  EXPECT_THROW(t.Add("x", -1.0), InvalidArgument);
  EXPECT_THROW(t.Add("x", std::nan("")), InvalidArgument);
  EXPECT_TRUE(t.empty());
  EXPECT_THROW(ScopedTimer(&t, ""), InvalidArgument);
}

TEST(ScopedTimer, AddsTheElapsedTimeOfItsScope) {
  Timings t;
  {
    ScopedTimer s(&t, "sleep");
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(t.count("sleep"), 1);
  EXPECT_GE(t.ms("sleep"), 19.0);
  EXPECT_LT(t.ms("sleep"), 5000.0);
  {
    ScopedTimer s(&t, "sleep");
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_EQ(t.count("sleep"), 2);
  EXPECT_GE(t.ms("sleep"), 24.0);
}

TEST(ScopedTimer, StopRecordsOnceAndNullTimesNothing) {
  Timings t;
  {
    ScopedTimer s(&t, "a");
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    const double ms = s.Stop();
    EXPECT_GE(ms, 1.5);
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    EXPECT_EQ(s.Stop(), ms);  // the recorded value, not a new reading
  }
  EXPECT_EQ(t.count("a"), 1);
  EXPECT_LT(t.ms("a"), 25.0);  // the 30 ms after Stop() are not counted
  {
    ScopedTimer s(nullptr, "");
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    EXPECT_GT(s.Stop(), 0.0);
  }
  EXPECT_EQ(t.size(), 1u);
}

TEST(Stopwatch, IsMonotonicAndRestarts) {
  Stopwatch w;
  std::this_thread::sleep_for(std::chrono::milliseconds(10));
  const double a = w.ElapsedMs();
  EXPECT_GE(a, 9.0);
  EXPECT_NEAR(w.ElapsedSeconds(), w.ElapsedMs() * 1e-3, 1e-3);
  w.Restart();
  EXPECT_LT(w.ElapsedMs(), a);
}

}  // namespace
}  // namespace dimr
