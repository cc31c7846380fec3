#include "scenario_runner.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <fstream>
#include <iomanip>
#include <limits>
#include <memory>
#include <queue>
#include <sstream>
#include <thread>

#include "../support/json_fields.h"
#include "../support/process.h"
#include "../support/sim_trace.h"
#include "occgeo/client/connection.h"
#include "occgeo/proto/labels.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/shape_world.h"
#include "occgeo/sim/sim_world.h"

namespace occgeo::testing {

namespace {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

client::Connection open_controller(const std::string& address) {
  auto connection = client::Connection::open(client::Endpoint::parse(address));
  v1::Hello hello;
  hello.set_protocol_version(proto::kProtocolVersion);
  hello.set_role(v1::ROLE_CONTROLLER);
  hello.set_client_name("scenario-runner");
  connection.hello(hello);
  return connection;
}

std::optional<v1::RobotStatus> robot_status(client::Connection& connection, const std::string& robot,
                                            std::uint64_t request_id) {
  v1::ClientMessage request;
  request.mutable_status();
  request.set_request_id(request_id);
  const v1::StatusReply status = connection.call(request, request_id).status();
  for (const auto& r : status.robots()) {
    if (r.id() == robot) return r;
  }
  return std::nullopt;
}

v1::LeaseReply lease(client::Connection& connection, const std::string& robot, v1::LeaseRequest::Action action,
                     std::uint64_t request_id) {
  v1::ClientMessage request;
  request.set_request_id(request_id);
  request.mutable_lease()->set_robot_id(robot);
  request.mutable_lease()->set_action(action);
  request.mutable_lease()->set_timeout_s(10.0);
  return connection.call(request, request_id).lease();
}

// "X,Y,THETA" as occgeo-sim --start reads it.
geometry::Pose2 parse_start(const std::string& text) {
  std::string fields = text;
  std::replace(fields.begin(), fields.end(), ',', ' ');
  std::istringstream in(fields);
  geometry::Pose2 pose;
  if (!(in >> pose.x >> pose.y >> pose.theta)) {
    throw std::runtime_error("scenario start '" + text + "' is not X,Y,THETA");
  }
  return pose;
}

// Registers the robot from a driver session of the runner's own with the preset's spec (the one the simulator sends),
// then closes it: the robot stays registered offline, and its control (lease, behaviour) is kept for the simulator's
// session. So the behaviour is in force before the simulator's first scan, and a lockstep run starts at sim time 0
// whatever the wall-clock timing of the controller; otherwise the moving obstacles would have moved on by a varying
// amount when the robot starts.
void register_robot_offline(const std::string& address, const std::string& robot, const Scenario& scenario) {
  const sim::RobotPreset* preset = sim::find_robot_preset(scenario.preset);
  if (preset == nullptr) throw std::runtime_error("unknown robot preset '" + scenario.preset + "'");
  auto driver = client::Connection::open(client::Endpoint::parse(address));
  driver.hello(sim::make_driver_hello(robot, "default"));
  v1::ClientMessage spec;
  *spec.mutable_robot_spec() = sim::make_robot_spec(*preset, parse_start(scenario.start));
  driver.send(spec);
  // The spec has no reply: a status request on the same session is answered after the spec was handled.
  v1::ClientMessage request;
  request.mutable_status();
  request.set_request_id(1);
  const v1::StatusReply status = driver.call(request, 1).status();
  if (std::none_of(status.robots().begin(), status.robots().end(),
                   [&](const v1::RobotStatus& r) { return r.id() == robot; })) {
    throw std::runtime_error("the robot's spec was refused");
  }
  driver.close();
}

std::string read_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::string last_state_of(const std::string& json) {
  const std::string key = "\"last_state\": \"";
  const auto at = json.find(key);
  if (at == std::string::npos) return {};
  const auto end = json.find('"', at + key.size());
  return json.substr(at + key.size(), end - at - key.size());
}

// The simulator's collision_events array, one event object per line, without the brackets.
std::string collision_events_of(const std::string& json) {
  const std::string key = "\"collision_events\": [";
  const auto at = json.find(key);
  if (at == std::string::npos) return {};
  const auto end = json.rfind(']');  // the array closes the summary; obstacle names hold brackets of their own
  if (end == std::string::npos || end < at + key.size()) return {};
  std::string events = json.substr(at + key.size(), end - at - key.size());
  for (std::size_t pos = events.find("}, {"); pos != std::string::npos; pos = events.find("}, {", pos)) {
    events.replace(pos, 4, "}\n{");
  }
  return events;
}

}  // namespace

std::filesystem::path world_path(const std::string& world) {
  const std::filesystem::path path(world);
  return path.is_absolute() ? path : source("clients/sim/worlds/" + world);
}

std::optional<OptimalPath> optimal_path_length(const std::string& world_file, const std::string& preset_name,
                                               const Eigen::Vector2d& start, const Eigen::Vector2d& goal,
                                               double goal_tolerance_m) {
  std::unique_ptr<sim::SimWorld> world = sim::load_sim_world(world_path(world_file));
  // Moving obstacles stand somewhere else by the time the robot gets there: the reference is the static layout.
  if (const auto* shapes = dynamic_cast<const sim::ShapeWorld*>(world.get());
      shapes && shapes->has_moving_obstacles()) {
    world = std::make_unique<sim::ShapeWorld>(shapes->shapes(), std::vector<sim::MovingObstacle>{}, shapes->bounds());
  }
  const sim::RobotPreset* preset = sim::find_robot_preset(preset_name);
  if (preset == nullptr) return std::nullopt;
  constexpr double kCell = 0.05;
  constexpr double kMargin = 4.0;
  const Eigen::Vector2d lo = start.cwiseMin(goal) - Eigen::Vector2d(kMargin, kMargin);
  const Eigen::Vector2d hi = start.cwiseMax(goal) + Eigen::Vector2d(kMargin, kMargin);
  const int nx = static_cast<int>(std::ceil((hi.x() - lo.x()) / kCell));
  const int ny = static_cast<int>(std::ceil((hi.y() - lo.y()) / kCell));
  const auto index = [&](int ix, int iy) { return static_cast<std::size_t>(iy) * static_cast<std::size_t>(nx) + ix; };
  const auto centre = [&](int ix, int iy) {
    return Eigen::Vector2d(lo.x() + (ix + 0.5) * kCell, lo.y() + (iy + 0.5) * kCell);
  };
  // Obstacle cells: a cell-sized prism as tall as the robot overlaps an obstacle.
  const geometry::BoxFootprint probe{
      .length = kCell, .width = kCell, .height = preset->footprint.height, .center_x = 0};
  // A lower bound for any path of the robot: the disc of its inscribed radius (the narrower half side) must pass. A
  // centre is blocked only when the nearest point of an obstacle cell's square is closer than that, so the blocked
  // set never exceeds the true one (an obstacle need not fill its cell).
  const double radius = std::max(0.0, std::min(preset->footprint.width / 2.0,
                                               preset->footprint.length / 2.0 - std::abs(preset->footprint.center_x)));
  const int reach = static_cast<int>(std::ceil(radius / kCell)) + 1;
  std::vector<char> blocked(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny), 0);
  std::vector<char> lattice_blocked(blocked.size(), 0);  // the former reference: the disc of half the width
  const double half_width = preset->footprint.width / 2.0;
  const int lattice_reach = static_cast<int>(std::ceil(half_width / kCell));
  for (int iy = 0; iy < ny; ++iy) {
    for (int ix = 0; ix < nx; ++ix) {
      const Eigen::Vector2d c = centre(ix, iy);
      if (!world->find_collision(probe, {c.x(), c.y(), 0.0}, 0.0)) continue;
      for (int dy = -std::max(reach, lattice_reach); dy <= std::max(reach, lattice_reach); ++dy) {
        for (int dx = -std::max(reach, lattice_reach); dx <= std::max(reach, lattice_reach); ++dx) {
          const int x = ix + dx;
          const int y = iy + dy;
          if (x < 0 || y < 0 || x >= nx || y >= ny) continue;
          const double gap = std::hypot(std::max(0.0, std::abs(dx) - 0.5), std::max(0.0, std::abs(dy) - 0.5)) * kCell;
          if (gap < radius) blocked[index(x, y)] = 1;
          if (std::hypot(dx, dy) * kCell <= half_width + kCell / 2.0) lattice_blocked[index(x, y)] = 1;
        }
      }
    }
  }
  const auto cell_of = [&](const Eigen::Vector2d& p) {
    return std::pair{std::clamp(static_cast<int>((p.x() - lo.x()) / kCell), 0, nx - 1),
                     std::clamp(static_cast<int>((p.y() - lo.y()) / kCell), 0, ny - 1)};
  };
  const auto [sx, sy] = cell_of(start);
  const auto [gx, gy] = cell_of(goal);
  OptimalPath out;

