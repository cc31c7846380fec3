// occgeo: command-line client for occgeod (status, geometry queries, map export).
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "occgeo/client/connection.h"
#include "occgeo/client/grid.h"
#include "occgeo/mapfile/certainty_image.h"
#include "occgeo/replay/replay.h"

namespace {

using occgeo::client::ClientError;
using occgeo::client::Connection;
using occgeo::client::Endpoint;
namespace v1 = occgeo::v1;

constexpr const char* kUsage = R"(usage: occgeo COMMAND [options]
commands:
  status                                     robots, worlds and clients of the server
  query collision --robot ID --x X --y Y [--theta T]
                                             is the robot's footprint at this pose in collision?
  query clearance --robot ID --x X --y Y [--theta T] [--max-distance D]
                                             distance from the footprint to the nearest obstacle
  map export --world W --out PREFIX          write the world's grid as PREFIX.pgm + PREFIX.yaml
                                             (ROS map_server format)
  replay --format carmen|dpslam|urg FILE [--max | --speed X] [--consistency] [--out PREFIX] [--json] ...
                                             stream a recorded laser log as a driver (occgeo replay --help)
common options:
  --server HOST:PORT   server address (default 127.0.0.1:7700)
  --json               print the reply as one JSON object
Units: metres and radians; poses are base_link in the world frame.
)";

// Thrown for command-line mistakes; exit code 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// --name value options and bare --flags after the command words.
struct Options {
  std::map<std::string, std::string> values;
  bool json = false;

  [[nodiscard]] std::string text(const std::string& name, const std::string& fallback = {}) const {
    const auto it = values.find(name);
    return it == values.end() ? fallback : it->second;
  }
  [[nodiscard]] std::string required(const std::string& name) const {
    const auto it = values.find(name);
    if (it == values.end()) throw UsageError("missing required option --" + name);
    return it->second;
  }
  [[nodiscard]] double number(const std::string& name, std::optional<double> fallback = std::nullopt) const {
    const auto it = values.find(name);
    if (it == values.end()) {
      if (fallback) return *fallback;
      throw UsageError("missing required option --" + name);
    }
    std::size_t used = 0;
    double value = 0.0;
    try {
      value = std::stod(it->second, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != it->second.size() || !std::isfinite(value)) {
      throw UsageError("option --" + name + " needs a number, not '" + it->second + "'");
    }
    return value;
  }
};

Options parse_options(const std::vector<std::string>& args, std::size_t first,
                      const std::vector<std::string>& allowed) {
  Options options;
  for (std::size_t i = first; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--json") {
      options.json = true;
      continue;
    }
    if (arg.rfind("--", 0) != 0) throw UsageError("unexpected argument '" + arg + "'");
    const std::string name = arg.substr(2);
    if (name != "server" && std::find(allowed.begin(), allowed.end(), name) == allowed.end()) {
      throw UsageError("unknown option '" + arg + "'");
    }
    if (i + 1 >= args.size()) throw UsageError("option '" + arg + "' needs a value");
    options.values[name] = args[++i];
  }
  return options;
}

Connection connect_query(const Options& options) {
  Connection connection = Connection::open(Endpoint::parse(options.text("server", "127.0.0.1:7700")));
  v1::Hello hello;
  hello.set_protocol_version(1);
  hello.set_role(v1::ROLE_QUERY);
  hello.set_client_name("occgeo-cli");
  connection.hello(hello);
  return connection;
}

