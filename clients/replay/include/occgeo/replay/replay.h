#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "occgeo/replay/diagnostics.h"
#include "occgeo/replay/parsers.h"

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
};

// Parses the arguments after "replay"; throws std::invalid_argument with a message naming the option.
ReplayOptions parse_replay_args(const std::vector<std::string>& args);

// A grid fetched from the server (GridReply), for the consistency check.
struct OccupancyWindow {
  double cell_size_m = 0.1;
  std::int32_t min_ix = 0;
  std::int32_t min_iy = 0;
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  int occupied_threshold = 3;
  std::vector<std::uint8_t> cells;  // row-major, row 0 at min_iy; 255 = unobserved

  // True when the cell holding world point (x, y) or one of its 8 neighbours has certainty >= occupied_threshold.
  [[nodiscard]] bool occupied_near(double x, double y) const;
};

// Fraction of beam endpoints (range_min <= range < range_max) that land within one cell of an occupied cell.
class ConsistencyCounter {
 public:
  void add_scan(const OccupancyWindow& grid, const ScanRecord& scan, double range_min_m, double range_max_m);
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
  std::uint64_t scans = 0;        // scans of the log sent into world W (the full pass)
  std::uint64_t scans_acked = 0;  // of those, accepted by the server
  std::uint64_t errors = 0;       // server Errors over all passes
  double duration_s = 0.0;        // wall time of the full pass
  double scans_per_s = 0.0;       // scans / duration_s
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