  // The former reference: 8-connected lattice to the goal's cell.
  {
    std::vector<double> cost(blocked.size(), std::numeric_limits<double>::infinity());
    using Entry = std::pair<double, std::size_t>;
    std::priority_queue<Entry, std::vector<Entry>, std::greater<>> open;
    cost[index(sx, sy)] = 0.0;
    open.push({0.0, index(sx, sy)});
    while (!open.empty()) {
      const auto [c, at] = open.top();
      open.pop();
      if (c > cost[at]) continue;
      const int x = static_cast<int>(at % static_cast<std::size_t>(nx));
      const int y = static_cast<int>(at / static_cast<std::size_t>(nx));
      if (x == gx && y == gy) {
        out.lattice_m = c;
        break;
      }
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          if (dx == 0 && dy == 0) continue;
          const int u = x + dx;
          const int v = y + dy;
          if (u < 0 || v < 0 || u >= nx || v >= ny || lattice_blocked[index(u, v)]) continue;
          const double next = c + std::hypot(dx, dy) * kCell;
          if (next < cost[index(u, v)]) {
            cost[index(u, v)] = next;
            open.push({next, index(u, v)});
          }
        }
      }
    }
  }

  // Any-angle (Theta*): a node's parent is any earlier node in line of sight, so paths are not bent to the lattice.
  // Line of sight samples the segment every quarter cell; the start node sits at the true start. The search ends on
  // the tolerance circle: from a node that sees the goal, the straight way there is cut short by the tolerance.
  const auto position = [&](std::size_t at) {
    if (at == index(sx, sy)) return start;
    return centre(static_cast<int>(at % static_cast<std::size_t>(nx)),
                  static_cast<int>(at / static_cast<std::size_t>(nx)));
  };
  const auto sees = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    const double length = (b - a).norm();
    const int steps = std::max(1, static_cast<int>(std::ceil(length / (kCell / 4.0))));
    for (int k = 0; k <= steps; ++k) {
      const Eigen::Vector2d p = a + (b - a) * (static_cast<double>(k) / steps);
      const int x = static_cast<int>(std::floor((p.x() - lo.x()) / kCell));
      const int y = static_cast<int>(std::floor((p.y() - lo.y()) / kCell));
      if (x < 0 || y < 0 || x >= nx || y >= ny || blocked[index(x, y)]) return false;
    }
    return true;
  };
  const auto to_circle = [&](const Eigen::Vector2d& p) { return std::max(0.0, (p - goal).norm() - goal_tolerance_m); };
  std::vector<double> cost(blocked.size(), std::numeric_limits<double>::infinity());
  std::vector<std::size_t> parent(blocked.size());
  std::vector<char> closed(blocked.size(), 0);
  using Entry = std::pair<double, std::size_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> open;
  const std::size_t start_index = index(sx, sy);
  cost[start_index] = 0.0;
  parent[start_index] = start_index;
  open.push({to_circle(start), start_index});
  double best = std::numeric_limits<double>::infinity();
  while (!open.empty()) {
    const auto [estimate, at] = open.top();
    open.pop();
    if (estimate >= best) break;
    if (closed[at]) continue;
    closed[at] = 1;
    const Eigen::Vector2d here = position(at);
    if (sees(here, goal)) best = std::min(best, cost[at] + to_circle(here));
    const int x = static_cast<int>(at % static_cast<std::size_t>(nx));
    const int y = static_cast<int>(at / static_cast<std::size_t>(nx));
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        if (dx == 0 && dy == 0) continue;
        const int u = x + dx;
        const int v = y + dy;
        if (u < 0 || v < 0 || u >= nx || v >= ny) continue;
        const std::size_t next = index(u, v);
        if (blocked[next] || closed[next]) continue;
        const Eigen::Vector2d there = centre(u, v);
        const std::size_t from = parent[at];
        double via = cost[at] + (there - here).norm();
        std::size_t via_parent = at;
        if (sees(position(from), there)) {
          via = cost[from] + (there - position(from)).norm();
          via_parent = from;
        }
        if (via < cost[next]) {
          cost[next] = via;
          parent[next] = via_parent;
          open.push({via + to_circle(there), next});
        }
      }
    }
  }
  if (std::isfinite(best)) out.any_angle_m = best;
  if (!out.any_angle_m && !out.lattice_m) return std::nullopt;
  return out;
}

