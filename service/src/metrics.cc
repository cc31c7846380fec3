#include "metrics.h"

#include <bit>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>

namespace occgeo::service::metrics {

namespace {

enum class Type { counter, gauge, histogram };

const char* type_name(Type type) {
  switch (type) {
    case Type::counter:
      return "counter";
    case Type::gauge:
      return "gauge";
    case Type::histogram:
      return "histogram";
  }
  return "untyped";
}

// Descriptions of the families the server itself updates, so call sites need not repeat them.
const std::map<std::string, std::string, std::less<>>& builtin_help() {
  static const std::map<std::string, std::string, std::less<>> help = {
      {"occgeo_scans_ingested_total", "Sensor messages accepted into a world's models, per robot, world and kind."},
      {"occgeo_scans_rejected_total", "Sensor messages refused (validation or order), per robot."},
      {"occgeo_scans_duplicate_total",
       "Sensor messages resent after they were journalled: acknowledged again, not applied twice, per robot."},
      {"occgeo_queries_total", "Queries received, per kind."},
      {"occgeo_query_duration_seconds",
       "Time a query takes on the query pool, from its snapshot to its reply being queued, per kind."},
      {"occgeo_sessions_opened_total", "TCP protocol connections accepted."},
      {"occgeo_sessions", "Open protocol sessions, per role (sessions before their hello are not counted)."},
      {"occgeo_slow_clients_dropped_total",
       "Protocol sessions closed because their unread replies exceeded the limit."},
      {"occgeo_observer_messages_dropped_total",
       "Messages to observers dropped because the observer read too slowly, per channel."},
      {"occgeo_guard_interventions_total", "Times the safety guard changed a robot's command, per robot."},
      {"occgeo_http_requests_total", "HTTP requests served, per path and status code."},
      {"occgeo_web_clients", "Open web view WebSocket connections."},
  };
  return help;
}

bool valid_name(std::string_view name) {
  if (name.empty()) return false;
  for (std::size_t i = 0; i < name.size(); ++i) {
    const char c = name[i];
    const bool alpha = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || c == ':';
    const bool digit = c >= '0' && c <= '9';
    if (!alpha && !(digit && i > 0)) return false;
  }
  return true;
}

std::string escape_label_value(const std::string& value) {
  std::string out;
  out.reserve(value.size());
  for (const char c : value) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '"') {
      out += "\\\"";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out;
}

std::string escape_help(std::string_view help) {
  std::string out;
  for (const char c : help) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out;
}

// `{a="x",b="y"}`, with `extra` (e.g. le) last; empty when there are no labels at all.
std::string label_text(const Labels& labels, const std::string& extra = {}) {
  if (labels.empty() && extra.empty()) return {};
  std::string out = "{";
  bool first = true;
  for (const auto& [name, value] : labels) {
    if (!first) out += ',';
    first = false;
    out += name + "=\"" + escape_label_value(value) + "\"";
  }
  if (!extra.empty()) {
    if (!first) out += ',';
    out += extra;
  }
  return out + "}";
}

std::string number_text(double value) {
  if (std::isinf(value)) return value > 0 ? "+Inf" : "-Inf";
  if (std::isnan(value)) return "NaN";
  std::ostringstream out;
  out.precision(17);
  out << value;
  return out.str();
}

struct Entry {
  Labels labels;
  std::unique_ptr<Counter> counter;
  std::unique_ptr<Gauge> gauge;
  std::unique_ptr<Histogram> histogram;
};

void check_names(std::string_view name, const Labels& labels) {
  if (!valid_name(name))
    throw std::logic_error("metric name '" + std::string(name) + "' is not a valid Prometheus name");
  for (const auto& [label, value] : labels) {
    if (!valid_name(label) || label.find(':') != std::string::npos || label == "le") {
      throw std::logic_error("metric '" + std::string(name) + "': label name '" + label + "' is not allowed");
    }
  }
}

}  // namespace

struct Registry::Family {
  Type type = Type::counter;
  std::string help;
  std::map<std::string, Entry> entries;  // by label text

