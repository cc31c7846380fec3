#include <cmath>

#include "occgeo/service/log.h"
#include "robot_control.h"

namespace occgeo::service {

void handle_drive_request(const SessionPtr& session, const v1::DriveRequest& request) {
  const SessionInfo& info = session->info();
  const std::uint64_t request_id = request.request_id();
  if (!known_behaviour(request.behaviour())) {
    session->send_error(
        v1::ERROR_INVALID_ARGUMENT, "drive.behaviour",
        "must be \"bearcat\", \"stop\" or \"teleop\", not \"" + request.behaviour().substr(0, 64) + "\"", request_id);
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
  session->send(std::move(reply));
  log::info("drive", {{"robot", request.robot_id()},
                      {"session", info.id},
                      {"behaviour", request.behaviour()},
                      {"linear_mps", velocity.body.linear_mps},
                      {"angular_radps", velocity.body.angular_radps}});
}

}  // namespace occgeo::service
