#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "occgeo/client/cli_options.h"
#include "occgeo/client/connection.h"

namespace occgeo::load {

// A command-line mistake, worded like every tool's: "option '--clients' needs a whole number, got 'x'".
class LoadArgsError : public client::UsageError {
 public:
  using client::UsageError::UsageError;
};

// The query kinds a query client can send. Each names one request message of occgeo.v1; the *_batch kinds carry
// --batch entries (poses, rays, points or motions) in one request, the others one.
enum class QueryKind {
  collision,
  clearance,
  ptem,
  status,
  grid,
  octree,
  collision_batch,
  clearance_batch,
  raycast,
  raycast_batch,
  occupancy,
  occupancy_batch,
  swept,
  swept_batch,
  grid_window,
  octree_window,
};

// Every kind, in the order above.
const std::vector<QueryKind>& all_query_kinds();

// Name as written in --mix and in reports, e.g. "collision".
std::string_view query_kind_name(QueryKind kind);
std::optional<QueryKind> parse_query_kind(std::string_view name);

// How fast simulated robots stream: at their sensors' real rates, or each scan as soon as the previous one was
// acknowledged and answered (lockstep, as fast as the server ingests).
enum class RobotPace { realtime, lockstep };

// SCHED_FIFO priority of the simulated robots' threads with --robot-sched fifo: occgeod's default
// control.realtime_priority, so that a robot and the server's command path do not preempt each other.
inline constexpr int kRobotFifoPriority = 10;

struct LoadOptions {
  std::optional<client::Endpoint> server;  // --server: a loopback address; unset: start occgeod
  std::filesystem::path occgeod;           // --occgeod: the server binary to start (default: next to this tool)
  std::optional<std::filesystem::path> server_config;  // --server-config: passed to occgeod as --config
  std::optional<int> server_pid;                       // --server-pid: whose CPU and memory to report with --server
  std::uint32_t robots = 1;                            // --robots
  std::string robot_preset = "bearcat";                // --robot
  std::filesystem::path world_file;                    // --world-file: the simulated robots' world
  RobotPace robot_pace = RobotPace::realtime;          // --robot-pace
  std::uint32_t clients = 4;                           // --clients
  std::uint32_t depth = 1;                             // --depth: requests in flight per query client
  std::map<QueryKind, std::uint32_t> mix;              // --mix: relative weights, e.g. collision=4,clearance=4
  std::uint32_t ptem_points = 16;                      // --ptem-points: points per PtemQuery
  std::uint32_t batch = 100;                           // --batch: entries per *_batch request
  std::uint32_t observers = 0;                         // --observers
  double observer_interval_s = 0.1;                    // --observer-interval
  bool observer_watch = true;                          // --no-watch turns the observers' WatchRequest off
  double duration_s = 10.0;                            // --duration
  std::uint32_t warmup_scans = 100;                    // --warmup-scans: lockstep scans mapped before measuring
  double area_half_size_m = 5.0;                       // --area: query poses in [-A, A]², metres
  std::uint32_t threads = 1;                           // --threads: threads running the query clients
  // --client-sched: the query-client threads' scheduling policy. Batch (SCHED_BATCH) keeps a client thread woken by a
  // reply from preempting the server mid-burst on a shared core; normal leaves them as the OS starts them.
  bool client_sched_batch = true;
  // --robot-sched: the simulated robots' threads at the normal policy, or SCHED_FIFO (priority
  // kRobotFifoPriority): a robot's driver runs on its own computer, so FIFO keeps the query clients, which share
  // this machine's cores with the robots here, out of the command latency measured.
  bool robot_sched_fifo = false;
  std::uint64_t seed = 1;  // --seed
  bool json = false;       // --json
  bool progress = true;    // --quiet turns progress lines off
  bool help = false;
};

// Parses the arguments after the program name; throws LoadArgsError.
LoadOptions parse_load_args(const std::vector<std::string_view>& args);

// --help text.
std::string load_usage();

// True for 127.0.0.0/8, ::1 and "localhost".
bool is_loopback_host(std::string_view host);

}  // namespace occgeo::load
