// A small std::thread pool loop and a stderr progress bar for the evaluation.
#pragma once

#include <atomic>
#include <cstddef>
#include <functional>
#include <mutex>
#include <string>

namespace dimr::eval {

// Terminal progress bar ("label [#####     ]  45% 123/270") on stderr; silent when disabled.
// Thread-safe; redraws only when the percentage changes.
class Progress {
 public:
  Progress(std::string label, std::size_t total, bool enabled);
  ~Progress();
  void Tick(std::size_t n = 1);
  void Finish();

 private:
  std::string label_;
  std::size_t total_;
  bool enabled_;
  std::atomic<std::size_t> done_{0};
  std::mutex mu_;
  int last_percent_ = -1;
  bool finished_ = false;
};

// Runs fn(i) for i in [0, n) on `threads` threads (<= 0: hardware concurrency). Items are
// handed out dynamically. The first exception thrown by any fn is rethrown after all threads
// stop; remaining items are skipped.
void ParallelFor(std::size_t n, int threads, const std::function<void(std::size_t)>& fn,
                 Progress* progress = nullptr);

// Threads to use for `threads` (<= 0: std::thread::hardware_concurrency, at least 1).
int ResolveThreads(int threads);

}  // namespace dimr::eval
