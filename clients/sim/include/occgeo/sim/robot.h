#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "occgeo/geometry/kinematics.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/geometry/track_dynamics.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/sim_world.h"
#include "occgeo/sim/world.h"

namespace occgeo::sim {

// Length of one physics step, seconds of sim time.
inline constexpr double kPhysicsStep_s = 0.01;

// A motion command as the simulated robot takes it. For a skid-steered robot the speeds are track rim speeds r*omega
// (what MotionCommand carries for such a robot); for a differential drive, wheel ground speeds.
struct WheelCommand {
  double left_mps = 0.0;         // left wheel (track rim) speed, m/s
  double right_mps = 0.0;        // right wheel (track rim) speed, m/s
  bool stop = false;             // stand still until the next command
  double expires_after_s = 0.0;  // stop once this long after the command, seconds; 0 leaves only the watchdog
};

// Cumulative encoder counts, positive forwards.
struct EncoderTicks {
  std::int64_t left = 0;
  std::int64_t right = 0;
};

// The simulated robot: exact kinematics in fixed physics steps (differential drive, or skid steer with slippage and a
// first-order powertrain lag), a watchdog that stops the wheels when commands stop coming, ground-truth collisions
// with the world that block motion, and each wheel's true travel for its encoders.
class SimulatedRobot {
 public:
  // Places the robot at base_link pose X_WB at sim time 0. Throws std::invalid_argument naming the pixel when the
  // footprint collides with the world there. The world must outlive the robot.
  SimulatedRobot(const SimWorld& world, const RobotPreset& preset, const geometry::Pose2& X_WB);
  // The same for a pixel world, which the robot copies.
  SimulatedRobot(const World& world, const RobotPreset& preset, const geometry::Pose2& X_WB);

  // Drives the wheels at the command's speeds from now until the watchdog period, or the command's own expiry if
  // sooner, has passed; both speeds are scaled down together when one exceeds the preset's maximum (keeping the
  // path's curvature). A stop command, or one with non-finite speeds, stops the wheels now (a tracked robot's tracks
  // run down through the powertrain lag). Cancels a drive_goto in progress.
  void command(const WheelCommand& command);

  // The ActivityBot's drive_goto (seed 003 §3.3.3, §3.4): each wheel turns by its own number of encoder ticks from its
  // current count, at the preset's drive_goto speed, and stops when it gets there (the last step is shortened so it
  // stops exactly on the tick). Ignores the watchdog; a later command() cancels it. Throws std::logic_error when the
  // preset has no encoders or no drive_goto speed.
  // speed_mps > 0 is drive_setMaxSpeed's cruising speed for this manoeuvre (at most the preset's).
  void drive_goto(std::int64_t left_ticks, std::int64_t right_ticks, double speed_mps = 0.0);
  // True while a drive_goto has not reached both targets.
  [[nodiscard]] bool drive_goto_active() const { return goto_target_.has_value(); }

  // Advances sim time by one physics step. The robot moves only when the footprint at the new pose is clear at the new
  // time; otherwise it stays put (the wheels stall: no encoder travel), and the first blocked step after moving freely
  // counts as one collision. In a world with moving obstacles a standing robot is tested too, so an obstacle running
  // into it counts as a collision.
  void step();

