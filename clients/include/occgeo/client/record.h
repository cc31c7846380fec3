#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "occgeo/client/mcap_writer.h"

namespace occgeo::client {

// What `occgeo record` does; see kRecordUsage.
struct RecordOptions {
  std::string server = "127.0.0.1:7700";
  std::filesystem::path out;
  std::string world;     // empty: every world
  std::string robot_id;  // empty: every robot
  std::optional<double> duration_s;
  double grid_period_s = 1.0;  // how often the grid's changes are fetched and written
  McapCompression compression = McapCompression::zstd;
  std::string token;  // the observer token, needed beyond loopback
  bool json = false;  // summary as JSON on stdout
};

// Parses the arguments after "record"; throws std::invalid_argument naming the option at fault.
RecordOptions parse_record_args(const std::vector<std::string>& args);

// What a recording held when it was closed.
struct RecordSummary {
  std::uint64_t messages = 0;  // MCAP messages written
  std::uint64_t bytes = 0;     // file size
  std::uint64_t dropped = 0;   // events the server dropped because the recorder read too slowly
  double duration_s = 0.0;
};

// Attaches as an observer and writes what the server accepts to options.out until stop_requested() or the duration
// ends, then closes the file; progress on `err`. Throws ClientError when the server cannot be reached or refuses;
// a connection lost midway closes the file and rethrows.
RecordSummary run_record(const RecordOptions& options, std::ostream& err);

// Asks a running run_record to close its file and return (async-signal-safe: for SIGINT and SIGTERM handlers).
void request_record_stop();

extern const char* const kRecordUsage;

// `occgeo record ARGS...`: installs SIGINT/SIGTERM handlers, returns the exit code (0 ok, 1 failure, 2 usage).
int run_record_cli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace occgeo::client
