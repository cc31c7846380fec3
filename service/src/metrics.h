#pragma once

// Process-wide metrics in the Prometheus text exposition format (served at GET /metrics).
//
//   metrics::counter("occgeo_guard_interventions_total", {{"robot", id}}).inc();
//   metrics::histogram("occgeo_query_duration_seconds", {{"kind", "collision"}}).observe(seconds);
//
// Looking a metric up takes a mutex (once per name and label set: keep the reference where it is hot);
// updating it is a relaxed atomic on a slot of the updating thread's own (one cache line per slot, summed when read),
// so ingest and query threads never wait for a scrape nor bounce a cache line between them. References stay
// valid for the life of the process. Names follow Prometheus conventions: counters end in _total,
// durations are in seconds.

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace occgeo::service::metrics {

// Label name/value pairs; the order given is the order shown.
using Labels = std::vector<std::pair<std::string, std::string>>;

namespace detail {
// Slots per counter and histogram: threads take them in turn, so up to this many threads update without sharing.
inline constexpr std::size_t kSlots = 8;
// The calling thread's slot.
std::size_t this_thread_slot();
}  // namespace detail

// A value that only goes up.
class Counter {
 public:
  void inc(std::uint64_t amount = 1) {
    slots_[detail::this_thread_slot()].value.fetch_add(amount, std::memory_order_relaxed);
  }
  [[nodiscard]] std::uint64_t value() const;

 private:
  struct alignas(64) Slot {
    std::atomic<std::uint64_t> value{0};
  };
  std::array<Slot, detail::kSlots> slots_{};
};

// A value that goes up and down (sessions open, queue depth).
class Gauge {
 public:
  void inc(std::int64_t amount = 1) { value_.fetch_add(amount, std::memory_order_relaxed); }
  void dec(std::int64_t amount = 1) { value_.fetch_sub(amount, std::memory_order_relaxed); }
  void set(std::int64_t value) { value_.store(value, std::memory_order_relaxed); }
  [[nodiscard]] std::int64_t value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<std::int64_t> value_{0};
};

// Observations counted into fixed buckets (upper bounds, seconds for durations), with their sum.
class Histogram {
 public:
  // Bounds from 10 µs to 10 s: a grid query takes microseconds, a whole-grid reply milliseconds.
  static constexpr std::array<double, 13> kLatencyBounds = {1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2,
                                                            3e-2, 0.1,  0.3,  1.0,  3.0,  10.0};
  void observe(double value);
  // Per bucket (not cumulative), the last one for values above every bound (+Inf).
  [[nodiscard]] std::array<std::uint64_t, kLatencyBounds.size() + 1> bucket_counts() const;
  [[nodiscard]] std::uint64_t count() const;
  [[nodiscard]] double sum() const;

 private:
  struct alignas(64) Slot {
    std::array<std::atomic<std::uint64_t>, kLatencyBounds.size() + 1> buckets{};
    std::atomic<std::uint64_t> count{0};
    std::atomic<std::uint64_t> sum_bits{0};  // a double, updated by compare-exchange
  };
  std::array<Slot, detail::kSlots> slots_{};
};

// The metric with this name and labels, created (at zero) on first use. `help` describes the family the
// first time it is given (known families have their description built in). Throws std::logic_error when
// the name is already used by a metric of another type, or is not a valid Prometheus name.
Counter& counter(std::string_view name, const Labels& labels = {}, std::string_view help = {});
Gauge& gauge(std::string_view name, const Labels& labels = {}, std::string_view help = {});
Histogram& histogram(std::string_view name, const Labels& labels = {}, std::string_view help = {});

// Every metric in the text exposition format 0.0.4, families sorted by name.
[[nodiscard]] std::string render();

// Measures from construction to destruction into a histogram (seconds).
class ScopedTimer {
 public:
  explicit ScopedTimer(Histogram& histogram);
  ~ScopedTimer();
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;

 private:
  Histogram& histogram_;
  std::int64_t start_ns_;
};

}  // namespace occgeo::service::metrics
