#include "robot_control.h"

#include <boost/asio/post.hpp>
#include <variant>

#include "../validation.h"
#include "occgeo/service/log.h"

namespace occgeo::service {

namespace {

using Clock = std::chrono::steady_clock;

Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

// The earliest moment a watchdog has something to check, if any.
std::optional<Clock::time_point> next_deadline(const ControlState& control, const RobotModel& model,
                                               const ControlConfig& config) {
  std::optional<Clock::time_point> next;
  if (control.lease) next = control.lease->expires_at;
  if (!model.lasers.empty() && !control.driver.expired() && control.last_sensor_at && !control.sensor_stale) {
    const Clock::time_point sensor_deadline = *control.last_sensor_at + seconds(config.sensor_timeout_s);
    if (!next || sensor_deadline < *next) next = sensor_deadline;
  }
  return next;
}

void arm_on_strand(const std::shared_ptr<Robot>& robot, const ControlConfig& config, bool only_if_earlier);

// A watchdog deadline has passed: lapse an expired lease, mark stale sensors; each stops the robot once.
void fire_on_strand(const std::shared_ptr<Robot>& robot, const ControlConfig& config) {
  const Clock::time_point now = Clock::now();
  std::string lapsed_holder;
  bool went_stale = false;
  robot->control().update([&](ControlState& c) {
    if (c.lease && c.lease->expires_at <= now) {
      lapsed_holder = describe_holder(c.lease);
      c.lease.reset();
      c.behaviour = "stop";
      c.teleop_linear_mps = 0.0;
      c.teleop_angular_radps = 0.0;
    }
    if (!robot->model().lasers.empty() && !c.driver.expired() && c.last_sensor_at && !c.sensor_stale &&
        now - *c.last_sensor_at >= seconds(config.sensor_timeout_s)) {
      c.sensor_stale = true;
      went_stale = true;
    }
  });
  if (!lapsed_holder.empty()) {
    log::warn("lease_expired", {{"robot", robot->model().id}, {"holder", lapsed_holder}});
    send_stop_to_driver(*robot, "lease_expired", config.command_expiry_s);
  }
  if (went_stale) {
    log::warn("sensor_stale", {{"robot", robot->model().id}, {"timeout_s", config.sensor_timeout_s}});
    send_stop_to_driver(*robot, "sensor_stale", config.command_expiry_s);
  }
  arm_on_strand(robot, config, false);
}

void arm_on_strand(const std::shared_ptr<Robot>& robot, const ControlConfig& config, bool only_if_earlier) {
  const auto next = next_deadline(robot->control().state(), robot->model(), config);
  auto& armed = robot->watchdog_deadline_on_strand();
  auto& timer = robot->watchdog_timer_on_strand();
  if (robot->watchdog_stopped_on_strand()) return;
  if (!next) {
    if (armed) {
      armed.reset();
      timer.cancel();
    }
    return;
  }
  if (armed && (*armed == *next || (only_if_earlier && *armed < *next))) return;
  armed = *next;
  timer.expires_at(*next);  // cancels a pending wait: its handler sees operation_aborted
  timer.async_wait([weak = robot->weak_from_this(), deadline = *next, config](const boost::system::error_code& error) {
    if (error) return;
    const auto self = weak.lock();
    if (!self || self->watchdog_deadline_on_strand() != deadline) return;  // superseded
    self->watchdog_deadline_on_strand().reset();
    fire_on_strand(self, config);
  });
}

v1::MotionCommand make_stop(const std::string& behaviour, const std::string& state, double expiry_s) {
  v1::MotionCommand command;
  command.set_expires_after_s(expiry_s);
  command.set_behaviour(behaviour);
  command.set_state(state);
  command.set_stop(true);
  return command;
}

}  // namespace

bool known_behaviour(const std::string& name) { return name == "bearcat" || name == "stop" || name == "teleop"; }

v1::MotionCommand stop_command(Robot& robot, const std::string& behaviour, const std::string& state, double expiry_s,
                               std::uint64_t answers_scan_seq) {
  v1::MotionCommand command = make_stop(behaviour, state, expiry_s);
  command.set_answers_scan_seq(answers_scan_seq);
  robot.update_state([&](RobotState& s) {
    command.set_seq(++s.commands_sent);
    s.behaviour_state = state;
    s.last_linear_mps = 0.0;
    s.last_angular_radps = 0.0;
  });
  return command;
}

void send_stop_to_driver(Robot& robot, const std::string& state, double expiry_s) {
  const ControlState control = robot.control().state();
  const auto driver = control.driver.lock();
  if (!driver) return;
  v1::ServerMessage message;
  *message.mutable_motion_command() = stop_command(robot, control.behaviour, state, expiry_s);
  driver->send(std::move(message));
}

void fill_holder(const std::optional<Lease>& lease, v1::LeaseHolder& holder) {
  if (!lease) return;
  holder.set_session_id(lease->session_id);
  holder.set_client_name(lease->client_name);
}

double seconds_left(const std::optional<Lease>& lease, Clock::time_point now) {
  if (!lease || lease->expires_at <= now) return 0.0;
  return std::chrono::duration<double>(lease->expires_at - now).count();
}

std::string describe_holder(const std::optional<Lease>& lease) {
  if (!lease) return "nobody";
  return "session " + std::to_string(lease->session_id) + " ('" + lease->client_name + "')";
}

void refresh_watchdog(const std::shared_ptr<Robot>& robot, const ControlConfig& config) {
  asio::post(robot->world().strand(), [robot, config] { arm_on_strand(robot, config, false); });
}

void note_sensor_message_on_strand(Robot& robot, const ControlConfig& config) {
  bool connected_driver = false;
  robot.control().update([&](ControlState& c) {
    connected_driver = !c.driver.expired();
    if (!connected_driver) return;
    c.last_sensor_at = Clock::now();
    c.sensor_stale = false;
  });
  if (connected_driver) arm_on_strand(robot.shared_from_this(), config, true);
}

void release_session_control(ServerCore& core, const SessionInfo& info) {
  const ControlConfig& config = core.config().control;
  if (info.role == v1::ROLE_DRIVER && info.robot) {
    info.robot->control().update([](ControlState& c) {
      c.driver.reset();
      c.last_sensor_at.reset();
      c.sensor_stale = false;
    });
    refresh_watchdog(info.robot, config);
  }
  if (info.role != v1::ROLE_CONTROLLER) return;
  for (const auto& robot : core.robots()) {
    const bool released = robot->control().update([&](ControlState& c) {
      if (!c.lease || c.lease->session_id != info.id) return false;
      c.lease.reset();
      c.behaviour = "stop";
      c.teleop_linear_mps = 0.0;
      c.teleop_angular_radps = 0.0;
      return true;
    });
    if (!released) continue;
    log::warn("lease_holder_disconnected", {{"robot", robot->model().id}, {"session", info.id}});
    send_stop_to_driver(*robot, "controller_disconnected", config.command_expiry_s);
    refresh_watchdog(robot, config);
  }
}

std::shared_ptr<Robot> find_named_robot(const SessionPtr& session, const std::string& robot_id,
                                        const std::string& message, std::uint64_t request_id) {
  if (!valid_name(robot_id)) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, message + ".robot_id",
                        "a robot id is 1-64 characters of A-Z a-z 0-9 _ . -", request_id);
    return nullptr;
  }
  auto robot = session->core().find_robot(robot_id);
  if (!robot) {
    session->send_error(v1::ERROR_UNKNOWN_ROBOT, message + ".robot_id", "no robot '" + robot_id + "' is registered",
                        request_id);
  }
  return robot;
}

