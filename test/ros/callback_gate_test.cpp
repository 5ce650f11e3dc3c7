// CallbackGate: the destructor-side wait for in-flight ROS callbacks (callback_gate.h).
#include "dimr/ros/callback_gate.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

namespace dimr::ros1 {
namespace {

using namespace std::chrono_literals;

TEST(CallbackGate, CloseWaitsForTheRunningCallbackAndRefusesNewOnes) {
  CallbackGate gate;
  std::atomic<bool> inside{false}, finished{false};
  std::thread callback([&] {
    const CallbackGate::Entry entry(gate);
    ASSERT_TRUE(entry);
    inside = true;
    std::this_thread::sleep_for(150ms);  // e.g. publishing diagnostics
    finished = true;
  });
  while (!inside) std::this_thread::sleep_for(1ms);
  const auto t0 = std::chrono::steady_clock::now();
  gate.CloseAndWait();
  // The callback's body completed before CloseAndWait returned: tearing down is safe now.
  EXPECT_TRUE(finished.load());
  EXPECT_GE(std::chrono::steady_clock::now() - t0, 100ms);
  EXPECT_EQ(gate.active(), 0u);
  EXPECT_TRUE(gate.closed());
  const CallbackGate::Entry late(gate);
  EXPECT_FALSE(late) << "an entry after CloseAndWait must be empty";
  EXPECT_EQ(gate.active(), 0u);
  callback.join();
  gate.CloseAndWait();  // again: returns at once
}

TEST(CallbackGate, EntriesNestAndCountManyThreads) {
  CallbackGate gate;
  {
    const CallbackGate::Entry outer(gate);
    const CallbackGate::Entry inner(gate);  // a callback calling another entry point
    EXPECT_TRUE(outer);
    EXPECT_TRUE(inner);
    EXPECT_EQ(gate.active(), 2u);
  }
  EXPECT_EQ(gate.active(), 0u);
  std::atomic<int> done{0};
  std::atomic<bool> go{false};
  std::vector<std::thread> threads;
  for (int t = 0; t < 6; ++t) {
    threads.emplace_back([&] {
      while (!go) std::this_thread::yield();
      for (int i = 0; i < 2000; ++i) {
        const CallbackGate::Entry e(gate);
        if (!e) return;
        ++done;
      }
    });
  }
  go = true;
  std::this_thread::sleep_for(2ms);
  gate.CloseAndWait();
  const int at_close = done.load();
  std::this_thread::sleep_for(20ms);
  EXPECT_EQ(done.load(), at_close) << "work happened after the gate closed";
  EXPECT_EQ(gate.active(), 0u);
  for (auto& th : threads) th.join();
}

}  // namespace
}  // namespace dimr::ros1
