#pragma once

#include <cstdint>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "occgeo/load/options.h"

namespace occgeo::load {

// Latency figures of one kind of request, microseconds.
struct KindReport {
  std::string kind;
  std::uint64_t completed = 0;  // answered within the measured window
  std::uint64_t errors = 0;     // answered with an Error, or lost to a connection failure
  double per_s = 0.0;
  double entries_per_s = 0.0;  // poses, rays, points or motions answered per second (batch kinds carry many)
  double p50_us = 0.0;
  double p99_us = 0.0;
  double p999_us = 0.0;
  double max_us = 0.0;
};

struct LoadReport {
  double duration_s = 0.0;  // the measured window
  std::uint32_t robots = 0;
  std::uint32_t clients = 0;
  std::uint32_t depth = 0;
  std::uint32_t observers = 0;
  std::uint32_t client_threads = 0;
  bool client_sched_batch = false;  // the query-client threads ran as SCHED_BATCH (--client-sched)
  bool robot_sched_fifo = false;    // the simulated robots' threads ran as SCHED_FIFO (--robot-sched)

  // Query clients, all kinds together.
  std::uint64_t queries = 0;
  double queries_per_s = 0.0;
  double p50_us = 0.0;
  double p99_us = 0.0;
  double p999_us = 0.0;
  std::vector<KindReport> kinds;  // one per kind in the mix, then the observers' polls

  // Every error: server Errors to queries, robots and observers, connection failures, timeouts.
  std::uint64_t errors = 0;
  std::vector<std::string> error_samples;  // the first few, verbatim

  // Simulated robots: sensor messages acknowledged, and the time from sending a sensor batch to its ScanAck.
  std::uint64_t scans = 0;
  double scans_per_s = 0.0;
  double ingest_mean_us = 0.0;
  double ingest_p50_us = 0.0;
  double ingest_p99_us = 0.0;
  // The control loop: the time from sending a steering scan to the MotionCommand answering it (not its ScanAck).
  std::uint64_t commands = 0;
  double command_p50_us = 0.0;
  double command_p99_us = 0.0;

  std::uint64_t observer_polls = 0;
  std::uint64_t observer_events = 0;  // WatchEvents received in the window
  // Watch events the server dropped for the observers (WatchEvent.dropped_since_last); unset without observers
  // or with --no-watch.
  std::optional<std::uint64_t> observer_dropped;

  // The server process (when started here or named by --server-pid): CPU in cores over the window (1.0 = one
  // core busy), resident memory at the end and its peak, kB.
  bool server_measured = false;
  double server_cpu_cores = 0.0;
  std::uint64_t server_rss_kb = 0;
  std::uint64_t server_peak_rss_kb = 0;
  bool server_alive = true;       // false: the server exited or stopped answering during the run
  double client_cpu_cores = 0.0;  // this tool's own CPU (robots, clients, observers)
};

// Runs the load described by `options`, printing a progress line a second on `progress` (when enabled).
// Throws std::runtime_error when the server cannot be started or reached at all.
LoadReport run_load(const LoadOptions& options, std::ostream& progress);

// One JSON object.
std::string report_json(const LoadReport& report);
// A few lines for people.
std::string report_text(const LoadReport& report);

}  // namespace occgeo::load
