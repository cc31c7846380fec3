#pragma once

// A server's metrics in the Prometheus text exposition format (served at GET /metrics). Each ServerCore owns its
// registry, so two servers in one process count apart:
//
//   core.metrics().counter("occgeo_guard_interventions_total", {{"robot", id}}).inc();
//   core.metrics().histogram("occgeo_query_duration_seconds", {{"kind", "collision"}}).observe(seconds);
//
// Looking a metric up takes the registry's mutex (keep the reference where it is hot, or use a NumberedFamily);
// updating it is a relaxed atomic on a slot of the updating thread's own (one cache line per slot, summed when read),
// so ingest and query threads never wait for a scrape nor bounce a cache line between them. References stay
// valid for the life of the registry. Names follow Prometheus conventions: counters end in _total,
// durations are in seconds.

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <type_traits>
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

// Every metric of one server. Not copyable: metrics hold references into it.
class Registry {
 public:
  Registry();
  ~Registry();
  Registry(const Registry&) = delete;
  Registry& operator=(const Registry&) = delete;

  // The metric with this name and labels, created (at zero) on first use. `help` describes the family the first time
  // it is given (known families have their description built in). Throws std::logic_error when the name is already
  // used by a metric of another type, or is not a valid Prometheus name.
  Counter& counter(std::string_view name, const Labels& labels = {}, std::string_view help = {});
  Gauge& gauge(std::string_view name, const Labels& labels = {}, std::string_view help = {});
  Histogram& histogram(std::string_view name, const Labels& labels = {}, std::string_view help = {});

  // Every metric in the text exposition format 0.0.4, families sorted by name.
  [[nodiscard]] std::string render() const;

 private:
  struct Family;
  mutable std::mutex mutex_;
  std::map<std::string, Family, std::less<>> families_;
};

// Counters or histograms of one family told apart by one label whose values are numbered below Count (a message
// body's field number): after a number's first use its metric is found without the registry's mutex, for updates
// on every request.
template <class Metric, std::size_t Count>
class NumberedFamily {
 public:
  NumberedFamily(Registry& registry, std::string name, std::string label)
      : registry_(registry), name_(std::move(name)), label_(std::move(label)) {}

  // The metric of `number`, whose label value is `label_value`; numbers at or above Count are looked up each time.
  Metric& at(std::size_t number, std::string_view label_value) {
    if (number >= Count) return lookup(label_value);
    Metric* metric = slots_[number].load(std::memory_order_acquire);
    if (metric == nullptr) {
      metric = &lookup(label_value);  // racing threads find the same metric
      slots_[number].store(metric, std::memory_order_release);
    }
    return *metric;
  }

 private:
  Metric& lookup(std::string_view label_value) {
    const Labels labels = {{label_, std::string(label_value)}};
    if constexpr (std::is_same_v<Metric, Counter>) {
      return registry_.counter(name_, labels);
    } else {
      return registry_.histogram(name_, labels);
    }
  }

  Registry& registry_;
  std::string name_;
  std::string label_;
  std::array<std::atomic<Metric*>, Count> slots_{};
};

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
