#pragma once

// The `occgeo` tool's commands: each reads its options (already checked by the command line in cli_main.cc), talks to
// the server and prints the reply as text or JSON.

#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "occgeo/client/cli_options.h"

namespace occgeo::cli {

using occgeo::client::finite_number;
using occgeo::client::UsageError;  // command-line mistakes; exit code 2

// --name value options and bare --flags after the command words.
struct Options {
  std::map<std::string, std::string> values;
  std::set<std::string> switches;  // bare --flags other than --json that the command allows, without the dashes
  bool json = false;

  [[nodiscard]] std::string text(const std::string& name, const std::string& fallback = {}) const {
    const auto it = values.find(name);
    return it == values.end() ? fallback : it->second;
  }
  [[nodiscard]] std::string required(const std::string& name) const {
    const auto it = values.find(name);
    if (it == values.end()) throw UsageError("missing required option '--" + name + "'");
    return it->second;
  }
  [[nodiscard]] double number(const std::string& name, std::optional<double> fallback = std::nullopt) const {
    const auto it = values.find(name);
    if (it == values.end()) {
      if (fallback) return *fallback;
      throw UsageError("missing required option '--" + name + "'");
    }
    const std::optional<double> value = finite_number(it->second);
    if (!value) throw UsageError("option '--" + name + "' needs a number, got '" + it->second + "'");
    return *value;
  }
};

int run_status(const Options& options);
int run_query_collision(const Options& options);
int run_query_clearance(const Options& options);
int run_query_ptem(const Options& options);
int run_query_raycast(const Options& options);
int run_query_occupancy(const Options& options);
int run_query_swept(const Options& options);
int run_query_window(const Options& options);
int run_map_export(const Options& options);
int run_cloud_insert(const std::string& file, const Options& options);
int run_lease(const std::string& verb, const Options& options);
// drive's behaviour and goto's goal (or the waypoints) are the command's bare words.
int run_drive(const std::vector<std::string>& words, const Options& options);
int run_goto(bool waypoints, const std::vector<std::string>& goal, const Options& options);
int run_estop(const Options& options);

}  // namespace occgeo::cli
