#include "robot_control.h"

#include <algorithm>
#include <boost/asio/post.hpp>
#include <cmath>
#include <variant>

#include "../metrics.h"
#include "../validation.h"
#include "occgeo/geometry/convex_polygon.h"
#include "occgeo/proto/labels.h"
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
      c.behaviour = v1::BEHAVIOUR_STOP;
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
    send_stop_to_driver(*robot, v1::BEHAVIOUR_STATE_LEASE_EXPIRED, config.command_expiry_s);
  }
  if (went_stale) {
    log::warn("sensor_stale", {{"robot", robot->model().id}, {"timeout_s", config.sensor_timeout_s}});
    send_stop_to_driver(*robot, v1::BEHAVIOUR_STATE_SENSOR_STALE, config.command_expiry_s);
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

v1::MotionCommand make_stop(v1::Behaviour behaviour, v1::BehaviourState state, double expiry_s) {
  v1::MotionCommand command;
  command.set_expires_after_s(expiry_s);
  command.set_behaviour(behaviour);
  command.set_state(state);
  command.set_stop(true);
  return command;
}

}  // namespace

bool known_behaviour(v1::Behaviour behaviour) {
  return v1::Behaviour_IsValid(behaviour) && behaviour != v1::BEHAVIOUR_UNSPECIFIED;
}

// The wire keeps the behaviours' states at the same numbers, followed by the server's own.
static_assert(static_cast<int>(control::kBehaviourStateCount) == v1::BEHAVIOUR_STATE_YIELD_ASIDE + 1);
static_assert(v1::BEHAVIOUR_STATE_YIELD_ASIDE < v1::BEHAVIOUR_STATE_ESTOP);

v1::BehaviourState to_wire(control::BehaviourState state) { return static_cast<v1::BehaviourState>(state); }

