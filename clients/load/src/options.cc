#include "occgeo/load/options.h"
#include "occgeo/client/cli_options.h"

#include <boost/asio/ip/address.hpp>
#include <charconv>
#include <cmath>
#include <sstream>
#include <string>

namespace occgeo::load {

namespace {

constexpr double kMaxDuration_s = 3600.0;
constexpr std::uint32_t kMaxClients = 4096;
constexpr std::uint32_t kMaxRobots = 256;
constexpr std::uint32_t kMaxDepth = 4096;

std::uint64_t parse_unsigned(std::string_view flag, std::string_view text, std::uint64_t min, std::uint64_t max) {
  std::uint64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size()) {
    throw LoadArgsError("option '" + std::string(flag) + "' needs a whole number, got '" + std::string(text) + "'");
  }
  if (value < min || value > max) {
    throw LoadArgsError("option '" + std::string(flag) + "' needs a value in " + std::to_string(min) + ".." +
                        std::to_string(max) + ", got " + std::to_string(value));
  }
  return value;
}

std::map<QueryKind, std::uint32_t> parse_mix(std::string_view text) {
  std::map<QueryKind, std::uint32_t> mix;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t comma = std::min(text.find(',', start), text.size());
    const std::string_view item = text.substr(start, comma - start);
    const std::size_t equals = item.find('=');
    const std::string_view name = item.substr(0, equals);
    const auto kind = parse_query_kind(name);
    if (!kind) {
      std::string names;
      for (const QueryKind known : all_query_kinds())
        names += (names.empty() ? "" : ", ") + std::string(query_kind_name(known));
      throw LoadArgsError("option '--mix' names an unknown query kind '" + std::string(name) + "' (" + names + ")");
    }
    const std::uint32_t weight =
        equals == std::string_view::npos
            ? 1
            : static_cast<std::uint32_t>(parse_unsigned("--mix", item.substr(equals + 1), 0, 1000000));
    mix[*kind] = weight;
    start = comma + 1;
  }
  std::uint64_t total = 0;
  for (const auto& [kind, weight] : mix) total += weight;
  if (total == 0) throw LoadArgsError("option '--mix' needs a weight above 0");
  return mix;
}

}  // namespace

std::string_view query_kind_name(QueryKind kind) {
  switch (kind) {
    case QueryKind::collision:
      return "collision";
    case QueryKind::clearance:
      return "clearance";
    case QueryKind::ptem:
      return "ptem";
    case QueryKind::status:
      return "status";
    case QueryKind::grid:
      return "grid";
    case QueryKind::octree:
      return "octree";
    case QueryKind::collision_batch:
      return "collision_batch";
    case QueryKind::clearance_batch:
      return "clearance_batch";
    case QueryKind::raycast:
      return "raycast";
    case QueryKind::raycast_batch:
      return "raycast_batch";
    case QueryKind::occupancy:
      return "occupancy";
    case QueryKind::occupancy_batch:
      return "occupancy_batch";
    case QueryKind::swept:
      return "swept";
    case QueryKind::swept_batch:
      return "swept_batch";
    case QueryKind::grid_window:
      return "grid_window";
    case QueryKind::octree_window:
      return "octree_window";
  }
  return "?";
}

const std::vector<QueryKind>& all_query_kinds() {
  static const std::vector<QueryKind> kinds = {QueryKind::collision,
                                               QueryKind::clearance,
                                               QueryKind::ptem,
                                               QueryKind::status,
                                               QueryKind::grid,
                                               QueryKind::octree,
                                               QueryKind::collision_batch,
                                               QueryKind::clearance_batch,
                                               QueryKind::raycast,
                                               QueryKind::raycast_batch,
                                               QueryKind::occupancy,
                                               QueryKind::occupancy_batch,
                                               QueryKind::swept,
                                               QueryKind::swept_batch,
                                               QueryKind::grid_window,
                                               QueryKind::octree_window};
  return kinds;
}

std::optional<QueryKind> parse_query_kind(std::string_view name) {
  for (const QueryKind kind : all_query_kinds()) {
    if (query_kind_name(kind) == name) return kind;
  }
  return std::nullopt;
}

bool is_loopback_host(std::string_view host) {
  if (host == "localhost") return true;
  std::string bare(host);
  if (bare.size() > 2 && bare.front() == '[' && bare.back() == ']') bare = bare.substr(1, bare.size() - 2);
  boost::system::error_code error;
  const auto address = boost::asio::ip::make_address(bare, error);
  return !error && address.is_loopback();
}

