#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include "handlers.h"

namespace occgeo::service {

// The server side of driving a robot safely: leases, behaviours set by the lease holder, the
// e-stop latch and the watchdogs (lease expiry, stale sensors). See docs/PROTOCOL.md "Control".

// The behaviours a lease holder may set: every Behaviour this build knows but BEHAVIOUR_UNSPECIFIED.
[[nodiscard]] bool known_behaviour(v1::Behaviour behaviour);

// A behaviour's state as the wire numbers it (the same number; the wire adds the server's own states after them).
[[nodiscard]] v1::BehaviourState to_wire(control::BehaviourState state);

// A stop command for the robot (wheel speeds 0, stop set), answering no scan (answers_scan_seq 0)
// unless `answers_scan_seq` is given; counts it in the robot's state.
v1::MotionCommand stop_command(Robot& robot, v1::Behaviour behaviour, v1::BehaviourState state, double expiry_s,
                               std::uint64_t answers_scan_seq = 0);

// Sends an unsolicited stop command to the robot's connected driver, if any; thread-safe.
void send_stop_to_driver(Robot& robot, v1::BehaviourState state, double expiry_s);

// The lease as the protocol shows it: holder and seconds left.
void fill_holder(const std::optional<Lease>& lease, v1::LeaseHolder& holder);
[[nodiscard]] double seconds_left(const std::optional<Lease>& lease, std::chrono::steady_clock::time_point now);
[[nodiscard]] std::string describe_holder(const std::optional<Lease>& lease);

// Brings the robot's watchdog timer in step with its control state: armed for the earliest of
// the lease's expiry and (for a connected driver of a robot with a laser) the sensor deadline,
// cancelled when there is neither. Each firing does O(1) work and re-arms only for a later
// deadline. Posts to the world's strand; thread-safe.
void refresh_watchdog(const std::shared_ptr<Robot>& robot, const ControlConfig& config);

// Records a sensor message of the connected driver (clears sensor_stale) and arms the sensor
// watchdog if needed; call only from the world's strand.
void note_sensor_message_on_strand(Robot& robot, const ControlConfig& config);

// The body velocity (linear m/s, angular rad/s) as wheel (or track rim) speeds within the robot's
// maximum, keeping their ratio, and the body velocity those clamped speeds produce.
struct ClampedVelocity {
  geometry::WheelSpeeds wheels;
  geometry::BodyVelocity body;
};
[[nodiscard]] ClampedVelocity clamp_velocity(const RobotModel& model, double linear_mps, double angular_radps);

// The command answering one scan of the robot's first laser (sensor frame view, stamp in seconds): a stop while the
// e-stop is latched or the behaviour is BEHAVIOUR_STOP, the teleop velocities, or the decision of the behaviour the
// lease holder set (rebuilt when a new DriveRequest was accepted); every moving command then passes the safety guard
// (config.guard) against the world's latest snapshot, and the guard's verdict is recorded in the robot's state.
// answers_scan_seq and seq are left to the caller. Call only from the world's strand.
// A robot without a laser passes its first range array's readings as `ring` (base_link bearings and distances) and an
// empty view; a robot whose only range sensor is a servo-swept beam passes each reading of its first one as `servo`.
v1::MotionCommand command_for_scan_on_strand(Robot& robot, const control::ScanView& view, double stamp_s,
                                             double expiry_s, const ServerConfig& config,
                                             const std::optional<control::RangeSet>& ring = std::nullopt,
                                             const std::optional<control::ServoSample>& servo = std::nullopt);

// Numbers the command as answering sensor message `answers_seq`, records it in the robot's state (logging a change of
// behaviour state) and sends it on the driver's session. Call only from the world's strand.
void send_command_on_strand(const SessionPtr& session, Robot& robot, v1::MotionCommand command,
                            std::uint64_t answers_seq);

// The behaviour a DriveRequest names, built for this robot; nullptr for "stop" and "teleop" (no decision needed).
// Throws std::invalid_argument naming the field when its parameters are wrong.
std::unique_ptr<control::Behaviour> make_behaviour(v1::Behaviour name, const v1::DriveRequest& request,
                                                   const RobotModel& model, const ServerConfig& config);

// A session ends: a driver's robot has no driver any more; every lease a controller held is freed
// and its robot stopped (behaviour "stop", a stop command to its driver) at once.
void release_session_control(ServerCore& core, const SessionInfo& info);

// The robot a lease, drive or e-stop request names (`<message>.robot_id`); nullptr after sending
// ERROR_INVALID_ARGUMENT or ERROR_UNKNOWN_ROBOT naming the field.
std::shared_ptr<Robot> find_named_robot(const SessionPtr& session, const std::string& robot_id,
                                        const std::string& message, std::uint64_t request_id);

}  // namespace occgeo::service
