#include <cmath>

#include "occgeo/service/log.h"
#include "robot_control.h"

namespace occgeo::service {

void handle_lease_request(const SessionPtr& session, std::uint64_t request_id, const v1::LeaseRequest& request) {
  const SessionInfo& info = session->info();
  const ControlConfig& config = session->core().config().control;
  const auto action = request.action();
  if (action != v1::LeaseRequest::ACQUIRE && action != v1::LeaseRequest::RETAIN && action != v1::LeaseRequest::RETURN &&
      action != v1::LeaseRequest::TAKE) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "lease.action", "must be ACQUIRE, RETAIN, RETURN or TAKE",
                        request_id);
    return;
  }
  const double asked_s = request.timeout_s();
  if (!std::isfinite(asked_s) || asked_s < 0.0 || asked_s > config.max_lease_timeout_s) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "lease.timeout_s",
                        "must be 0 (the server's control.lease_timeout_s) or a number of seconds up to " +
                            std::to_string(config.max_lease_timeout_s),
                        request_id);
    return;
  }
  auto robot = find_named_robot(session, request.robot_id(), "lease", request_id);
  if (!robot) return;
  if (action == v1::LeaseRequest::TAKE && !info.is_operator) {
    session->send_error(v1::ERROR_UNAUTHENTICATED, "lease.action",
                        "TAKE needs the operator token (auth.operator_token) in this session's hello.auth_token",
                        request_id);
    return;
  }

  using Clock = std::chrono::steady_clock;
  const Clock::time_point now = Clock::now();
  const auto after = [&](double s) {
    return now + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
  };
  bool granted = false;
  bool lapsed = false;  // a lease past its expiry that the watchdog has not handled yet
  std::string previous;
  std::optional<Lease> lease;
  robot->control().update([&](ControlState& c) {
    if (c.lease && c.lease->expires_at <= now) {
      c.lease.reset();
      c.behaviour = v1::BEHAVIOUR_STOP;
      c.teleop_linear_mps = 0.0;
      c.teleop_angular_radps = 0.0;
      lapsed = true;
    }
    const bool mine = c.lease && c.lease->session_id == info.id;
    previous = describe_holder(c.lease);
    const double timeout_s = asked_s > 0.0 ? asked_s : config.lease_timeout_s;
    switch (action) {
      case v1::LeaseRequest::ACQUIRE:
      case v1::LeaseRequest::TAKE:
        if (c.lease && !mine && action == v1::LeaseRequest::ACQUIRE) break;
        if (c.lease && !mine && c.behaviour == v1::BEHAVIOUR_TELEOP)
          c.behaviour = v1::BEHAVIOUR_STOP;  // velocities were the old holder's
        c.lease = Lease{info.id, info.client_name, timeout_s, after(timeout_s)};
        granted = true;
        break;
      case v1::LeaseRequest::RETAIN:
        if (!mine) break;
        if (asked_s > 0.0) c.lease->timeout_s = asked_s;
        c.lease->expires_at = after(c.lease->timeout_s);
        granted = true;
        break;
      case v1::LeaseRequest::RETURN:
        if (!mine) break;
        c.lease.reset();
        if (c.behaviour == v1::BEHAVIOUR_TELEOP) c.behaviour = v1::BEHAVIOUR_STOP;  // teleop velocities need a holder
        granted = true;
        break;
      default:
        break;
    }
    lease = c.lease;
  });
  if (lapsed) send_stop_to_driver(*robot, v1::BEHAVIOUR_STATE_LEASE_EXPIRED, config.command_expiry_s);
  refresh_watchdog(robot, config);

  v1::ServerMessage reply;
  auto* out = reply.mutable_lease();
  reply.set_request_id(request_id);
  out->set_robot_id(request.robot_id());
  out->set_granted(granted);
  if (lease) fill_holder(lease, *out->mutable_holder());
  out->set_expires_in_s(seconds_left(lease, now));
  session->send(reply);
  log::info("lease", {{"robot", request.robot_id()},
                      {"session", info.id},
                      {"action", v1::LeaseRequest::Action_Name(action)},
                      {"granted", granted},
                      {"previous_holder", previous}});
}

}  // namespace occgeo::service