namespace {

// The options of occgeo-load as one CLI11 app writing into `options`; also the source of --help.
struct LoadCommandLine {
  CLI::App app{"occgeo-load: load an occgeod on this machine with simulated robots, query clients and observers",
               "occgeo-load"};
  std::string server, occgeod, server_config, robot_pace, client_sched, robot_sched, mix, world_file;
  std::uint64_t server_pid = 0, robots = 0, clients = 0, depth = 0, ptem_points = 0, batch = 0, observers = 0,
                warmup_scans = 0, threads = 0;
  double observer_interval_s = 0.0, duration_s = 0.0, area_m = 0.0;

  explicit LoadCommandLine(LoadOptions& options) {
    using client::add_number;
    using client::add_text;
    using client::add_whole;
    client::configure_cli(app, options.help);
    app.footer(
        "Exit status: 0 when every request was answered without error and the server is still up; 1 otherwise;\n"
        "2 for a usage error.");
    add_text(app, "--server", server,
             "a running server on a loopback address (default: start occgeod on a free 127.0.0.1 port with a "
             "temporary data directory, and stop it at the end)",
             "HOST:PORT");
    app.add_option("--occgeod", occgeod, "the server binary to start (default: service/occgeod of this build)")
        ->type_name("PATH");
    app.add_option("--server-config", server_config, "passed to the started server as --config")->type_name("FILE");
    add_whole(app, "--server-pid", server_pid, 1, 4194304, "with --server: the process whose CPU and memory to report")
        ->type_name("PID");
    add_whole(app, "--robots", robots, 0, kMaxRobots, "simulated robots streaming scans (default 1)");
    app.add_option("--robot", options.robot_preset, "their preset (default bearcat)")->type_name("PRESET");
    app.add_option("--world-file", world_file, "their world (default clients/sim/worlds/open_field.yaml)")
        ->type_name("FILE");
    add_text(app, "--robot-pace", robot_pace, "sensors at real rates, or each scan as soon as the last was answered",
             "realtime|lockstep");
    add_whole(app, "--clients", clients, 0, kMaxClients, "query clients (default 4)");
    add_whole(app, "--depth", depth, 1, kMaxDepth, "requests in flight per query client (default 1: one at a time)");
    add_text(app, "--mix", mix,
             "query kinds and their weights (default collision=4,clearance=4,ptem=1,status=1); kinds: collision, "
             "clearance, ptem, status, grid, octree, raycast, occupancy, swept, grid_window, octree_window, and "
             "collision_batch, clearance_batch, raycast_batch, occupancy_batch, swept_batch (--batch entries each)",
             "K=W,...");
    add_whole(app, "--batch", batch, 1, 100000, "entries per *_batch request (default 100; swept_batch: at most 1000)");
    add_whole(app, "--ptem-points", ptem_points, 0, 100000, "points per PtemQuery (default 16)");
    add_whole(app, "--observers", observers, 0, kMaxClients,
              "observer sessions: each watches every robot's accepted sensor messages (WatchRequest) and polls the "
              "server's status");
    app.add_flag_callback(
        "--no-watch", [&options] { options.observer_watch = false; }, "observers only poll");
    add_number(app, "--observer-interval", observer_interval_s, "seconds between an observer's polls (default 0.1)")
        ->type_name("S");
    add_number(app, "--duration", duration_s, "measured seconds (default 10, at most 3600)")->type_name("S");
    add_whole(app, "--warmup-scans", warmup_scans, 0, 100000,
              "lockstep scans mapped by a seeding robot before measuring (default 100)");
    add_number(app, "--area", area_m, "query poses uniformly in [-A, A] x [-A, A] metres (default 5)")->type_name("A");
    add_whole(app, "--threads", threads, 1, 64, "threads running the query clients and observers (default 1)");
    add_text(app, "--client-sched", client_sched,
             "their scheduling policy (default batch: SCHED_BATCH, so that a client thread woken by a reply waits "
             "for its turn instead of preempting the server it measures on a shared core; the server keeps its "
             "policies, the simulated robots --robot-sched's)",
             "batch|normal");
    add_text(app, "--robot-sched", robot_sched,
             "the simulated robots' threads' policy (default normal; fifo: SCHED_FIFO, as a driver on its own "
             "computer would not share cores with the query clients; needs CAP_SYS_NICE or an RLIMIT_RTPRIO)",
             "normal|fifo");
    add_whole(app, "--seed", options.seed, 0, UINT64_MAX, "random seed (default 1)")->type_name("S");
    app.add_flag("--json", options.json, "print one JSON object (queries_per_s, p50_us, p99_us, errors, ...)");
    app.add_flag_callback(
        "--quiet", [&options] { options.progress = false; }, "no progress lines on stderr");
  }
};

// A positive number of at most `max`, already known finite.
double positive_at_most(const std::string& flag, double value, double max) {
  if (value <= 0.0 || value > max) {
    std::ostringstream text;
    text << "option '" << flag << "' needs a number > 0 and <= " << max << ", got " << value;
    throw LoadArgsError(text.str());
  }
  return value;
}

}  // namespace

