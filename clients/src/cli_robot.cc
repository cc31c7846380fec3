// occgeo's robot control: leases, drive, goto and waypoints, and the e-stop.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <iostream>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>
#include "occgeo/client/option_values.h"
#include "occgeo/proto/labels.h"
#include "occgeo/proto/protocol.h"

#include "cli_common.h"

namespace occgeo::cli {

Connection connect_role(const Options& options, v1::Role role) {
  Connection connection = Connection::open(Endpoint::parse(options.text("server", "127.0.0.1:7700")));
  v1::Hello hello;
  hello.set_protocol_version(occgeo::proto::kProtocolVersion);
  hello.set_role(role);
  hello.set_client_name("occgeo-cli");
  hello.set_auth_token(options.text("token"));
  connection.hello(hello);
  return connection;
}

v1::LeaseReply lease_call(Connection& connection, const std::string& robot, v1::LeaseRequest::Action action,
                          double timeout_s, std::uint64_t request_id) {
  v1::ClientMessage request;
  auto* lease = request.mutable_lease();
  request.set_request_id(request_id);
  lease->set_robot_id(robot);
  lease->set_action(action);
  lease->set_timeout_s(timeout_s);
  return connection.call(request, request_id).lease();
}

std::string holder_text(const v1::LeaseReply& reply) {
  if (!reply.has_holder()) return "nobody";
  return "session " + std::to_string(reply.holder().session_id()) + " (" + reply.holder().client_name() + ")";
}

// Refusals (lease held by another session) print the holder and exit 1.
void require_granted(const v1::LeaseReply& reply, const std::string& what) {
  if (!reply.granted()) {
    throw ClientError(what + " of robot '" + reply.robot_id() + "' refused: the lease is held by " +
                      holder_text(reply));
  }
}

int run_lease(const std::string& verb, const Options& options) {
  v1::LeaseRequest::Action action = v1::LeaseRequest::ACTION_UNSPECIFIED;
  if (verb == "acquire") action = v1::LeaseRequest::ACQUIRE;
  if (verb == "retain") action = v1::LeaseRequest::RETAIN;
  if (verb == "return") action = v1::LeaseRequest::RETURN;
  if (verb == "take") action = v1::LeaseRequest::TAKE;
  if (action == v1::LeaseRequest::ACTION_UNSPECIFIED) {
    throw UsageError("lease takes acquire, retain, return or take, got '" + verb + "'");
  }
  const std::string robot = options.required("robot");
  const double timeout_s = options.number("timeout", 0.0);
  Connection connection = connect_role(options, v1::ROLE_CONTROLLER);
  const v1::LeaseReply reply = lease_call(connection, robot, action, timeout_s, 1);
  if (options.json) {
    print_json(reply);
  } else if (reply.granted()) {
    std::cout << verb << " granted: robot " << robot << " held by " << holder_text(reply) << " for "
              << fmt(reply.expires_in_s()) << " s\n";
  } else {
    std::cout << verb << " refused: robot " << robot << " held by " << holder_text(reply) << "\n";
  }
  // A lease belongs to its session: this one ends now, so a granted acquire or take lasts only until the server
  // sees the connection close (the robot is then stopped). Use `occgeo drive` to hold a lease.
  connection.close();
  return reply.granted() ? 0 : 1;
}

// occgeo drive --robot ID BEHAVIOUR [options]: the behaviour is the one bare word.
int run_drive(const std::vector<std::string>& words, const Options& options) {
  if (words.size() > 1) throw UsageError("drive takes one behaviour, got '" + words[0] + "' and '" + words[1] + "'");
  const std::optional<v1::Behaviour> named = proto::behaviour_from_label(words.empty() ? "" : words[0]);
  if (!named || *named == v1::BEHAVIOUR_GOTO || *named == v1::BEHAVIOUR_WAYPOINTS) {
    throw UsageError(
        "drive needs a behaviour: bearcat, bearcat_seed, wander, stop or teleop (goto has its own "
        "command)");
  }
  const v1::Behaviour behaviour = *named;
  const std::string robot = options.required("robot");
  const double v = options.number("v", 0.0);
  const double w = options.number("w", 0.0);
  if (behaviour != v1::BEHAVIOUR_TELEOP && (options.values.contains("v") || options.values.contains("w"))) {
    throw UsageError("options '--v' and '--w' need the teleop behaviour");
  }
  const double hold_s = options.number("hold", 0.0);
  if (hold_s < 0.0 || hold_s > 86400.0) throw UsageError("option '--hold' takes 0 to 86400 seconds");
  const double timeout_s = options.number("timeout", 0.0);

  Connection connection = connect_role(options, v1::ROLE_CONTROLLER);
  std::uint64_t id = 0;
  const v1::LeaseReply acquired = lease_call(connection, robot, v1::LeaseRequest::ACQUIRE, timeout_s, ++id);
  require_granted(acquired, "acquire");
  v1::ClientMessage request;
  auto* drive = request.mutable_drive();
  request.set_request_id(++id);
  drive->set_robot_id(robot);
  drive->set_behaviour(behaviour);
  drive->set_linear_mps(v);
  drive->set_angular_radps(w);
  const v1::DriveReply reply = connection.call(request, id).drive();
  // Retain at a third of the lease's timeout so one late retain never lets it lapse.
  const double period_s = std::clamp(acquired.expires_in_s() / 3.0, 0.05, 1.0);
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(hold_s);
  std::uint64_t retains = 0;
  while (std::chrono::steady_clock::now() < end) {
    const auto left = std::chrono::duration<double>(end - std::chrono::steady_clock::now()).count();
    std::this_thread::sleep_for(std::chrono::duration<double>(std::min(period_s, std::max(0.0, left))));
    if (std::chrono::steady_clock::now() >= end) break;
    require_granted(lease_call(connection, robot, v1::LeaseRequest::RETAIN, timeout_s, ++id), "retain");
    ++retains;
  }
  const v1::LeaseReply returned = lease_call(connection, robot, v1::LeaseRequest::RETURN, 0.0, ++id);
  connection.close();
  if (options.json) {
    std::cout << "{\"robot\":" << json_string(robot)
              << ",\"behaviour\":" << json_string(proto::behaviour_label(reply.behaviour()))
              << ",\"linear_mps\":" << fmt(reply.linear_mps()) << ",\"angular_radps\":" << fmt(reply.angular_radps())
              << ",\"estop\":" << (reply.estop() ? "true" : "false") << ",\"held_s\":" << fmt(hold_s)
              << ",\"retains\":" << retains << ",\"returned\":" << (returned.granted() ? "true" : "false") << "}\n";
  } else {
    std::cout << "robot " << robot << ": " << proto::behaviour_label(reply.behaviour());
    if (reply.behaviour() == v1::BEHAVIOUR_TELEOP) {
      std::cout << " at " << fmt(reply.linear_mps()) << " m/s, " << fmt(reply.angular_radps()) << " rad/s";
    }
    std::cout << (reply.estop() ? " (e-stop engaged: the robot stays stopped)" : "") << ", held " << fmt(hold_s)
              << " s, lease " << (returned.granted() ? "returned" : "lost") << "\n";
  }
  return returned.granted() ? 0 : 1;
}

// Set by SIGINT/SIGTERM while a goal is being followed: the lease is returned before exiting.
volatile std::sig_atomic_t g_interrupted = 0;

extern "C" void on_interrupt(int /*signal*/) { g_interrupted = 1; }

// occgeo goto --robot ID X Y: the two bare words are the goal; negative numbers are goal values, not options.
// occgeo waypoints --robot ID X1,Y1 X2,Y2 ...: each bare word is one waypoint.
int run_goto(bool waypoints, const std::vector<std::string>& goal, const Options& options) {
  const auto number = [](const std::string& text, const std::string& what) {
    const std::optional<double> value = finite_number(text);
    if (!value) throw UsageError(what + " needs a number, got '" + text + "'");
    return *value;
  };
  std::vector<std::pair<double, double>> points;
  if (waypoints) {
    if (goal.empty()) throw UsageError("waypoints needs at least one X,Y (metres, world frame)");
    for (const std::string& word : goal) {
      const auto comma = word.find(',');
      if (comma == std::string::npos) throw UsageError("waypoint '" + word + "' must be X,Y");
      points.emplace_back(number(word.substr(0, comma), "waypoint '" + word + "' X"),
                          number(word.substr(comma + 1), "waypoint '" + word + "' Y"));
    }
  } else {
    if (goal.size() != 2) throw UsageError("goto needs the goal as two numbers X Y (metres, world frame)");
    points.emplace_back(number(goal[0], "goto's X"), number(goal[1], "goto's Y"));
  }
  const double goal_x = points.back().first;
  const double goal_y = points.back().second;
  const std::string robot = options.required("robot");
  const double limit_s = options.number("limit", 600.0);
  if (!(limit_s > 0.0 && limit_s <= 86400.0)) throw UsageError("option '--limit' takes (0, 86400] seconds");
  const double timeout_s = options.number("timeout", 0.0);

  Connection connection = connect_role(options, v1::ROLE_CONTROLLER);
  std::uint64_t id = 0;
  const v1::LeaseReply acquired = lease_call(connection, robot, v1::LeaseRequest::ACQUIRE, timeout_s, ++id);
  require_granted(acquired, "acquire");
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);
  v1::ClientMessage request;
  auto* drive = request.mutable_drive();
  request.set_request_id(++id);
  drive->set_robot_id(robot);
  drive->set_behaviour(waypoints ? v1::BEHAVIOUR_WAYPOINTS : v1::BEHAVIOUR_GOTO);
  drive->set_escape(!options.switches.contains("no-escape"));
  if (waypoints) {
    for (const auto& [x, y] : points) {
      auto* waypoint = drive->add_waypoints();
      waypoint->set_x_m(x);
      waypoint->set_y_m(y);
    }
  } else {
    drive->mutable_goal()->set_x_m(goal_x);
    drive->mutable_goal()->set_y_m(goal_y);
  }
  static_cast<void>(connection.call(request, id).drive());