bool constant_time_equal(const std::string& a, const std::string& b) {
  // Every byte of the longer string is visited whatever the contents; only the lengths leak.
  const std::size_t n = std::max(a.size(), b.size());
  unsigned difference = a.size() == b.size() ? 0U : 1U;
  for (std::size_t i = 0; i < n; ++i) {
    const auto x = static_cast<unsigned char>(i < a.size() ? a[i] : 0);
    const auto y = static_cast<unsigned char>(i < b.size() ? b[i] : 0);
    difference |= static_cast<unsigned>(x ^ y);
  }
  return difference == 0U;
}

ClampedVelocity clamp_velocity(const RobotModel& model, double linear_mps, double angular_radps) {
  const geometry::BodyVelocity wanted{linear_mps, angular_radps};
  ClampedVelocity out;
  if (const auto* skid = std::get_if<geometry::SkidSteerParams>(&model.drive)) {
    out.wheels = geometry::clamp_to_max_speed(geometry::to_wheels(wanted, *skid), *skid);
    out.body = geometry::to_body(out.wheels, *skid);
  } else {
    const auto& drive = std::get<geometry::DifferentialDriveParams>(model.drive);
    out.wheels = geometry::clamp_to_max_speed(geometry::to_wheels(wanted, drive), drive);
    out.body = geometry::to_body(out.wheels, drive);
  }
  return out;
}

}  // namespace occgeo::service