LoadOptions parse_load_args(const std::vector<std::string_view>& args) {
  LoadOptions options;
  options.mix = {{QueryKind::collision, 4}, {QueryKind::clearance, 4}, {QueryKind::ptem, 1}, {QueryKind::status, 1}};
  LoadCommandLine line(options);
  try {
    client::parse_command_line(line.app, std::vector<std::string>(args.begin(), args.end()));
  } catch (const client::UsageError& error) {
    throw LoadArgsError(error.what());
  }
  const auto given = [&line](const char* flag) { return line.app.count(flag) > 0; };
  if (given("--server")) {
    try {
      options.server = client::Endpoint::parse(line.server);
    } catch (const client::ClientError& error) {
      throw LoadArgsError(std::string("option '--server' ") + error.what());
    }
    if (!is_loopback_host(options.server->host)) {
      throw LoadArgsError("option '--server' needs a loopback address, got '" + options.server->host +
                          "'; occgeo-load only loads servers on this machine "
                          "(127.0.0.0/8, ::1, localhost)");
    }
  }
  if (given("--occgeod")) options.occgeod = line.occgeod;
  if (given("--server-config")) options.server_config = line.server_config;
  if (given("--world-file")) options.world_file = line.world_file;
  if (given("--server-pid")) options.server_pid = static_cast<int>(line.server_pid);
  if (given("--robots")) options.robots = static_cast<std::uint32_t>(line.robots);
  if (given("--robot-pace")) {
    if (line.robot_pace == "realtime") {
      options.robot_pace = RobotPace::realtime;
    } else if (line.robot_pace == "lockstep") {
      options.robot_pace = RobotPace::lockstep;
    } else {
      throw LoadArgsError("option '--robot-pace' needs realtime or lockstep, got '" + line.robot_pace + "'");
    }
  }
  if (given("--clients")) options.clients = static_cast<std::uint32_t>(line.clients);
  if (given("--depth")) options.depth = static_cast<std::uint32_t>(line.depth);
  if (given("--mix")) options.mix = parse_mix(line.mix);
  if (given("--ptem-points")) options.ptem_points = static_cast<std::uint32_t>(line.ptem_points);
  if (given("--batch")) options.batch = static_cast<std::uint32_t>(line.batch);
  if (given("--observers")) options.observers = static_cast<std::uint32_t>(line.observers);
  if (given("--observer-interval")) {
    options.observer_interval_s = positive_at_most("--observer-interval", line.observer_interval_s, 60.0);
  }
  if (given("--duration")) options.duration_s = positive_at_most("--duration", line.duration_s, kMaxDuration_s);
  if (given("--warmup-scans")) options.warmup_scans = static_cast<std::uint32_t>(line.warmup_scans);
  if (given("--area")) options.area_half_size_m = positive_at_most("--area", line.area_m, 1000.0);
  if (given("--threads")) options.threads = static_cast<std::uint32_t>(line.threads);
  if (given("--client-sched")) {
    if (line.client_sched != "batch" && line.client_sched != "normal") {
      throw LoadArgsError("option '--client-sched' needs batch or normal, got '" + line.client_sched + "'");
    }
    options.client_sched_batch = line.client_sched == "batch";
  }
  if (given("--robot-sched")) {
    if (line.robot_sched != "normal" && line.robot_sched != "fifo") {
      throw LoadArgsError("option '--robot-sched' needs normal or fifo, got '" + line.robot_sched + "'");
    }
    options.robot_sched_fifo = line.robot_sched == "fifo";
  }
  if (options.server_pid && !options.server) {
    throw LoadArgsError("option '--server-pid' needs --server (a server this tool starts is measured anyway)");
  }
  if (options.server_config && options.server) {
    throw LoadArgsError("option '--server-config' only applies when occgeo-load starts the server (no --server)");
  }
  return options;
}

std::string load_usage() {
  LoadOptions options;
  LoadCommandLine line(options);
  return line.app.help();
}

}  // namespace occgeo::load
