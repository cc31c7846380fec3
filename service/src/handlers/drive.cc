#include <cmath>

#include "../validation.h"
#include "occgeo/proto/labels.h"
#include "occgeo/service/log.h"
#include "robot_control.h"

namespace occgeo::service {

void handle_drive_request(const SessionPtr& session, std::uint64_t request_id, const v1::DriveRequest& request) {
  const SessionInfo& info = session->info();
  if (!known_behaviour(request.behaviour())) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "drive.behaviour",
                        "must be a Behaviour (" + proto::behaviour_labels() + "), not " +
                            (v1::Behaviour_IsValid(request.behaviour()) ? v1::Behaviour_Name(request.behaviour())
                                                                        : std::to_string(request.behaviour())),
                        request_id);
    return;
  }
  // A request the robot cannot carry out leaves it stopped when this session drives it, rather than carrying on with
  // the plan the request meant to replace.
  const auto refuse = [&](const std::string& field, const std::string& message) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, field, message, request_id);
    if (!valid_name(request.robot_id())) return;
    const auto robot = session->core().find_robot(request.robot_id());
    if (!robot) return;
    const auto now = std::chrono::steady_clock::now();
    const bool stopped = robot->control().update([&](ControlState& c) {
      if (!c.lease || c.lease->session_id != info.id || c.lease->expires_at <= now) return false;
      c.behaviour = v1::BEHAVIOUR_STOP;
      c.teleop_linear_mps = 0.0;
      c.teleop_angular_radps = 0.0;
      ++c.drive_generation;
      return true;
    });
    if (stopped) {
      log::warn("drive_refused", {{"robot", request.robot_id()}, {"field", field}, {"error", message}});
      send_stop_to_driver(*robot, v1::BEHAVIOUR_STATE_DRIVE_REFUSED, session->core().config().control.command_expiry_s);
    }
  };
  if (!std::isfinite(request.linear_mps())) {
    refuse("drive.linear_mps", "must be finite");
    return;
  }
  if (!std::isfinite(request.angular_radps())) {
    refuse("drive.angular_radps", "must be finite");
    return;
  }
  if (request.behaviour() == v1::BEHAVIOUR_GOTO) {
    if (!request.has_goal()) {
      refuse("drive.goal", "goto needs a goal");
      return;
    }
    const double limit = session->core().config().limits.max_abs_coordinate_m;
    for (const auto& [value, field] :
         {std::pair{request.goal().x_m(), "drive.goal.x_m"}, std::pair{request.goal().y_m(), "drive.goal.y_m"}}) {
      if (!std::isfinite(value) || std::abs(value) > limit) {
        refuse(field, "the goal is outside the world: it must be finite and within limits.max_abs_coordinate_m (" +
                          std::to_string(limit) + " m) of the origin");
        return;
      }
    }
  }
  if (request.behaviour() == v1::BEHAVIOUR_WAYPOINTS) {
    constexpr int kMaxWaypoints = 1000;
    if (request.waypoints_size() == 0 || request.waypoints_size() > kMaxWaypoints) {
      refuse("drive.waypoints", "waypoints needs 1 to 1000 waypoints");
      return;
    }
    const double limit = session->core().config().limits.max_abs_coordinate_m;
    for (int i = 0; i < request.waypoints_size(); ++i) {
      const auto& w = request.waypoints(i);
      if (!std::isfinite(w.x_m()) || !std::isfinite(w.y_m()) || std::abs(w.x_m()) > limit ||
          std::abs(w.y_m()) > limit) {
        refuse("drive.waypoints[" + std::to_string(i) + "]",
               "must be finite and within limits.max_abs_coordinate_m of the origin");
        return;
      }
    }
  }
  auto robot = find_named_robot(session, request.robot_id(), "drive", request_id);
  if (!robot) return;
  if (const std::optional<std::string> missing = missing_sensor_for(request.behaviour(), robot->model())) {
    refuse("drive.behaviour", *missing);
    return;
  }
  ClampedVelocity velocity;
  if (request.behaviour() == v1::BEHAVIOUR_TELEOP) {
    velocity = clamp_velocity(robot->model(), request.linear_mps(), request.angular_radps());
  }
  const auto now = std::chrono::steady_clock::now();
  bool holder = false;
  std::string current;
  bool estop = false;
  robot->control().update([&](ControlState& c) {
    holder = c.lease && c.lease->session_id == info.id && c.lease->expires_at > now;
    current = describe_holder(c.lease);
    estop = c.estop;
    if (!holder) return;
    c.behaviour = request.behaviour();
    c.teleop_linear_mps = velocity.body.linear_mps;
    c.teleop_angular_radps = velocity.body.angular_radps;
    c.drive = request;
    ++c.drive_generation;
  });
  if (!holder) {
    session->send_error(v1::ERROR_NOT_ALLOWED, "drive.robot_id",
                        "this session does not hold robot '" + request.robot_id() + "''s lease (held by " + current +
                            "); send a lease ACQUIRE first",
                        request_id);
    return;
  }
  v1::ServerMessage reply;
  auto* out = reply.mutable_drive();
  reply.set_request_id(request_id);
  out->set_robot_id(request.robot_id());
  out->set_behaviour(request.behaviour());
  out->set_linear_mps(velocity.body.linear_mps);
  out->set_angular_radps(velocity.body.angular_radps);
  out->set_estop(estop);
  session->send(reply);
  log::info("drive", {{"robot", request.robot_id()},
                      {"session", info.id},
                      {"behaviour", proto::behaviour_label(request.behaviour())},
                      {"linear_mps", velocity.body.linear_mps},
                      {"angular_radps", velocity.body.angular_radps}});
}

}  // namespace occgeo::service
