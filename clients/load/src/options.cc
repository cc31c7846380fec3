#include "occgeo/load/options.h"
#include "occgeo/client/option_values.h"

#include <boost/asio/ip/address.hpp>
#include <charconv>
#include <cmath>
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

double parse_positive(std::string_view flag, std::string_view text, double max) {
  const std::optional<double> value = client::finite_number(text);
  if (!value) {
    throw LoadArgsError("option '" + std::string(flag) + "' needs a number, got '" + std::string(text) + "'");
  }
  if (*value <= 0.0 || *value > max) {
    throw LoadArgsError("option '" + std::string(flag) + "' needs a number > 0 and <= " + std::to_string(max) +
                        ", got '" + std::string(text) + "'");
  }
  return *value;
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

LoadOptions parse_load_args(const std::vector<std::string_view>& args) {
  LoadOptions options;
  options.mix = {{QueryKind::collision, 4}, {QueryKind::clearance, 4}, {QueryKind::ptem, 1}, {QueryKind::status, 1}};
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string_view flag = args[i];
    const auto value = [&]() -> std::string_view {
      if (i + 1 >= args.size()) throw LoadArgsError("option '" + std::string(flag) + "' needs a value");
      return args[++i];
    };
    if (flag == "--help" || flag == "-h") {
      options.help = true;
    } else if (flag == "--server") {
      try {
        options.server = client::Endpoint::parse(value());
      } catch (const client::ClientError& error) {
        throw LoadArgsError(std::string("option '--server' ") + error.what());
      }
      if (!is_loopback_host(options.server->host)) {
        throw LoadArgsError("option '--server' needs a loopback address, got '" + options.server->host +
                            "'; occgeo-load only loads servers on this machine "
                            "(127.0.0.0/8, ::1, localhost)");
      }
    } else if (flag == "--occgeod") {
      options.occgeod = std::string(value());
    } else if (flag == "--server-config") {
      options.server_config = std::string(value());
    } else if (flag == "--server-pid") {
      options.server_pid = static_cast<int>(parse_unsigned(flag, value(), 1, 4194304));
    } else if (flag == "--robots") {
      options.robots = static_cast<std::uint32_t>(parse_unsigned(flag, value(), 0, kMaxRobots));
    } else if (flag == "--robot") {
      options.robot_preset = std::string(value());
    } else if (flag == "--world-file") {
      options.world_file = std::string(value());
    } else if (flag == "--robot-pace") {
      const std::string_view pace = value();
      if (pace == "realtime") {
        options.robot_pace = RobotPace::realtime;
      } else if (pace == "lockstep") {
        options.robot_pace = RobotPace::lockstep;
      } else {
        throw LoadArgsError("option '--robot-pace' needs realtime or lockstep, got '" + std::string(pace) + "'");
      }
    } else if (flag == "--clients") {
      options.clients = static_cast<std::uint32_t>(parse_unsigned(flag, value(), 0, kMaxClients));
    } else if (flag == "--depth") {
      options.depth = static_cast<std::uint32_t>(parse_unsigned(flag, value(), 1, kMaxDepth));
    } else if (flag == "--mix") {
      options.mix = parse_mix(value());
    } else if (flag == "--ptem-points") {
      options.ptem_points = static_cast<std::uint32_t>(parse_unsigned(flag, value(), 0, 100000));
    } else if (flag == "--batch") {
      options.batch = static_cast<std::uint32_t>(parse_unsigned(flag, value(), 1, 100000));
    } else if (flag == "--no-watch") {
      options.observer_watch = false;
    } else if (flag == "--observers") {
      options.observers = static_cast<std::uint32_t>(parse_unsigned(flag, value(), 0, kMaxClients));
    } else if (flag == "--observer-interval") {
      options.observer_interval_s = parse_positive(flag, value(), 60.0);
    } else if (flag == "--duration") {
      options.duration_s = parse_positive(flag, value(), kMaxDuration_s);
    } else if (flag == "--warmup-scans") {
      options.warmup_scans = static_cast<std::uint32_t>(parse_unsigned(flag, value(), 0, 100000));
    } else if (flag == "--area") {
      options.area_half_size_m = parse_positive(flag, value(), 1000.0);
    } else if (flag == "--threads") {
      options.threads = static_cast<std::uint32_t>(parse_unsigned(flag, value(), 1, 64));
    } else if (flag == "--client-sched") {
      const std::string policy(value());
      if (policy != "batch" && policy != "normal") {
        throw LoadArgsError("option '--client-sched' needs batch or normal, got '" + policy + "'");
      }
      options.client_sched_batch = policy == "batch";
    } else if (flag == "--seed") {
      options.seed = parse_unsigned(flag, value(), 0, UINT64_MAX);
    } else if (flag == "--json") {
      options.json = true;
    } else if (flag == "--quiet") {
      options.progress = false;
    } else {
      throw LoadArgsError("unknown option '" + std::string(flag) + "'");
    }
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
  return R"(occgeo-load: load an occgeod on this machine with simulated robots, query clients and observers

  --server HOST:PORT      a running server on a loopback address (default: start occgeod on a free
                          127.0.0.1 port with a temporary data directory, and stop it at the end)
  --occgeod PATH          the server binary to start (default: service/occgeod of this build)
  --server-config FILE    passed to the started server as --config
  --server-pid PID        with --server: the process whose CPU and memory to report
  --robots N              simulated robots streaming scans (default 1)
  --robot PRESET          their preset (default bearcat)
  --world-file FILE       their world (default clients/sim/worlds/open_field.yaml)
  --robot-pace realtime|lockstep   sensors at real rates, or each scan as soon as the last was answered
  --clients M             query clients (default 4)
  --depth D               requests in flight per query client (default 1: one at a time)
  --mix K=W,...           query kinds and their weights (default collision=4,clearance=4,ptem=1,status=1); kinds:
                          collision, clearance, ptem, status, grid, octree, raycast, occupancy, swept,
                          grid_window, octree_window, and collision_batch, clearance_batch, raycast_batch,
                          occupancy_batch, swept_batch (--batch entries each)
  --batch B               entries per *_batch request (default 100; swept_batch: at most 1000)
  --ptem-points P         points per PtemQuery (default 16)
  --observers K           observer sessions: each watches every robot's accepted sensor messages (WatchRequest)
                          and polls the server's status
  --no-watch              observers only poll
  --observer-interval S   seconds between an observer's polls (default 0.1)
  --duration S            measured seconds (default 10, at most 3600)
  --warmup-scans N        lockstep scans mapped by a seeding robot before measuring (default 100)
  --area A                query poses uniformly in [-A, A] x [-A, A] metres (default 5)
  --threads T             threads running the query clients and observers (default 1)
  --client-sched batch|normal   their scheduling policy (default batch: SCHED_BATCH, so that a client thread
                          woken by a reply waits for its turn instead of preempting the server it measures on a
                          shared core; the server and the simulated robots keep the normal policy)
  --seed S                random seed (default 1)
  --json                  print one JSON object (queries_per_s, p50_us, p99_us, errors, ...)
  --quiet                 no progress lines on stderr
Exit status: 0 when every request was answered without error and the server is still up; 1 otherwise;
2 for a usage error.
)";
}

}  // namespace occgeo::load
