// The project's one parallel loop over std::thread (every layer's thread pool; the nn kernels
// keep at::parallel_for). Threads are started per call and joined before it returns: no
// global pool, nothing left running, so a caller never shares workers with another library.
//
//   dimr::ParallelFor(items.size(), jobs, [&](std::size_t i) { out[i] = Work(items[i]); });
//   dimr::ParallelRanges(n, 0, 2048, [&](std::size_t b, std::size_t e) { ... });
//
// Results must not depend on the thread count: give every index its own output slot (and its
// own seed). The first exception thrown by any call is rethrown in the caller after every
// thread has stopped.
#pragma once

#include <cstddef>
#include <functional>

namespace dimr {

// std::thread::hardware_concurrency(), at least 1.
int HardwareThreads();
// Threads to use for a request: `threads` when > 0, else HardwareThreads().
int ResolveThreads(int threads);

// fn(i) for every i in [0, n) on min(ResolveThreads(threads), n) threads (the caller's thread
// is one of them). Indices are handed out one at a time in increasing order (dynamic: uneven
// items balance). After an exception, items not yet started are skipped.
// `on_done` (optional) is called after each finished item, from the worker that ran it.
void ParallelFor(std::size_t n, int threads, const std::function<void(std::size_t)>& fn,
                 const std::function<void()>& on_done = {});

// fn(begin, end) on contiguous ranges covering [0, n): T = min(ResolveThreads(threads), 64,
// ceil(n / min_chunk)) ranges of ceil(n / T) indices (the last one shorter), one per thread,
// the first on the caller's thread. For cheap uniform items (queries, rows), where handing
// out single indices would cost more than the work. min_chunk 0 counts as 1.
void ParallelRanges(std::size_t n, int threads, std::size_t min_chunk,
                    const std::function<void(std::size_t, std::size_t)>& fn);

}  // namespace dimr
