// The worker hand-over queue: newest wins with capacity 1, oldest dropped when full, Push
// never blocks while a consumer is busy, Stop wakes a waiting consumer.
#include "dimr/ros/job_queue.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

namespace dimr::ros1 {
namespace {

using namespace std::chrono_literals;

TEST(JobQueue, NewestWins) {
  JobQueue<int> q(1);
  EXPECT_FALSE(q.Push(1));
  EXPECT_TRUE(q.Push(2));
  EXPECT_TRUE(q.Push(3));
  int v = 0;
  ASSERT_TRUE(q.Pop(&v, 10ms));
  EXPECT_EQ(v, 3);
  EXPECT_EQ(q.dropped(), 2u);
  EXPECT_EQ(q.pushed(), 3u);
  EXPECT_FALSE(q.Pop(&v, 10ms));
}

TEST(JobQueue, BoundedFifoDropsOldest) {
  JobQueue<int> q(3);
  for (int i = 0; i < 5; ++i) q.Push(i);
  EXPECT_EQ(q.size(), 3u);
  EXPECT_EQ(q.dropped(), 2u);
  int v = 0;
  for (int want : {2, 3, 4}) {
    ASSERT_TRUE(q.Pop(&v, 10ms));
    EXPECT_EQ(v, want);
  }
}

TEST(JobQueue, ProducerNeverBlocksOnABusyConsumerAndStopWakes) {
  JobQueue<int> q(1);
  std::atomic<int> consumed{0}, last{-1};
  std::thread worker([&] {
    int v;
    while (q.Pop(&v, 1000ms)) {
      std::this_thread::sleep_for(50ms);  // "inference"
      last = v;
      ++consumed;
    }
  });
  // A burst of 200 pushes at full speed while the consumer sleeps: all return at once.
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 200; ++i) q.Push(i);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(ms, 40.0);  // far less than one 50 ms consumer step
  std::this_thread::sleep_for(250ms);
  EXPECT_EQ(last.load(), 199);    // the newest one was processed
  EXPECT_LE(consumed.load(), 3);  // at most: one in flight, then the newest
  EXPECT_GE(q.dropped(), 197u);
  q.Stop();
  worker.join();
  EXPECT_FALSE(q.Push(5));
}

}  // namespace
}  // namespace dimr::ros1