  // Physics steps taken since the start.
  [[nodiscard]] std::int64_t step_count() const { return step_count_; }
  // Sim time since the start, seconds.
  [[nodiscard]] double time_s() const { return static_cast<double>(step_count_) * kPhysicsStep_s; }
  // True base_link pose in the world.
  [[nodiscard]] const geometry::Pose2& pose() const { return X_WB_; }
  // Body velocity actually achieved during the last step: zero while stopped or blocked.
  [[nodiscard]] const geometry::BodyVelocity& velocity() const { return velocity_; }
  // Wheel (track rim) speeds commanded for the next step, m/s (zero once the command lapsed), before any lag.
  [[nodiscard]] geometry::WheelSpeeds wheel_speeds() const;
  // Wheel (track rim) speeds reached at the end of the last step, m/s: the commanded ones after the powertrain lag.
  [[nodiscard]] const geometry::WheelSpeeds& rim_speeds() const { return rim_speeds_; }
  // Sum of the position changes of all steps, metres.
  [[nodiscard]] double distance_m() const { return distance_m_; }
  // Number of times the robot ran into an obstacle (transitions into contact, not blocked steps).
  [[nodiscard]] std::uint64_t collisions() const {
    return collisions_moving_ + collisions_hit_moving_ + collisions_at_rest_;
  }
  // Contacts begun while the wheels turned (the robot ran into something) ...
  [[nodiscard]] std::uint64_t collisions_moving() const { return collisions_moving_; }
  // ... and while it stood still (a moving obstacle ran into it).
  [[nodiscard]] std::uint64_t collisions_at_rest() const { return collisions_at_rest_; }
  // ... and while the wheels turned, but with a moving obstacle already inside the footprint where the robot stood:
  // it ran into the robot (a robot backing or creeping away from someone walking faster).
  [[nodiscard]] std::uint64_t collisions_hit_moving() const { return collisions_hit_moving_; }
  // One contact as it began: when, where, what the wheels were doing and what was hit.
  struct CollisionEvent {
    double time_s = 0.0;
    geometry::Pose2 X_WB;          // base_link when the contact began
    geometry::WheelSpeeds wheels;  // rim speeds of the blocked step (zeros for a robot at rest)
    bool moving = false;           // the wheels turned (else the robot stood)
    bool ran_into_robot = false;   // a moving obstacle was already inside the footprint where the robot stood
    std::string obstacle;          // the world's description of what was hit
  };
  // The first kMaxCollisionEvents contacts, in order.
  static constexpr std::size_t kMaxCollisionEvents = 32;
  [[nodiscard]] const std::vector<CollisionEvent>& collision_events() const { return collision_events_; }
  // Each wheel's (track's rim) true signed travel since the start, metres, positive forwards.
  [[nodiscard]] double left_travel_m() const { return left_travel_m_; }
  [[nodiscard]] double right_travel_m() const { return right_travel_m_; }
  // Whole encoder ticks of the true travel, rounded toward zero; zeros when the preset has no encoders.
  [[nodiscard]] EncoderTicks encoder_ticks() const;

 private:
  SimulatedRobot(std::shared_ptr<const SimWorld> owned_world, const RobotPreset& preset, const geometry::Pose2& X_WB);
  SimulatedRobot(std::shared_ptr<const SimWorld> owned_world, const SimWorld& world, const RobotPreset& preset,
                 const geometry::Pose2& X_WB);

  // The wheel speeds this step drives at (drive_goto or the commanded ones, through the lag for a tracked robot).
  geometry::WheelSpeeds next_rim_speeds();
  geometry::BodyVelocity body_velocity(const geometry::WheelSpeeds& rim) const;
  geometry::WheelSpeeds clamp(const geometry::WheelSpeeds& wheels) const;

  std::shared_ptr<const SimWorld> owned_world_;  // set only when the robot copied a pixel world
  const SimWorld* world_;
  KinematicsPreset kinematics_;
  std::optional<geometry::TrackDynamics> tracks_;  // set for a skid-steered robot
  std::optional<geometry::EncoderParams> encoders_;
  double drive_goto_speed_mps_;
  double goto_speed_mps_ = 0.0;  // the running drive_goto's speed
  geometry::BoxFootprint footprint_;
  std::int64_t watchdog_steps_;
  geometry::Pose2 X_WB_;
  std::int64_t step_count_ = 0;
  geometry::WheelSpeeds commanded_{};
  std::int64_t drive_until_step_ = 0;        // the wheels drive during steps that start before this one
  std::optional<EncoderTicks> goto_target_;  // drive_goto's tick targets while one runs
  geometry::WheelSpeeds rim_speeds_{};
  geometry::BodyVelocity velocity_{};
  double distance_m_ = 0.0;
  double left_travel_m_ = 0.0;
  double right_travel_m_ = 0.0;
  std::uint64_t collisions_moving_ = 0;
  std::uint64_t collisions_at_rest_ = 0;
  std::uint64_t collisions_hit_moving_ = 0;
  bool in_contact_ = false;
  std::vector<CollisionEvent> collision_events_;
};

}  // namespace occgeo::sim