  // The entry of these labels, created on first use; the caller holds the registry's mutex.
  Entry& entry(const Labels& labels, Type entry_type);
};

Registry::Registry() = default;
Registry::~Registry() = default;

namespace {

template <class Families>
Entry& find_or_add(Families& families, std::string_view name, const Labels& labels, std::string_view help, Type type) {
  check_names(name, labels);
  auto family_it = families.find(name);
  if (family_it == families.end()) {
    typename Families::mapped_type family;
    family.type = type;
    const auto known = builtin_help().find(name);
    family.help =
        help.empty() ? (known != builtin_help().end() ? known->second : std::string(name)) : std::string(help);
    family_it = families.emplace(std::string(name), std::move(family)).first;
  } else if (family_it->second.type != type) {
    throw std::logic_error("metric '" + std::string(name) + "' is a " + type_name(family_it->second.type) + ", not a " +
                           type_name(type));
  }
  return family_it->second.entry(labels, type);
}

}  // namespace

Entry& Registry::Family::entry(const Labels& labels, Type entry_type) {
  auto [entry_it, added] = entries.try_emplace(label_text(labels));
  if (added) {
    entry_it->second.labels = labels;
    switch (entry_type) {
      case Type::counter:
        entry_it->second.counter = std::make_unique<Counter>();
        break;
      case Type::gauge:
        entry_it->second.gauge = std::make_unique<Gauge>();
        break;
      case Type::histogram:
        entry_it->second.histogram = std::make_unique<Histogram>();
        break;
    }
  }
  return entry_it->second;
}

std::size_t detail::this_thread_slot() {
  static std::atomic<std::size_t> next{0};
  thread_local const std::size_t slot = next.fetch_add(1, std::memory_order_relaxed) % kSlots;
  return slot;
}

std::uint64_t Counter::value() const {
  std::uint64_t total = 0;
  for (const Slot& slot : slots_) total += slot.value.load(std::memory_order_relaxed);
  return total;
}

void Histogram::observe(double value) {
  std::size_t bucket = 0;
  while (bucket < kLatencyBounds.size() && value > kLatencyBounds[bucket]) ++bucket;
  Slot& slot = slots_[detail::this_thread_slot()];
  slot.buckets[bucket].fetch_add(1, std::memory_order_relaxed);
  std::uint64_t old_bits = slot.sum_bits.load(std::memory_order_relaxed);
  while (!slot.sum_bits.compare_exchange_weak(
      old_bits, std::bit_cast<std::uint64_t>(std::bit_cast<double>(old_bits) + value), std::memory_order_relaxed)) {
  }
  slot.count.fetch_add(1, std::memory_order_relaxed);
}

std::array<std::uint64_t, Histogram::kLatencyBounds.size() + 1> Histogram::bucket_counts() const {
  std::array<std::uint64_t, kLatencyBounds.size() + 1> counts{};
  for (const Slot& slot : slots_) {
    for (std::size_t i = 0; i < counts.size(); ++i) counts[i] += slot.buckets[i].load(std::memory_order_relaxed);
  }
  return counts;
}

std::uint64_t Histogram::count() const {
  std::uint64_t total = 0;
  for (const Slot& slot : slots_) total += slot.count.load(std::memory_order_relaxed);
  return total;
}

double Histogram::sum() const {
  double total = 0.0;
  for (const Slot& slot : slots_) total += std::bit_cast<double>(slot.sum_bits.load(std::memory_order_relaxed));
  return total;
}

Counter& Registry::counter(std::string_view name, const Labels& labels, std::string_view help) {
  const std::lock_guard lock(mutex_);
  return *find_or_add(families_, name, labels, help, Type::counter).counter;
}

Gauge& Registry::gauge(std::string_view name, const Labels& labels, std::string_view help) {
  const std::lock_guard lock(mutex_);
  return *find_or_add(families_, name, labels, help, Type::gauge).gauge;
}

Histogram& Registry::histogram(std::string_view name, const Labels& labels, std::string_view help) {
  const std::lock_guard lock(mutex_);
  return *find_or_add(families_, name, labels, help, Type::histogram).histogram;
}

std::string Registry::render() const {
  const std::lock_guard lock(mutex_);
  std::string out;
  for (const auto& [name, family] : families_) {
    out += "# HELP " + name + " " + escape_help(family.help) + "\n";
    out += "# TYPE " + name + " " + type_name(family.type) + "\n";
    for (const auto& [key, entry] : family.entries) {
      switch (family.type) {
        case Type::counter:
          out += name + key + " " + std::to_string(entry.counter->value()) + "\n";
          break;
        case Type::gauge:
          out += name + key + " " + std::to_string(entry.gauge->value()) + "\n";
          break;
        case Type::histogram: {
          // Read the buckets first and derive the count from them, so the exposition is self-consistent even while
          // observations arrive (the sum may lag by the observations in flight).
          const auto counts = entry.histogram->bucket_counts();
          std::uint64_t cumulative = 0;
          for (std::size_t i = 0; i < counts.size(); ++i) {
            cumulative += counts[i];
            const std::string le =
                i < Histogram::kLatencyBounds.size() ? number_text(Histogram::kLatencyBounds[i]) : "+Inf";
            out += name + "_bucket" + label_text(entry.labels, "le=\"" + le + "\"") + " " + std::to_string(cumulative) +
                   "\n";
          }
          out += name + "_sum" + key + " " + number_text(entry.histogram->sum()) + "\n";
          out += name + "_count" + key + " " + std::to_string(cumulative) + "\n";
          break;
        }
      }
    }
  }
  return out;
}

ScopedTimer::ScopedTimer(Histogram& histogram)
    : histogram_(histogram),
      start_ns_(
          std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
              .count()) {}

ScopedTimer::~ScopedTimer() {
  const std::int64_t now_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
  histogram_.observe(static_cast<double>(now_ns - start_ns_) * 1e-9);
}

}  // namespace occgeo::service::metrics
