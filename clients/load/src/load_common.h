#pragma once

// What the load tool's parts share: the clock, the error log every thread writes to, setting a thread's scheduling
// policy, and latency samples.

#include <sched.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <mutex>
#include <string>
#include <vector>

namespace occgeo::load::internal {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

inline constexpr std::size_t kMaxErrorSamples = 8;
inline constexpr auto kDrainLimit = std::chrono::seconds(5);
inline constexpr auto kLockstepAnswerTimeout = std::chrono::seconds(10);
inline constexpr const char* kSeedRobotId = "load-seed";

// Errors from every thread: a count and the first few messages.
class ErrorLog {
 public:
  void add(const std::string& text) {
    count_.fetch_add(1, std::memory_order_relaxed);
    const std::lock_guard lock(mutex_);
    if (samples_.size() < kMaxErrorSamples) samples_.push_back(text);
  }
  [[nodiscard]] std::uint64_t count() const { return count_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::vector<std::string> samples() const {
    const std::lock_guard lock(mutex_);
    return samples_;
  }

 private:
  std::atomic<std::uint64_t> count_{0};
  mutable std::mutex mutex_;
  std::vector<std::string> samples_;
};

// Puts the calling thread (only it, on Linux) under `policy` at `priority`; an error naming `option` when it may not.
inline void set_this_threads_policy(int policy, int priority, const std::string& option, ErrorLog& errors) {
  sched_param param{};
  param.sched_priority = priority;
  if (sched_setscheduler(0, policy, &param) != 0) errors.add(option + ": " + std::strerror(errno));
}

// Latency samples, nanoseconds.
using Samples = std::vector<std::uint64_t>;

inline void add_sample(Samples& samples, std::chrono::nanoseconds latency) {
  samples.push_back(static_cast<std::uint64_t>(std::max<std::int64_t>(latency.count(), 0)));
}

// The q-quantile of sorted samples, microseconds.
inline double quantile_us(const Samples& sorted, double q) {
  if (sorted.empty()) return 0.0;
  const auto index = static_cast<std::size_t>(std::ceil(q * static_cast<double>(sorted.size()))) - 1;
  return static_cast<double>(sorted[std::min(index, sorted.size() - 1)]) / 1000.0;
}

}  // namespace occgeo::load::internal
