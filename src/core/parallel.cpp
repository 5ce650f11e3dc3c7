#include "dimr/core/parallel.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace dimr {
namespace {

// Collects the first exception of several threads.
class FirstError {
 public:
  void Capture() {
    std::lock_guard<std::mutex> lock(mu_);
    if (!error_) error_ = std::current_exception();
    failed_.store(true);
  }
  bool failed() const { return failed_.load(); }
  void Rethrow() {
    if (error_) std::rethrow_exception(error_);
  }

 private:
  std::mutex mu_;
  std::exception_ptr error_;
  std::atomic<bool> failed_{false};
};

}  // namespace

int HardwareThreads() {
  const unsigned hc = std::thread::hardware_concurrency();
  return hc > 0 ? static_cast<int>(hc) : 1;
}

int ResolveThreads(int threads) { return threads > 0 ? threads : HardwareThreads(); }

void ParallelFor(std::size_t n, int threads, const std::function<void(std::size_t)>& fn,
                 const std::function<void()>& on_done) {
  if (n == 0) return;
  const std::size_t nt =
      std::min<std::size_t>(static_cast<std::size_t>(ResolveThreads(threads)), n);
  std::atomic<std::size_t> next{0};
  FirstError error;
  auto worker = [&]() {
    while (!error.failed()) {
      const std::size_t i = next.fetch_add(1);
      if (i >= n) break;
      try {
        fn(i);
        if (on_done) on_done();
      } catch (...) {
        error.Capture();
      }
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(nt - 1);
  try {
    for (std::size_t t = 1; t < nt; ++t) pool.emplace_back(worker);
  } catch (...) {
    error.Capture();  // could not start a thread: the started ones stop after their item
  }
  worker();
  for (std::thread& th : pool) th.join();
  error.Rethrow();
}

void ParallelRanges(std::size_t n, int threads, std::size_t min_chunk,
                    const std::function<void(std::size_t, std::size_t)>& fn) {
  if (n == 0) return;
  min_chunk = std::max<std::size_t>(min_chunk, 1);
  const std::size_t nt = std::min<std::size_t>(
      {static_cast<std::size_t>(ResolveThreads(threads)), 64, (n + min_chunk - 1) / min_chunk});
  if (nt <= 1) {
    fn(0, n);
    return;
  }
  const std::size_t chunk = (n + nt - 1) / nt;
  FirstError error;
  auto run = [&](std::size_t b, std::size_t e) {
    try {
      if (b < e) fn(b, e);
    } catch (...) {
      error.Capture();
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(nt - 1);
  try {
    for (std::size_t t = 1; t < nt; ++t) {
      const std::size_t b = std::min(n, t * chunk);
      pool.emplace_back(run, b, std::min(n, b + chunk));
    }
  } catch (...) {
    error.Capture();
  }
  run(0, std::min(n, chunk));
  for (std::thread& th : pool) th.join();
  error.Rethrow();
}

}  // namespace dimr
