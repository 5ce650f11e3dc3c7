#include "dimr/eval/parallel.h"

#include <cstdio>
#include <exception>
#include <thread>
#include <vector>

namespace dimr::eval {

Progress::Progress(std::string label, std::size_t total, bool enabled)
    : label_(std::move(label)), total_(total), enabled_(enabled) {}

Progress::~Progress() { Finish(); }

void Progress::Tick(std::size_t n) {
  const std::size_t done = done_.fetch_add(n) + n;
  if (!enabled_ || total_ == 0) return;
  const int percent = static_cast<int>(100 * std::min(done, total_) / total_);
  std::lock_guard<std::mutex> lock(mu_);
  if (percent == last_percent_ || finished_) return;
  last_percent_ = percent;
  const int width = 30;
  const int fill = percent * width / 100;
  std::string bar(static_cast<std::size_t>(fill), '#');
  bar.append(static_cast<std::size_t>(width - fill), ' ');
  std::fprintf(stderr, "\r%-22s [%s] %3d%% %zu/%zu", label_.c_str(), bar.c_str(), percent,
               std::min(done, total_), total_);
  std::fflush(stderr);
}

void Progress::Finish() {
  std::lock_guard<std::mutex> lock(mu_);
  if (!enabled_ || finished_) return;
  finished_ = true;
  if (last_percent_ >= 0) std::fprintf(stderr, "\n");
}

int ResolveThreads(int threads) {
  if (threads > 0) return threads;
  const unsigned hc = std::thread::hardware_concurrency();
  return hc > 0 ? static_cast<int>(hc) : 1;
}

void ParallelFor(std::size_t n, int threads, const std::function<void(std::size_t)>& fn,
                 Progress* progress) {
  const int nt = static_cast<int>(std::min<std::size_t>(ResolveThreads(threads), n));
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex error_mu;
  auto worker = [&]() {
    while (!failed.load()) {
      const std::size_t i = next.fetch_add(1);
      if (i >= n) break;
      try {
        fn(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mu);
        if (!error) error = std::current_exception();
        failed = true;
      }
      if (progress) progress->Tick();
    }
  };
  if (nt <= 1) {
    worker();
  } else {
    std::vector<std::thread> pool;
    for (int t = 0; t < nt; ++t) pool.emplace_back(worker);
    for (auto& th : pool) th.join();
  }
  if (error) std::rethrow_exception(error);
}

}  // namespace dimr::eval
