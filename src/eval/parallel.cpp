#include "dimr/eval/parallel.h"

#include <algorithm>
#include <cstdio>
#include <utility>

#include "dimr/core/parallel.h"

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

int ResolveThreads(int threads) { return dimr::ResolveThreads(threads); }

void ParallelFor(std::size_t n, int threads, const std::function<void(std::size_t)>& fn,
                 Progress* progress) {
  if (progress == nullptr) {
    dimr::ParallelFor(n, threads, fn);
  } else {
    dimr::ParallelFor(n, threads, fn, [progress] { progress->Tick(); });
  }
}

}  // namespace dimr::eval
