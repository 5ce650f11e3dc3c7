// A bounded hand-over queue between ROS callbacks and the node's worker thread. With capacity 1
// it is "newest wins": a cloud that arrives while the previous one still waits replaces it
// (and is counted as dropped) - accumulated clouds supersede each other. With a larger capacity
// (per-frame scans, which must all be integrated) the oldest job is dropped when it is full.
// Push never blocks; Pop blocks until a job, Stop() or the timeout. ROS-free.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>

namespace dimr::ros1 {

template <typename T>
class JobQueue {
 public:
  explicit JobQueue(std::size_t capacity) : capacity_(capacity < 1 ? 1 : capacity) {}

  // Returns true when an older job was dropped to make room.
  bool Push(T job) {
    bool dropped = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stopped_) return false;
      if (jobs_.size() >= capacity_) {
        jobs_.pop_front();
        ++dropped_;
        dropped = true;
      }
      jobs_.push_back(std::move(job));
      ++pushed_;
    }
    cv_.notify_one();
    return dropped;
  }

  // Waits up to `timeout` for a job; false on timeout or after Stop().
  bool Pop(T* job, std::chrono::milliseconds timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (!cv_.wait_for(lock, timeout, [&] { return stopped_ || !jobs_.empty(); })) return false;
    if (stopped_) return false;
    *job = std::move(jobs_.front());
    jobs_.pop_front();
    return true;
  }

  void Stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopped_ = true;
      jobs_.clear();
    }
    cv_.notify_all();
  }
  void Clear() {
    std::lock_guard<std::mutex> lock(mutex_);
    jobs_.clear();
  }
  std::size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return jobs_.size();
  }
  std::size_t dropped() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return dropped_;
  }
  std::size_t pushed() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return pushed_;
  }
  std::size_t capacity() const { return capacity_; }

 private:
  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<T> jobs_;
  std::size_t dropped_ = 0, pushed_ = 0;
  bool stopped_ = false;
};

}  // namespace dimr::ros1
