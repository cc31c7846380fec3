#include <cmath>

#include "occgeo/service/log.h"
#include "robot_control.h"

namespace occgeo::service {

void handle_drive_request(const SessionPtr& session, const v1::DriveRequest& request) {
  const SessionInfo& info = session->info();
  const std::uint64_t request_id = request.request_id();
  if (!known_behaviour(request.behaviour())) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "drive.behaviour",
                        "must be \"bearcat\", \"stop\", \"teleop\", \"wander\", \"goto\" or \"waypoints\", not \"" +
                            request.behaviour().substr(0, 64) + "\"",
                        request_id);
    return;
  }
  if (!std::isfinite(request.linear_mps())) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "drive.linear_mps", "must be finite", request_id);
    return;
  }
  if (!std::isfinite(request.angular_radps())) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "drive.angular_radps", "must be finite", request_id);
    return;
  }
  if (request.behaviour() == "goto") {
    if (!request.has_goal()) {
      session->send_error(v1::ERROR_INVALID_ARGUMENT, "drive.goal", "goto needs a goal", request_id);
      return;
    }
    const double limit = session->core().config().limits.max_abs_coordinate_m;
    for (const auto& [value, field] :
         {std::pair{request.goal().x_m(), "drive.goal.x_m"}, std::pair{request.goal().y_m(), "drive.goal.y_m"}}) {
      if (!std::isfinite(value) || std::abs(value) > limit) {
        session->send_error(v1::ERROR_INVALID_ARGUMENT, field,
                            "must be finite and within limits.max_abs_coordinate_m of the origin", request_id);
        return;
      }
    }
  }
  if (request.behaviour() == "waypoints") {
    constexpr int kMaxWaypoints = 1000;
    if (request.waypoints_size() == 0 || request.waypoints_size() > kMaxWaypoints) {
      session->send_error(v1::ERROR_INVALID_ARGUMENT, "drive.waypoints", "waypoints needs 1 to 1000 waypoints",
                          request_id);
      return;
    }
    const double limit = session->core().config().limits.max_abs_coordinate_m;
    for (int i = 0; i < request.waypoints_size(); ++i) {
      const auto& w = request.waypoints(i);
      if (!std::isfinite(w.x_m()) || !std::isfinite(w.y_m()) || std::abs(w.x_m()) > limit ||
          std::abs(w.y_m()) > limit) {
        session->send_error(v1::ERROR_INVALID_ARGUMENT, "drive.waypoints[" + std::to_string(i) + "]",
                            "must be finite and within limits.max_abs_coordinate_m of the origin", request_id);
        return;
      }
    }
  }
  auto robot = find_named_robot(session, request.robot_id(), "drive", request_id);
  if (!robot) return;
  ClampedVelocity velocity;
  if (request.behaviour() == "teleop") {
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
  out->set_request_id(request_id);
  out->set_robot_id(request.robot_id());
  out->set_behaviour(request.behaviour());
  out->set_linear_mps(velocity.body.linear_mps);
  out->set_angular_radps(velocity.body.angular_radps);
  out->set_estop(estop);
  session->send(reply);
  log::info("drive", {{"robot", request.robot_id()},
                      {"session", info.id},
                      {"behaviour", request.behaviour()},
                      {"linear_mps", velocity.body.linear_mps},
                      {"angular_radps", velocity.body.angular_radps}});
}

}  // namespace occgeo::service
