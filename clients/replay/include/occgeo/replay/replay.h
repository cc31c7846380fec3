#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "occgeo/mapfile/certainty_image.h"
#include "occgeo/replay/diagnostics.h"
#include "occgeo/replay/parsers.h"
#include "occgeo/replay/scan_source.h"

namespace occgeo::replay {

// What `occgeo replay` does; see kReplayUsage.
struct ReplayOptions {
  LogFormat format = LogFormat::carmen;
  std::filesystem::path file;
  std::string server = "127.0.0.1:7700";  // HOST:PORT
  std::string world = "default";
  std::string robot_id = "replay";
  double speed = 1.0;  // log time per wall time; ignored when as_fast_as_possible
  bool as_fast_as_possible = false;
  bool json = false;
  bool consistency = false;
  std::string out_prefix;             // empty: write no map files
  std::optional<double> max_range_m;  // nullopt: the format's default
  double ack_timeout_s = 30.0;        // longest wait for one scan's answer before giving up
  // Log scans sent and not yet answered, at most (1: lockstep). A driver does not wait for each ScanAck either; the
  // server holds a fast sender back through TCP, never by dropping scans. Recordings replay in lockstep.
  std::size_t in_flight = 8;
  McapOptions mcap;  // --format mcap: topics and laser mount
};

// Parses the arguments after "replay"; throws std::invalid_argument with a message naming the option.
ReplayOptions parse_replay_args(const std::vector<std::string>& args);

// True when the cell of `grid` holding world point (x, y) or one of its 8 neighbours has certainty >= the grid's
// occupied threshold.
bool occupied_near(const mapfile::CertaintyWindow& grid, double x, double y);

// Fraction of beam endpoints (range_min <= range < range_max) that land within one cell of an occupied cell.
class ConsistencyCounter {
 public:
  void add_scan(const mapfile::CertaintyWindow& grid, const ScanRecord& scan, double range_min_m, double range_max_m);
  [[nodiscard]] std::uint64_t endpoints() const { return endpoints_; }
  [[nodiscard]] std::uint64_t hits() const { return hits_; }
  [[nodiscard]] double fraction() const {
    return endpoints_ == 0 ? 0.0 : static_cast<double>(hits_) / static_cast<double>(endpoints_);
  }

 private:
  std::uint64_t endpoints_ = 0;
  std::uint64_t hits_ = 0;
};

// What a replay did.
struct ReplaySummary {
  std::uint64_t scans = 0;                   // scans of the log sent into world W (the full pass)
  std::uint64_t scans_acked = 0;             // of those, accepted by the server
  std::uint64_t clouds = 0;                  // point clouds sent (bags only)
  std::uint64_t clouds_acked = 0;            // of those, accepted by the server
  std::uint64_t errors = 0;                  // server Errors over all passes
  double duration_s = 0.0;                   // wall time of the full pass
  double scans_per_s = 0.0;                  // scans / duration_s
  std::vector<double> scans_per_s_by_tenth;  // the rate within each tenth of the log: does it slow as the map grows?
  std::optional<double> consistency;
  std::uint64_t consistency_endpoints = 0;
  std::vector<std::string> files_written;
};

// Replays the log per `options`, printing warnings and progress to `err`; throws on fatal errors (cannot connect,
// spec refused, file unreadable, a scan not answered within ack_timeout_s).
ReplaySummary run_replay(const ReplayOptions& options, Diagnostics& diagnostics, std::ostream& err);

// The summary as one JSON object (no trailing newline).
std::string summary_json(const ReplayOptions& options, const ReplaySummary& summary, const Diagnostics& diagnostics);

extern const char* const kReplayUsage;

// `occgeo replay ARGS...`: returns the exit code (0 ok, 1 failure or server errors, 2 usage).
int run_cli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace occgeo::replay