namespace {

// A planned path as the robot's state keeps it: shared, null when there is none.
std::shared_ptr<const std::vector<Eigen::Vector2d>> shared_path(std::vector<Eigen::Vector2d> path_W) {
  if (path_W.empty()) return nullptr;
  return std::make_shared<const std::vector<Eigen::Vector2d>>(std::move(path_W));
}

control::RobotShape robot_shape(const RobotModel& model) {
  control::RobotShape shape;
  shape.footprint = model.footprint;
  if (!model.lasers.empty()) shape.laser_x_m = model.lasers.front().X_BS.translation().x();
  if (const auto* skid = std::get_if<geometry::SkidSteerParams>(&model.drive)) {
    shape.max_linear_mps = skid->max_track_speed_mps;
  } else {
    shape.max_linear_mps = std::get<geometry::DifferentialDriveParams>(model.drive).max_wheel_speed_mps;
  }
  return shape;
}

// Speeds from a behaviour as the drive executes them: differential wheel speeds as the behaviour computed them, or
// the body velocity through the drive's kinematics (skid steer: the slippage model); clamped keeping their ratio.
ClampedVelocity executable(const RobotModel& model, const control::BehaviourCommand& wanted) {
  if (const auto* drive = std::get_if<geometry::DifferentialDriveParams>(&model.drive); drive && wanted.wheels) {
    ClampedVelocity out;
    out.wheels = geometry::clamp_to_max_speed(*wanted.wheels, *drive);
    out.body = geometry::to_body(out.wheels, *drive);
    return out;
  }
  return clamp_velocity(model, wanted.linear_mps, wanted.angular_radps);
}

void fill_guard(const control::GuardDecision& decision, double requested_linear_mps, double requested_angular_radps,
                v1::GuardDecision& out) {
  out.set_checked(true);
  out.set_action(std::string(control::guard_action_name(decision.action)));
  out.set_zone(std::string(decision.zone));
  out.set_model(std::string(decision.model));
  out.set_time_to_contact_s(decision.time_to_contact_s);
  out.set_distance_to_contact_m(decision.distance_to_contact_m);
  out.set_requested_linear_mps(requested_linear_mps);
  out.set_requested_angular_radps(requested_angular_radps);
}

// make_behaviour without the yielding to moving obstacles around goto and waypoints (which wraps the escape too).
std::unique_ptr<control::Behaviour> make_plain_behaviour(v1::Behaviour name, const v1::DriveRequest& request,
                                                         const RobotModel& model, const ServerConfig& config) {
  const control::RobotShape shape = robot_shape(model);
  // The Bearcat and wander get out of deadlocks over the map they built (seed 000 §5.2); bearcat_seed is the thesis's
  // behaviour alone, which stops in a deadlock for good. Each robot's Bearcat uses its own wheel separation.
  const control::BearcatParams bearcat = bearcat_params_for(model, config.bearcat);
  if (name == v1::BEHAVIOUR_BEARCAT_SEED) return control::make_bearcat(bearcat);
  if (name == v1::BEHAVIOUR_BEARCAT) {
    return control::make_map_escape([bearcat] { return control::make_bearcat(bearcat); }, shape, config.guard);
  }
  if (name == v1::BEHAVIOUR_WANDER) {
    return control::make_map_escape([shape] { return control::make_wander(control::WanderParams{}, shape); }, shape,
                                    config.guard);
  }
  if ((name == v1::BEHAVIOUR_GOTO || name == v1::BEHAVIOUR_WAYPOINTS) && request.escape()) {
    v1::DriveRequest plain = request;
    plain.set_escape(false);
    return control::make_escape(
        [plain, name, &model, &config] { return make_plain_behaviour(name, plain, model, config); }, shape,
        config.guard);
  }
  if (name == v1::BEHAVIOUR_WAYPOINTS) {
    std::vector<Eigen::Vector2d> waypoints_W;
    for (const auto& w : request.waypoints()) waypoints_W.emplace_back(w.x_m(), w.y_m());
    return control::make_waypoints(shape, std::move(waypoints_W));
  }
  if (name == v1::BEHAVIOUR_GOTO && model.lasers.empty() && !model.servo_ranges.empty()) {
    // Seed 003's robot: PointBug on the swept beam, one decision per servo step.
    const ServoRangeModel& servo = model.servo_ranges.front();
    const control::ServoSweepLimits limits{servo.servo_min_rad, servo.servo_max_rad, servo.servo_step_rad,
                                           servo.range_max_m};
    const Eigen::Vector3d beam_B = servo.X_BS.transform.linear() * Eigen::Vector3d::UnitX();
    control::PointBugParams params = control::pointbug_params_for(shape);
    if (model.encoders) {
      // A pose dead-reckoned from whole ticks knows the heading only to one tick of one wheel over the wheel
      // separation (1.76 degrees on the ActivityBot), as coarse as the seed's own drive_goto turns; a finer tolerance
      // would dither between the two ticks either side of the goal's bearing for ever.
      const double heading_step_rad = geometry::metres_per_tick(*model.encoders) / model.encoders->wheel_separation_m;
      params.heading_tolerance_rad = std::max(params.heading_tolerance_rad, heading_step_rad);
    }
    return control::make_servo_goto(params, limits, std::atan2(beam_B.y(), beam_B.x()), request.goal().x_m(),
                                    request.goal().y_m(), servo.step_period_s);
  }
  if (name == v1::BEHAVIOUR_GOTO) {
    double half_width_m = 0.0;
    std::visit(
        [&](const auto& shape_of) {
          if constexpr (requires { shape_of.width; }) {
            half_width_m = shape_of.width / 2.0;
          } else if constexpr (requires { shape_of.vertices_B; }) {
            half_width_m = std::max(geometry::farthest_along(shape_of.vertices_B, Eigen::Vector2d::UnitY()),
                                    geometry::farthest_along(shape_of.vertices_B, -Eigen::Vector2d::UnitY()));
          } else {
            half_width_m = shape_of.radius;
          }
        },
        model.footprint);
    return control::make_goto(control::pointbug_params_for(shape), request.goal().x_m(), request.goal().y_m(), 0.1,
                              half_width_m + 0.1);
  }
  return nullptr;
}

}  // namespace

std::unique_ptr<control::Behaviour> make_behaviour(v1::Behaviour name, const v1::DriveRequest& request,
                                                   const RobotModel& model, const ServerConfig& config) {
  auto behaviour = make_plain_behaviour(name, request, model, config);
  // A robot with a laser going somewhere yields to the people and carts its PTEM tracks.
  if (behaviour && (name == v1::BEHAVIOUR_GOTO || name == v1::BEHAVIOUR_WAYPOINTS) && !model.lasers.empty()) {
    return control::make_yield(std::move(behaviour), robot_shape(model), config.guard);
  }
  return behaviour;
}

