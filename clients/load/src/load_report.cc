// occgeo-load's report as JSON (--json) or text.
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>

#include "occgeo/client/json.h"
#include "occgeo/load/load_run.h"

namespace occgeo::load {

namespace {

std::string json_number(double value) {
  if (!std::isfinite(value)) return "null";
  char text[64];
  std::snprintf(text, sizeof text, "%.6g", value);
  return text;
}

using client::json_string;

}  // namespace

std::string report_json(const LoadReport& report) {
  std::ostringstream out;
  out << "{\"duration_s\":" << json_number(report.duration_s) << ",\"robots\":" << report.robots
      << ",\"clients\":" << report.clients << ",\"depth\":" << report.depth << ",\"observers\":" << report.observers
      << ",\"client_threads\":" << report.client_threads
      << ",\"client_sched\":" << (report.client_sched_batch ? "\"batch\"" : "\"normal\"")
      << ",\"robot_sched\":" << (report.robot_sched_fifo ? "\"fifo\"" : "\"normal\"")
      << ",\"queries\":" << report.queries << ",\"queries_per_s\":" << json_number(report.queries_per_s)
      << ",\"p50_us\":" << json_number(report.p50_us) << ",\"p99_us\":" << json_number(report.p99_us)
      << ",\"p999_us\":" << json_number(report.p999_us) << ",\"errors\":" << report.errors << ",\"error_samples\":[";
  for (std::size_t i = 0; i < report.error_samples.size(); ++i) {
    out << (i ? "," : "") << json_string(report.error_samples[i]);
  }
  out << "],\"kinds\":{";
  for (std::size_t i = 0; i < report.kinds.size(); ++i) {
    const KindReport& kind = report.kinds[i];
    out << (i ? "," : "") << json_string(kind.kind) << ":{\"completed\":" << kind.completed
        << ",\"errors\":" << kind.errors << ",\"per_s\":" << json_number(kind.per_s)
        << ",\"entries_per_s\":" << json_number(kind.entries_per_s) << ",\"p50_us\":" << json_number(kind.p50_us)
        << ",\"p99_us\":" << json_number(kind.p99_us) << ",\"p999_us\":" << json_number(kind.p999_us)
        << ",\"max_us\":" << json_number(kind.max_us) << "}";
  }
  out << "},\"scans\":" << report.scans << ",\"scans_per_s\":" << json_number(report.scans_per_s)
      << ",\"ingest_mean_us\":" << json_number(report.ingest_mean_us)
      << ",\"ingest_p50_us\":" << json_number(report.ingest_p50_us)
      << ",\"ingest_p99_us\":" << json_number(report.ingest_p99_us) << ",\"commands\":" << report.commands
      << ",\"command_p50_us\":" << json_number(report.command_p50_us)
      << ",\"command_p99_us\":" << json_number(report.command_p99_us) << ",\"observer_polls\":" << report.observer_polls
      << ",\"observer_events\":" << report.observer_events << ",\"observer_dropped\":"
      << (report.observer_dropped ? std::to_string(*report.observer_dropped) : std::string("null"))
      << ",\"server_alive\":" << (report.server_alive ? "true" : "false");
  if (report.server_measured) {
    out << ",\"server_cpu_cores\":" << json_number(report.server_cpu_cores)
        << ",\"server_rss_kb\":" << report.server_rss_kb << ",\"server_peak_rss_kb\":" << report.server_peak_rss_kb;
  }
  out << ",\"client_cpu_cores\":" << json_number(report.client_cpu_cores) << "}";
  return out.str();
}

std::string report_text(const LoadReport& report) {
  std::ostringstream out;
  char line[256];
  std::snprintf(line, sizeof line,
                "%u robots, %u query clients (depth %u), %u observers, %.1f s\n"
                "queries: %llu  (%.0f/s)  p50 %.1f us  p99 %.1f us  p99.9 %.1f us\n",
                report.robots, report.clients, report.depth, report.observers, report.duration_s,
                static_cast<unsigned long long>(report.queries), report.queries_per_s, report.p50_us, report.p99_us,
                report.p999_us);
  out << line;
  for (const KindReport& kind : report.kinds) {
    std::snprintf(
        line, sizeof line,
        "  %-16s %10llu  %9.0f/s (%10.0f entries/s)  p50 %8.1f us  p99 %8.1f us  p99.9 %8.1f us  max %8.1f us  "
        "errors %llu\n",
        kind.kind.c_str(), static_cast<unsigned long long>(kind.completed), kind.per_s, kind.entries_per_s, kind.p50_us,
        kind.p99_us, kind.p999_us, kind.max_us, static_cast<unsigned long long>(kind.errors));
    out << line;
  }
  std::snprintf(line, sizeof line,
                "robots: %llu scans (%.1f/s), send to ScanAck mean %.0f us p50 %.0f us p99 %.0f us\n",
                static_cast<unsigned long long>(report.scans), report.scans_per_s, report.ingest_mean_us,
                report.ingest_p50_us, report.ingest_p99_us);
  out << line;
  std::snprintf(line, sizeof line,
                "control loop: %llu commands, steering scan to MotionCommand p50 %.0f us p99 %.0f us\n",
                static_cast<unsigned long long>(report.commands), report.command_p50_us, report.command_p99_us);
  out << line;
  out << "observers: " << report.observer_polls << " polls, " << report.observer_events
      << " watch events, dropped messages: "
      << (report.observer_dropped ? std::to_string(*report.observer_dropped)
                                  : std::string("not reported by the server"))
      << '\n';
  if (report.server_measured) {
    std::snprintf(line, sizeof line, "server: %.2f cores, RSS %.1f MB (peak %.1f MB)\n", report.server_cpu_cores,
                  static_cast<double>(report.server_rss_kb) / 1024.0,
                  static_cast<double>(report.server_peak_rss_kb) / 1024.0);
    out << line;
  }
  std::snprintf(line, sizeof line, "occgeo-load itself: %.2f cores\n", report.client_cpu_cores);
  out << line;
  out << "server alive: " << (report.server_alive ? "yes" : "NO") << "   errors: " << report.errors << '\n';
  for (const std::string& sample : report.error_samples) out << "  error: " << sample << '\n';
  return out.str();
}

}  // namespace occgeo::load