std::string json_string(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string fmt(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", v);
  return buffer;
}

v1::Pose2D pose_from(const Options& options) {
  v1::Pose2D pose;
  pose.set_x(options.number("x"));
  pose.set_y(options.number("y"));
  pose.set_theta(options.number("theta", 0.0));
  return pose;
}

int run_status(const Options& options) {
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  request.mutable_status()->set_request_id(1);
  const v1::StatusReply status = connection.call(request, 1).status();
  if (options.json) {
    std::ostringstream out;
    out << "{\"server_version\":" << json_string(status.server_version()) << ",\"clients\":" << status.clients()
        << ",\"uptime_s\":" << fmt(status.uptime_s()) << ",\"robots\":[";
    for (int i = 0; i < status.robots_size(); ++i) {
      const auto& r = status.robots(i);
      out << (i ? "," : "") << "{\"id\":" << json_string(r.id()) << ",\"world\":" << json_string(r.world())
          << ",\"model\":" << json_string(r.model()) << ",\"connected\":" << (r.connected() ? "true" : "false")
          << ",\"pose\":{\"x\":" << fmt(r.pose().x()) << ",\"y\":" << fmt(r.pose().y())
          << ",\"theta\":" << fmt(r.pose().theta()) << "},\"scans_ingested\":" << r.scans_ingested()
          << ",\"scans_rejected\":" << r.scans_rejected() << ",\"behaviour\":" << json_string(r.behaviour())
          << ",\"behaviour_state\":" << json_string(r.behaviour_state()) << "}";
    }
    out << "],\"worlds\":[";
    for (int i = 0; i < status.worlds_size(); ++i) {
      const auto& w = status.worlds(i);
      out << (i ? "," : "") << "{\"name\":" << json_string(w.name()) << ",\"cell_size_m\":" << fmt(w.cell_size_m())
          << ",\"version\":" << w.version() << ",\"tiles\":" << w.tiles()
          << ",\"occupied_cells\":" << w.occupied_cells() << "}";
    }
    out << "]}";
    std::cout << out.str() << "\n";
    return 0;
  }
  std::cout << status.server_version() << ", up " << fmt(status.uptime_s()) << " s, " << status.clients()
            << " client(s)\n";
  std::cout << "robots:\n";
  for (const auto& r : status.robots()) {
    std::cout << "  " << r.id() << " (" << r.model() << ") world " << r.world() << ", "
              << (r.connected() ? "connected" : "offline") << ", pose (" << fmt(r.pose().x()) << ", "
              << fmt(r.pose().y()) << ", " << fmt(r.pose().theta()) << "), scans " << r.scans_ingested() << " ("
              << r.scans_rejected() << " rejected), " << r.behaviour() << ": " << r.behaviour_state() << "\n";
  }
  std::cout << "worlds:\n";
  for (const auto& w : status.worlds()) {
    std::cout << "  " << w.name() << ": " << w.occupied_cells() << " occupied cells of " << fmt(w.cell_size_m())
              << " m in " << w.tiles() << " tiles, version " << w.version() << "\n";
  }
  return 0;
}

int run_query_collision(const Options& options) {
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  auto* query = request.mutable_collision();
  query->set_request_id(1);
  query->set_robot_id(options.required("robot"));
  *query->mutable_pose() = pose_from(options);
  const v1::CollisionReply reply = connection.call(request, 1).collision();
  if (options.json) {
    std::cout << "{\"hit\":" << (reply.hit() ? "true" : "false");
    if (reply.hit()) {
      std::cout << ",\"cell\":{\"ix\":" << reply.cell().ix() << ",\"iy\":" << reply.cell().iy()
                << "},\"cell_center\":{\"x\":" << fmt(reply.cell_center().x())
                << ",\"y\":" << fmt(reply.cell_center().y()) << "}";
    }
    std::cout << ",\"cells_tested\":" << reply.cells_tested() << "}\n";
  } else if (reply.hit()) {
    std::cout << "hit: occupied cell (" << reply.cell().ix() << ", " << reply.cell().iy() << ") centred at ("
              << fmt(reply.cell_center().x()) << ", " << fmt(reply.cell_center().y()) << ")\n";
  } else {
    std::cout << "free\n";
  }
  return 0;
}

int run_query_clearance(const Options& options) {
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  auto* query = request.mutable_clearance();
  query->set_request_id(1);
  query->set_robot_id(options.required("robot"));
  *query->mutable_pose() = pose_from(options);
  query->set_max_distance_m(options.number("max-distance", 0.0));
  const v1::ClearanceReply reply = connection.call(request, 1).clearance();
  if (options.json) {
    std::cout << "{\"clearance_m\":" << fmt(reply.clearance_m()) << ",\"found\":" << (reply.found() ? "true" : "false");
    if (reply.found()) {
      std::cout << ",\"nearest_cell\":{\"ix\":" << reply.nearest_cell().ix() << ",\"iy\":" << reply.nearest_cell().iy()
                << "},\"nearest_point\":{\"x\":" << fmt(reply.nearest_point().x())
                << ",\"y\":" << fmt(reply.nearest_point().y()) << "}";
    }
    std::cout << "}\n";
  } else if (reply.found()) {
    std::cout << "clearance " << fmt(reply.clearance_m()) << " m to occupied cell (" << reply.nearest_cell().ix()
              << ", " << reply.nearest_cell().iy() << ")\n";
  } else {
    std::cout << "clearance at least " << fmt(reply.clearance_m())
              << " m (nothing occupied within the search radius)\n";
  }
  return 0;
}

int run_map_export(const Options& options) {
  const std::string prefix = options.required("out");
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  request.mutable_grid()->set_request_id(1);
  request.mutable_grid()->set_world(options.required("world"));
  const v1::GridReply grid = connection.call(request, 1, std::chrono::seconds(60)).grid();
  if (grid.width() == 0 || grid.height() == 0) {
    std::cerr << "occgeo: world '" << grid.world() << "' has no cells observed yet; nothing written\n";
    return 1;
  }
  occgeo::mapfile::write_map(prefix, occgeo::mapfile::image_from_certainty(occgeo::client::certainty_window(grid)));
  if (options.json) {
    std::cout << "{\"pgm\":" << json_string(prefix + ".pgm") << ",\"yaml\":" << json_string(prefix + ".yaml")
              << ",\"width\":" << grid.width() << ",\"height\":" << grid.height() << ",\"version\":" << grid.version()
              << "}\n";
  } else {
    std::cout << "wrote " << prefix << ".pgm and " << prefix << ".yaml (" << grid.width() << " x " << grid.height()
              << " cells of " << fmt(grid.cell_size_m()) << " m, map version " << grid.version() << ")\n";
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  try {
    if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
      std::fputs(kUsage, args.empty() ? stderr : stdout);
      return args.empty() ? 2 : 0;
    }
    if (args[0] == "replay") {
      if (args.size() >= 2 && (args[1] == "--help" || args[1] == "-h")) {
        std::fputs(occgeo::replay::kReplayUsage, stdout);
        return 0;
      }
      return occgeo::replay::run_cli(std::vector<std::string>(args.begin() + 1, args.end()), std::cout, std::cerr);
    }
    if (args[0] == "status") return run_status(parse_options(args, 1, {}));
    if (args.size() >= 2 && args[0] == "query" && args[1] == "collision") {
      return run_query_collision(parse_options(args, 2, {"robot", "x", "y", "theta"}));
    }
    if (args.size() >= 2 && args[0] == "query" && args[1] == "clearance") {
      return run_query_clearance(parse_options(args, 2, {"robot", "x", "y", "theta", "max-distance"}));
    }
    if (args.size() >= 2 && args[0] == "map" && args[1] == "export") {
      return run_map_export(parse_options(args, 2, {"world", "out"}));
    }
    throw UsageError("unknown command '" + args[0] + (args.size() > 1 ? " " + args[1] : "") + "'");
  } catch (const UsageError& e) {
    std::cerr << "occgeo: " << e.what() << "\n" << kUsage;
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "occgeo: " << e.what() << "\n";
    return 1;
  }
}