v1::MotionCommand command_for_scan_on_strand(Robot& robot, const control::ScanView& view, double stamp_s,
                                             double expiry_s, const ServerConfig& config,
                                             const std::optional<control::RangeSet>& ring,
                                             const std::optional<control::ServoSample>& servo) {
  const RobotModel& model = robot.model();
  const ControlState control = robot.control().state();
  v1::MotionCommand command;
  command.set_expires_after_s(expiry_s);
  command.set_behaviour(control.behaviour);
  if (control.estop || control.behaviour == v1::BEHAVIOUR_STOP) {
    command.set_state(control.estop ? v1::BEHAVIOUR_STATE_ESTOP : v1::BEHAVIOUR_STATE_STOP);
    command.set_stop(true);
    robot.update_state([](RobotState& s) {
      s.guard.Clear();
      s.path_W.reset();
    });
    return command;
  }
  const std::optional<geometry::Pose2> X_WB = robot.state().X_WB;
  const WorldSnapshot snapshot = robot.world().snapshots_on_strand();
  const std::span<const control::TrackedObstacle> moving_tracks =
      snapshot.moving ? std::span<const control::TrackedObstacle>(*snapshot.moving)
                      : std::span<const control::TrackedObstacle>();
  control::BehaviourCommand wanted;
  std::vector<Eigen::Vector2d> path_W;  // what the behaviour plans from here, for the status and the web view
  v1::BehaviourState state = v1::BEHAVIOUR_STATE_TELEOP;
  if (control.behaviour == v1::BEHAVIOUR_TELEOP) {
    wanted.linear_mps = control.teleop_linear_mps;
    wanted.angular_radps = control.teleop_angular_radps;
  } else {
    auto& active = robot.active_behaviour_on_strand();
    try {
      // Rebuilt only for a newly accepted DriveRequest: every other change of behaviour (a lapsed lease, a refused
      // request, the controller gone) is to stop or teleop, which run none, and leaving them takes a DriveRequest.
      if (!active || robot.active_generation_on_strand() != control.drive_generation) {
        active = make_behaviour(control.behaviour, control.drive, model, config);
        robot.active_generation_on_strand() = control.drive_generation;
      }
      if (!active) {
        throw std::invalid_argument("drive.behaviour '" + proto::behaviour_label(control.behaviour) +
                                    "' has no decision");
      }
      wanted = active->decide({view, X_WB, stamp_s, snapshot.grid.get(), snapshot.ptem.get(), snapshot.octomap.get(),
                               ring, servo, moving_tracks});
      path_W = active->planned_path();
      state = to_wire(wanted.state);
    } catch (const std::invalid_argument& e) {
      log::warn("behaviour_error",
                {{"robot", model.id}, {"behaviour", proto::behaviour_label(control.behaviour)}, {"error", e.what()}});
      wanted = control::BehaviourCommand{};
      wanted.stop = true;
      state = v1::BEHAVIOUR_STATE_BEHAVIOUR_ERROR;
    }
  }
  command.set_state(state);
  if (wanted.stop) {
    command.set_stop(true);
    robot.update_state([&](RobotState& s) {
      s.guard.Clear();
      s.path_W = shared_path(std::move(path_W));
    });
    return command;
  }
  ClampedVelocity velocity = executable(model, wanted);
  v1::GuardDecision guard;
  if (config.guard.enabled && X_WB) {
    const std::vector<control::TrackedObstacle> moving =
        control.behaviour == v1::BEHAVIOUR_TELEOP || !robot.active_behaviour_on_strand()
            ? std::vector<control::TrackedObstacle>{}
            : robot.active_behaviour_on_strand()->moving_obstacles();
    const control::GuardModels models{snapshot.grid.get(), snapshot.octomap.get(), snapshot.ptem.get(),
                                      snapshot.ptem.get(), moving_tracks};
    const control::GuardDecision decision = control::guard_command(
        models, model.footprint, *X_WB, velocity.body.linear_mps, velocity.body.angular_radps, config.guard, moving);
    fill_guard(decision, velocity.body.linear_mps, velocity.body.angular_radps, guard);
    if (decision.action != control::GuardAction::kPass) {
      velocity = clamp_velocity(model, decision.linear_mps, decision.angular_radps);
      robot.counters().guard_interventions.inc();
    }
  }
  if (model.encoders && model.spec.command_units() == v1::COMMAND_UNITS_ACTIVITYBOT_TICKS) {
    // Seed 003's robot takes whole encoder ticks (abdrive): its wheel speeds become ticks per second, and a straight
    // leg the behaviour drives to its end, unchanged by the guard, becomes a drive_goto of the leg's ticks.
    const double metres_per_tick = geometry::metres_per_tick(*model.encoders);
    const auto ticks = [&](double metres) { return static_cast<std::int32_t>(std::lround(metres / metres_per_tick)); };
    const bool guard_passed = !guard.checked() || guard.action() == "pass";
    if (wanted.leg_m && guard_passed && velocity.wheels.left_mps > 0.0) {
      const auto leg_ticks = static_cast<std::int64_t>(std::lround(*wanted.leg_m / metres_per_tick));
      v1::DriveGoto& drive_goto = *command.mutable_drive_goto();
      drive_goto.set_left_ticks(leg_ticks);
      drive_goto.set_right_ticks(leg_ticks);
      drive_goto.set_id(wanted.leg_id);
      drive_goto.set_max_ticks_per_s(std::max(1, ticks(velocity.wheels.left_mps)));
    } else {
      v1::DriveSpeed& drive_speed = *command.mutable_drive_speed();
      drive_speed.set_left_ticks_per_s(ticks(velocity.wheels.left_mps));
      drive_speed.set_right_ticks_per_s(ticks(velocity.wheels.right_mps));
      // What the wheels will do: the speeds the whole ticks give.
      const auto* drive = std::get_if<geometry::DifferentialDriveParams>(&model.drive);
      velocity.wheels = {drive_speed.left_ticks_per_s() * metres_per_tick,
                         drive_speed.right_ticks_per_s() * metres_per_tick};
      if (drive != nullptr) velocity.body = geometry::to_body(velocity.wheels, *drive);
    }
  }
  command.set_left_wheel_mps(velocity.wheels.left_mps);
  command.set_right_wheel_mps(velocity.wheels.right_mps);
  command.set_linear_mps(velocity.body.linear_mps);
  command.set_angular_radps(velocity.body.angular_radps);
  command.set_stop(velocity.wheels.left_mps == 0.0 && velocity.wheels.right_mps == 0.0);
  *command.mutable_guard() = guard;
  robot.update_state([&](RobotState& s) {
    s.guard = guard;
    s.path_W = shared_path(std::move(path_W));
  });
  return command;
}