  // Retain at a third of the lease's timeout so one late retain never lets it lapse; each retain also reads the
  // robot's status for the progress line.
  const double period_s = std::clamp(acquired.expires_in_s() / 3.0, 0.05, 0.5);
  const auto started = std::chrono::steady_clock::now();
  const auto elapsed_s = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  };
  std::string outcome = "limit";
  v1::BehaviourState last_state = v1::BEHAVIOUR_STATE_UNSPECIFIED;
  v1::RobotStatus last;
  double next_print_s = 0.0;
  while (elapsed_s() < limit_s) {
    if (g_interrupted) {
      outcome = "interrupted";
      break;
    }
    v1::ClientMessage status_request;
    status_request.mutable_status();
    status_request.set_request_id(++id);
    const v1::StatusReply status = connection.call(status_request, id).status();
    const auto it = std::find_if(status.robots().begin(), status.robots().end(),
                                 [&](const v1::RobotStatus& r) { return r.id() == robot; });
    if (it == status.robots().end()) throw ClientError("robot '" + robot + "' is no longer registered");
    last = *it;
    const double distance = std::hypot(goal_x - last.pose().x(), goal_y - last.pose().y());
    if (!options.json && (last.behaviour_state() != last_state || elapsed_s() >= next_print_s)) {
      std::cout << "t=" << fmt(elapsed_s()) << "s pose (" << fmt(last.pose().x()) << ", " << fmt(last.pose().y())
                << ") " << fmt(distance) << " m to go, " << proto::behaviour_state_label(last.behaviour_state())
                << (last.guard().action().empty() || last.guard().action() == "pass"
                        ? ""
                        : ", guard " + last.guard().action() + " (" + last.guard().zone() + ", " +
                              last.guard().model() + ")")
                << std::endl;
      next_print_s = elapsed_s() + 1.0;
      last_state = last.behaviour_state();
    }
    if (last.behaviour() == drive->behaviour() && (last.behaviour_state() == v1::BEHAVIOUR_STATE_REACHED ||
                                                   last.behaviour_state() == v1::BEHAVIOUR_STATE_NO_PATH)) {
      outcome = proto::behaviour_state_label(last.behaviour_state());
      break;
    }
    if (!last.connected()) {
      outcome = "disconnected";
      break;
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(period_s));
    require_granted(lease_call(connection, robot, v1::LeaseRequest::RETAIN, timeout_s, ++id), "retain");
  }
  const v1::LeaseReply returned = lease_call(connection, robot, v1::LeaseRequest::RETURN, 0.0, ++id);
  connection.close();
  const double distance = std::hypot(goal_x - last.pose().x(), goal_y - last.pose().y());
  if (options.json) {
    std::cout << "{\"robot\":" << json_string(robot) << ",\"outcome\":" << json_string(outcome)
              << ",\"x\":" << fmt(last.pose().x()) << ",\"y\":" << fmt(last.pose().y())
              << ",\"distance_to_goal_m\":" << fmt(distance) << ",\"wall_s\":" << fmt(elapsed_s())
              << ",\"returned\":" << (returned.granted() ? "true" : "false") << "}\n";
  } else {
    std::cout << "robot " << robot << ": " << outcome << " at (" << fmt(last.pose().x()) << ", " << fmt(last.pose().y())
              << "), " << fmt(distance) << " m from the goal, lease " << (returned.granted() ? "returned" : "lost")
              << "\n";
  }
  if (outcome == "reached") return 0;
  return outcome == "interrupted" ? 130 : 1;
}

int run_estop(const Options& options) {
  const std::string robot = options.required("robot");
  const bool release = options.switches.contains("release");
  // Engaging needs no lease (any observer may); releasing is for the lease holder only.
  Connection connection = connect_role(options, release ? v1::ROLE_CONTROLLER : v1::ROLE_OBSERVER);
  std::uint64_t id = 0;
  if (release) require_granted(lease_call(connection, robot, v1::LeaseRequest::ACQUIRE, 0.0, ++id), "acquire");
  v1::ClientMessage request;
  auto* estop = request.mutable_estop();
  request.set_request_id(++id);
  estop->set_robot_id(robot);
  estop->set_engage(!release);
  const v1::EStopReply reply = connection.call(request, id).estop();
  if (release) lease_call(connection, robot, v1::LeaseRequest::RETURN, 0.0, ++id);
  connection.close();
  if (options.json) {
    print_json(reply);
  } else {
    std::cout << "robot " << robot << ": e-stop " << (reply.engaged() ? "engaged" : "released") << "\n";
  }
  return 0;
}

}  // namespace occgeo::cli
