// Lets a ROS-facing object wait for its in-flight callbacks before its members go away.
//
// roscpp's Timer::stop(), Subscriber::shutdown() and ServiceServer destruction do not wait for a
// callback that another spinner thread is executing at that moment (CallbackQueue::removeByID only
// marks it for removal when the callback's lock is taken, since the deadlock fix of ros_comm
// #2121). A node whose destructor stops a timer and then destroys the publisher that the timer's
// callback is using races with it: "Call to isLatched() on an invalid Publisher" and an abort.
// Every callback entry point holds an Entry for its whole body; the destructor calls
// CloseAndWait() before it tears anything down. Entries nest (a callback that calls another entry
// point on the same thread), and an entry taken after CloseAndWait() is empty: the callback
// returns at once. ROS-free.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <mutex>

namespace dimr::ros1 {

class CallbackGate {
 public:
  class Entry {
   public:
    explicit Entry(CallbackGate& gate) : gate_(&gate) {
      std::lock_guard<std::mutex> lock(gate_->mutex_);
      if (gate_->closed_) {
        gate_ = nullptr;
      } else {
        ++gate_->active_;
      }
    }
    ~Entry() {
      if (gate_ == nullptr) return;
      std::lock_guard<std::mutex> lock(gate_->mutex_);
      if (--gate_->active_ == 0) gate_->idle_.notify_all();
    }
    Entry(const Entry&) = delete;
    Entry& operator=(const Entry&) = delete;
    // False once the gate is closed: the callback must not touch the object.
    explicit operator bool() const { return gate_ != nullptr; }

   private:
    CallbackGate* gate_;
  };

  // Refuses new entries and blocks until every open one has ended. Must not be called from
  // inside an entry (it would wait for itself).
  void CloseAndWait() {
    std::unique_lock<std::mutex> lock(mutex_);
    closed_ = true;
    idle_.wait(lock, [this] { return active_ == 0; });
  }
  bool closed() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return closed_;
  }
  std::size_t active() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return active_;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable idle_;
  std::size_t active_ = 0;
  bool closed_ = false;
};

}  // namespace dimr::ros1