std::optional<std::size_t> first_trace_difference(const ScenarioResult& a, const ScenarioResult& b) {
  const std::size_t common = std::min(a.trace.size(), b.trace.size());
  for (std::size_t i = 0; i < common; ++i) {
    if (a.trace[i] != b.trace[i]) return i;
  }
  if (a.trace.size() != b.trace.size()) return common;
  return std::nullopt;
}

ScenarioResult run_scenario(const Scenario& scenario, const std::optional<std::string>& picture_dir) {
  ScenarioResult result;
  result.name = scenario.name;
  const Clock::time_point started = Clock::now();
  TempDir dir;
  const auto config = dir.path() / "occgeod.yaml";
  std::ofstream(config) << "log_level: warn\ncontrol:\n  initial_behaviour: stop\noctomap:\n  publish_every_messages: "
                        << scenario.octomap_publish_every_messages << "\n"
                        << scenario.extra_config;
  ServerProcess server(dir.path(), {"--config", config.string()});
  const std::string robot = "scenario-robot";
  std::vector<std::string> argv = {binary("clients/sim/occgeo-sim").string(),
                                   "--server",
                                   server.address(),
                                   "--robot",
                                   scenario.preset,
                                   "--world",
                                   world_path(scenario.world).string(),
                                   "--start",
                                   scenario.start,
                                   "--id",
                                   robot,
                                   "--lockstep",
                                   "--duration",
                                   std::to_string(scenario.duration_s),
                                   "--json",
                                   "--trace-out",
                                   (dir.path() / "trace.csv").string()};
  if (scenario.command_latency_s > 0.0) {
    argv.insert(argv.end(), {"--command-latency", std::to_string(scenario.command_latency_s)});
  }
  if (picture_dir) {
    std::filesystem::create_directories(*picture_dir);
    argv.insert(argv.end(), {"--png-out", (std::filesystem::path(*picture_dir) / (scenario.name + ".png")).string()});
  }
  std::optional<BackgroundProcess> sim;
  try {
    auto controller = open_controller(server.address());
    std::uint64_t id = 0;
    if (scenario.drive_after_start_s) {
      // The simulator registers the robot itself and holds at sim time 0 until the behaviour below is set.
      argv.insert(argv.end(), {"--hold", "60"});
      sim.emplace(argv, dir.path() / "sim.out", dir.path() / "sim.err");
      const Clock::time_point connecting = Clock::now();
      for (auto status = robot_status(controller, robot, ++id); !status || !status->connected();
           status = robot_status(controller, robot, ++id)) {
        if (seconds_since(connecting) > 20.0) throw std::runtime_error("the simulator never registered the robot");
        std::this_thread::sleep_for(5ms);
      }
      std::this_thread::sleep_for(std::chrono::duration<double>(*scenario.drive_after_start_s));
    } else {
      register_robot_offline(server.address(), robot, scenario);
    }
    if (!lease(controller, robot, v1::LeaseRequest::ACQUIRE, ++id).granted()) {
      throw std::runtime_error("the lease was refused");
    }
    v1::ClientMessage drive;
    drive.set_request_id(++id);
    drive.mutable_drive()->set_robot_id(robot);
    const std::optional<v1::Behaviour> behaviour = proto::behaviour_from_label(scenario.behaviour);
    if (!behaviour) throw std::invalid_argument("scenario behaviour '" + scenario.behaviour + "' is not a Behaviour");
    drive.mutable_drive()->set_behaviour(*behaviour);
    drive.mutable_drive()->set_linear_mps(scenario.teleop_linear_mps);
    drive.mutable_drive()->set_angular_radps(scenario.teleop_angular_radps);
    drive.mutable_drive()->set_escape(scenario.escape);
    for (const Eigen::Vector2d& w : scenario.waypoints) {
      auto* waypoint = drive.mutable_drive()->add_waypoints();
      waypoint->set_x_m(w.x());
      waypoint->set_y_m(w.y());
    }
    if (scenario.goal) {
      drive.mutable_drive()->mutable_goal()->set_x_m(scenario.goal->x());
      drive.mutable_drive()->mutable_goal()->set_y_m(scenario.goal->y());
    }
    const v1::ServerMessage reply = controller.call(drive, id);
    if (!reply.has_drive()) throw std::runtime_error("drive refused: " + reply.DebugString());
    if (!sim) {
      // The simulator may connect as the robot's driver once the server has let the runner's driver session go.
      const Clock::time_point releasing = Clock::now();
      for (auto status = robot_status(controller, robot, ++id); !status || status->connected();
           status = robot_status(controller, robot, ++id)) {
        if (seconds_since(releasing) > 20.0) {
          throw std::runtime_error("the runner's driver session was never released");
        }
        std::this_thread::sleep_for(5ms);
      }
      sim.emplace(argv, dir.path() / "sim.out", dir.path() / "sim.err");
    }
    // Hold the lease while the simulator runs (bounded: lockstep runs far faster than real time).
    Clock::time_point last_retain = Clock::now();
    while (sim->running()) {
      if (seconds_since(started) > scenario.max_wall_s) {
        static_cast<void>(sim->stop(SIGTERM, std::chrono::seconds(10)));
        throw std::runtime_error("the simulation ran past " + std::to_string(scenario.max_wall_s) + " s of wall time");
      }
      std::this_thread::sleep_for(20ms);
      if (seconds_since(last_retain) > 2.0) {
        static_cast<void>(lease(controller, robot, v1::LeaseRequest::RETAIN, ++id));
        last_retain = Clock::now();
      }
    }
    static_cast<void>(lease(controller, robot, v1::LeaseRequest::RETURN, ++id));
  } catch (const std::exception& e) {
    result.failure = e.what();
    if (sim) static_cast<void>(sim->stop(SIGTERM, std::chrono::seconds(10)));
    result.wall_s = seconds_since(started);
    return result;
  }
  const std::optional<int> code = sim->stop(SIGTERM, std::chrono::seconds(10));
  result.wall_s = seconds_since(started);
  const std::string out = read_file(dir.path() / "sim.out");
  if (code != 0) {
    result.failure = "occgeo-sim exited with " + (code ? std::to_string(*code) : std::string("no code")) + ": " +
                     read_file(dir.path() / "sim.err");
    return result;
  }
  try {
    result.collisions = static_cast<int>(json_number(out, "collisions"));
    result.collisions_moving = static_cast<int>(json_number(out, "collisions_moving"));
    result.collisions_at_rest = static_cast<int>(json_number(out, "collisions_at_rest"));
    result.collisions_hit_moving = static_cast<int>(json_number(out, "collisions_hit_moving"));
  } catch (const std::exception& e) {
    result.failure = e.what();
    return result;
  }
  result.last_state = last_state_of(out);
  result.collision_events = collision_events_of(out);
  std::vector<Eigen::Vector4d> trace = read_sim_trace(dir.path() / "trace.csv");
  if (trace.empty()) {
    result.failure = "empty trace";
    return result;
  }
  // Sim time counts from the first motion: a behaviour may hold the robot still for its first scans.
  std::size_t first = 0;
  while (first + 1 < trace.size() &&
         std::hypot(trace[first + 1](1) - trace[0](1), trace[first + 1](2) - trace[0](2)) < 1e-4 &&
         std::abs(trace[first + 1](3) - trace[0](3)) < 1e-4) {
    ++first;
  }
  std::size_t last = trace.size() - 1;
  if (scenario.goal) {
    result.reached = false;
    for (std::size_t i = first; i < trace.size(); ++i) {
      if (std::hypot(trace[i](1) - scenario.goal->x(), trace[i](2) - scenario.goal->y()) <= scenario.goal_tolerance_m) {
        result.reached = true;
        last = i;
        break;
      }
    }
    const std::optional<OptimalPath> optimal = optimal_path_length(
        scenario.world, scenario.preset, {trace[0](1), trace[0](2)}, *scenario.goal, scenario.goal_tolerance_m);
    if (optimal) {
      result.optimal_m = optimal->any_angle_m;
      result.lattice_m = optimal->lattice_m;
    }
  }
  for (std::size_t i = first + 1; i <= last; ++i) {
    result.path_m += std::hypot(trace[i](1) - trace[i - 1](1), trace[i](2) - trace[i - 1](2));
  }
  result.sim_s = trace[last](0) - trace[first](0);
  result.final_pose = {trace.back()(1), trace.back()(2), trace.back()(3)};
  result.trace = std::move(trace);
  result.ran = true;
  return result;
}

