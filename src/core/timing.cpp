#include "dimr/core/timing.h"

#include <cmath>
#include <cstdio>

#include "dimr/core/error.h"

namespace dimr {

int Timings::Find(const std::string& name) const {
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    if (entries_[i].first == name) return static_cast<int>(i);
  }
  return -1;
}

void Timings::Add(const std::string& name, double ms) {
  if (name.empty()) throw InvalidArgument("Timings::Add: empty name");
  if (!std::isfinite(ms) || ms < 0.0) {
    throw InvalidArgument("Timings::Add: duration of '" + name + "' must be finite and >= 0");
  }
  const int i = Find(name);
  if (i < 0) {
    entries_.emplace_back(name, ms);
    counts_.push_back(1);
  } else {
    entries_[i].second += ms;
    ++counts_[i];
  }
}

void Timings::Merge(const Timings& other) {
  for (std::size_t i = 0; i < other.entries_.size(); ++i) {
    const int j = Find(other.entries_[i].first);
    if (j < 0) {
      entries_.push_back(other.entries_[i]);
      counts_.push_back(other.counts_[i]);
    } else {
      entries_[j].second += other.entries_[i].second;
      counts_[j] += other.counts_[i];
    }
  }
}

bool Timings::has(const std::string& name) const { return Find(name) >= 0; }

double Timings::ms(const std::string& name) const {
  const int i = Find(name);
  return i < 0 ? 0.0 : entries_[i].second;
}

int Timings::count(const std::string& name) const {
  const int i = Find(name);
  return i < 0 ? 0 : counts_[i];
}

double Timings::total_ms() const {
  double sum = 0.0;
  for (const Entry& e : entries_) sum += e.second;
  return sum;
}

void Timings::clear() {
  entries_.clear();
  counts_.clear();
}

std::string Timings::ToString(int decimals) const {
  if (decimals < 0) decimals = 0;
  if (decimals > 9) decimals = 9;
  std::string out;
  char buf[64];
  for (const Entry& e : entries_) {
    if (!out.empty()) out += ", ";
    std::snprintf(buf, sizeof(buf), "%.*f", decimals, e.second);
    out += e.first + " " + buf + " ms";
  }
  return out;
}

ScopedTimer::ScopedTimer(Timings* timings, std::string name)
    : timings_(timings), name_(std::move(name)) {
  if (timings_ != nullptr && name_.empty()) throw InvalidArgument("ScopedTimer: empty name");
}

ScopedTimer::~ScopedTimer() {
  if (!stopped_ && timings_ != nullptr) timings_->Add(name_, clock_.ElapsedMs());
}

double ScopedTimer::Stop() {
  if (stopped_) return recorded_ms_;
  stopped_ = true;
  recorded_ms_ = clock_.ElapsedMs();
  if (timings_ != nullptr) timings_->Add(name_, recorded_ms_);
  return recorded_ms_;
}

}  // namespace dimr
