#include "occgeo/service/log.h"
#include "robot_control.h"

namespace occgeo::service {

void handle_estop(const SessionPtr& session, std::uint64_t request_id, const v1::EStop& request) {
  const SessionInfo& info = session->info();
  auto robot = find_named_robot(session, request.robot_id(), "estop", request_id);
  if (!robot) return;
  const auto now = std::chrono::steady_clock::now();
  bool refused = false;
  bool engaged_now = false;
  std::optional<Lease> lease;
  robot->control().update([&](ControlState& c) {
    const bool holder = c.lease && c.lease->session_id == info.id && c.lease->expires_at > now;
    if (request.engage()) {
      engaged_now = !c.estop;
      c.estop = true;
    } else if (c.estop && !holder) {
      refused = true;
    } else {
      c.estop = false;
    }
    lease = c.lease;
  });
  if (refused) {
    session->send_error(v1::ERROR_NOT_ALLOWED, "estop.engage",
                        "only the lease holder may release robot '" + request.robot_id() + "''s e-stop (held by " +
                            describe_holder(lease) + ")",
                        request_id);
    return;
  }
  if (request.engage()) {
    // The next scan would be answered by a stop anyway; this one does not wait for it.
    send_stop_to_driver(*robot, v1::BEHAVIOUR_STATE_ESTOP, session->core().config().control.command_expiry_s);
  }
  v1::ServerMessage reply;
  auto* out = reply.mutable_estop();
  reply.set_request_id(request_id);
  out->set_robot_id(request.robot_id());
  out->set_engaged(request.engage());
  if (lease) fill_holder(lease, *out->mutable_holder());
  session->send(reply);
  if (request.engage() ? engaged_now : true) {
    log::warn("estop", {{"robot", request.robot_id()},
                        {"session", info.id},
                        {"role", v1::Role_Name(info.role)},
                        {"engaged", request.engage()}});
  }
}

}  // namespace occgeo::service