std::string results_table(const std::vector<Scenario>& scenarios, const std::vector<ScenarioResult>& results) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(2);
  out << std::left << std::setw(44) << "scenario" << std::setw(9) << "reached" << std::setw(11) << "collisions"
      << std::setw(9) << "path_m" << std::setw(11) << "optimal_m" << std::setw(11) << "lattice_m" << std::setw(7)
      << "ratio" << std::setw(9) << "sim_s" << std::setw(8) << "wall_s"
      << "last state / note\n";
  for (std::size_t i = 0; i < results.size(); ++i) {
    const ScenarioResult& r = results[i];
    out << std::left << std::setw(44) << r.name;
    if (!r.ran) {
      out << "did not run: " << r.failure << '\n';
      continue;
    }
    out << std::setw(9) << (r.reached ? (*r.reached ? "yes" : "no") : "-") << std::setw(11) << r.collisions
        << std::setw(9) << r.path_m << std::setw(11);
    if (r.optimal_m) {
      out << *r.optimal_m;
    } else {
      out << "-";
    }
    out << std::setw(11);
    if (r.lattice_m) {
      out << *r.lattice_m;
    } else {
      out << "-";
    }
    out << std::setw(7);
    if (r.ratio()) {
      out << *r.ratio();
    } else {
      out << "-";
    }
    out << std::setw(9) << r.sim_s << std::setw(8) << r.wall_s << (r.last_state.empty() ? "-" : r.last_state);
    if (i < scenarios.size() && !scenarios[i].note.empty()) out << "  (" << scenarios[i].note << ")";
    out << '\n';
  }
  return out.str();
}

}  // namespace occgeo::testing
