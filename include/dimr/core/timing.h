// Named wall-clock timings: `Timings` maps a stage name to milliseconds in the order the names
// first appeared (the order a pipeline ran its stages), `ScopedTimer` adds the time of a scope
// to one name, `Stopwatch` is a plain monotonic clock for loops that report as they go.
//
//   dimr::Timings t;
//   { dimr::ScopedTimer s(&t, "unet"); RunUnet(); }
//   { dimr::ScopedTimer s(&t, "cluster"); Cluster(); }
//   std::cout << t.ToString();   // "unet 12.3 ms, cluster 4.5 ms"
//
// A name that is timed again accumulates (its count says how often). Timings is a value type
// and not synchronised: time each thread into its own Timings and Merge them afterwards.
#pragma once

#include <chrono>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace dimr {

class Timings {
 public:
  using Entry = std::pair<std::string, double>;  // name, milliseconds
  using const_iterator = std::vector<Entry>::const_iterator;

  // Adds `ms` to `name` (appended at the end when new). Throws dimr::InvalidArgument for an
  // empty name or a negative or non-finite duration.
  void Add(const std::string& name, double ms);
  // Every entry of `other` added to this one (new names appended in other's order).
  void Merge(const Timings& other);

  bool has(const std::string& name) const;
  // Milliseconds recorded under `name`; 0 when it was never timed.
  double ms(const std::string& name) const;
  // How many times `name` was added; 0 when it was never timed.
  int count(const std::string& name) const;
  // Sum over every name.
  double total_ms() const;

  std::size_t size() const { return entries_.size(); }
  bool empty() const { return entries_.empty(); }
  const_iterator begin() const { return entries_.begin(); }
  const_iterator end() const { return entries_.end(); }
  const std::vector<Entry>& entries() const { return entries_; }
  void clear();

  // "name 1.2 ms, other 30.5 ms" (milliseconds with `decimals` digits after the point).
  std::string ToString(int decimals = 1) const;

 private:
  int Find(const std::string& name) const;

  std::vector<Entry> entries_;
  std::vector<int> counts_;
};

// Monotonic clock (std::chrono::steady_clock) started at construction or Restart().
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  void Restart() { start_ = std::chrono::steady_clock::now(); }
  double ElapsedMs() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_)
        .count();
  }
  double ElapsedSeconds() const { return ElapsedMs() * 1e-3; }

 private:
  std::chrono::steady_clock::time_point start_;
};

// Adds the milliseconds from construction to destruction (or to Stop()) to `timings[name]`.
// A null `timings` times nothing (callers that may or may not collect timings pass theirs
// through). Not copyable or movable: one timer, one scope.
class ScopedTimer {
 public:
  ScopedTimer(Timings* timings, std::string name);
  ~ScopedTimer();
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;

  // Records now instead of at destruction (once; later calls and the destructor do nothing).
  // Returns the milliseconds recorded (also when `timings` is null; the same on later calls).
  double Stop();
  double ElapsedMs() const { return clock_.ElapsedMs(); }

 private:
  Timings* timings_;
  std::string name_;
  Stopwatch clock_;
  bool stopped_ = false;
  double recorded_ms_ = 0.0;
};

}  // namespace dimr