void send_command_on_strand(const SessionPtr& session, Robot& robot, v1::MotionCommand command,
                            std::uint64_t answers_seq) {
  command.set_answers_scan_seq(answers_seq);
  v1::BehaviourState previous_state = v1::BEHAVIOUR_STATE_UNSPECIFIED;
  robot.update_state([&](RobotState& state) {
    command.set_seq(++state.commands_sent);
    previous_state = state.behaviour_state;
    state.behaviour = command.behaviour();
    state.behaviour_state = command.state();
    state.last_linear_mps = command.linear_mps();
    state.last_angular_radps = command.angular_radps();
  });
  if (command.state() != previous_state) {
    const auto level = command.stop() ? log::Level::warn : log::Level::debug;
    if (log::enabled(level)) {
      log::write(level, "behaviour_state",
                 {{"robot", robot.model().id},
                  {"state", proto::behaviour_state_label(command.state())},
                  {"scan_seq", answers_seq}});
    }
  }
  v1::ServerMessage reply;
  *reply.mutable_motion_command() = std::move(command);
  session->send(reply);
}

v1::MotionCommand stop_command(Robot& robot, v1::Behaviour behaviour, v1::BehaviourState state, double expiry_s,
                               std::uint64_t answers_scan_seq) {
  v1::MotionCommand command = make_stop(behaviour, state, expiry_s);
  command.set_answers_scan_seq(answers_scan_seq);
  robot.update_state([&](RobotState& s) {
    command.set_seq(++s.commands_sent);
    s.behaviour_state = state;
    s.last_linear_mps = 0.0;
    s.last_angular_radps = 0.0;
    s.path_W.reset();
  });
  return command;
}

void send_stop_to_driver(Robot& robot, v1::BehaviourState state, double expiry_s) {
  const ControlState control = robot.control().state();
  const auto driver = control.driver.lock();
  if (!driver) return;
  v1::ServerMessage message;
  *message.mutable_motion_command() = stop_command(robot, control.behaviour, state, expiry_s);
  driver->send(message);
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
      c.behaviour = v1::BEHAVIOUR_STOP;
      c.teleop_linear_mps = 0.0;
      c.teleop_angular_radps = 0.0;
      return true;
    });
    if (!released) continue;
    log::warn("lease_holder_disconnected", {{"robot", robot->model().id}, {"session", info.id}});
    send_stop_to_driver(*robot, v1::BEHAVIOUR_STATE_CONTROLLER_DISCONNECTED, config.command_expiry_s);
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
