#include "dimr/core/parallel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

namespace dimr {
namespace {

TEST(Parallel, ResolveThreads) {
  EXPECT_GE(HardwareThreads(), 1);
  EXPECT_EQ(ResolveThreads(3), 3);
  EXPECT_EQ(ResolveThreads(0), HardwareThreads());
  EXPECT_EQ(ResolveThreads(-2), HardwareThreads());
}

TEST(Parallel, ForVisitsEveryIndexOnceOnTheAskedThreads) {
  for (const int threads : {1, 2, 4, 7}) {
    std::vector<std::atomic<int>> hits(1000);
    std::mutex mu;
    std::set<std::thread::id> ids;
    std::atomic<int> done{0};
    ParallelFor(
        hits.size(), threads,
        [&](std::size_t i) {
          hits[i]++;
          std::lock_guard<std::mutex> lock(mu);
          ids.insert(std::this_thread::get_id());
        },
        [&] { done++; });
    for (const auto& h : hits) ASSERT_EQ(h.load(), 1);
    EXPECT_EQ(done.load(), 1000);
    EXPECT_LE(ids.size(), static_cast<std::size_t>(threads));
    if (threads == 1) {
      EXPECT_EQ(*ids.begin(), std::this_thread::get_id());  // inline on the caller
    }
  }
  int calls = 0;
  ParallelFor(0, 4, [&](std::size_t) { ++calls; });
  EXPECT_EQ(calls, 0);
}

TEST(Parallel, ForRethrowsTheFirstErrorAndStops) {
  // Items after 10 wait until item 10 is about to throw, then take 20 us each: the other workers
  // cannot run out the 100000 items (>= 1 s) before the error stops them, even if the throwing
  // thread is descheduled for a while on a loaded machine (CI saw ran == 100000 with trivial
  // items).
  std::atomic<int> ran{0};
  std::atomic<bool> throwing{false};
  EXPECT_THROW(ParallelFor(100000, 3,
                           [&](std::size_t i) {
                             ran++;
                             if (i == 10) {
                               throwing = true;
                               throw std::runtime_error("item 10");
                             }
                             if (i > 10) {
                               while (!throwing) std::this_thread::yield();
                               std::this_thread::sleep_for(std::chrono::microseconds(20));
                             }
                           }),
               std::runtime_error);
  EXPECT_LT(ran.load(), 100000);  // later items were skipped
  try {
    ParallelFor(5, 1, [](std::size_t i) {
      if (i >= 2) throw std::invalid_argument("item " + std::to_string(i));
    });
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "item 2");  // one thread: in order, the first one
  }
}

TEST(Parallel, RangesCoverEverythingInContiguousChunks) {
  for (const std::size_t n : {std::size_t{1}, std::size_t{999}, std::size_t{10000}}) {
    std::vector<int> hits(n, 0);
    std::mutex mu;
    std::vector<std::pair<std::size_t, std::size_t>> ranges;
    ParallelRanges(n, 3, 1000, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) hits[i]++;
      std::lock_guard<std::mutex> lock(mu);
      ranges.emplace_back(b, e);
    });
    for (int h : hits) ASSERT_EQ(h, 1);
    // ceil(n / 1000) chunks at most, 3 threads at most.
    EXPECT_LE(ranges.size(), std::min<std::size_t>(3, (n + 999) / 1000));
  }
  EXPECT_THROW(ParallelRanges(10000, 2, 1,
                              [](std::size_t b, std::size_t) {
                                if (b > 0) throw std::runtime_error("second range");
                              }),
               std::runtime_error);
  int calls = 0;
  ParallelRanges(0, 2, 0, [&](std::size_t, std::size_t) { ++calls; });
  EXPECT_EQ(calls, 0);
}

}  // namespace
}  // namespace dimr
