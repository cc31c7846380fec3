#pragma once

#include <cstdint>
#include <memory>

#include "occgeo/geometry/kinematics.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/sim_world.h"
#include "occgeo/sim/world.h"

namespace occgeo::sim {

// Length of one physics step, seconds of sim time.
inline constexpr double kPhysicsStep_s = 0.01;

// A motion command as the simulated robot takes it.
struct WheelCommand {
  double left_mps = 0.0;         // left wheel ground speed, m/s
  double right_mps = 0.0;        // right wheel ground speed, m/s
  bool stop = false;             // stand still until the next command
  double expires_after_s = 0.0;  // stop once this long after the command, seconds; 0 leaves only the watchdog
};

// The simulated differential-drive robot: exact kinematics in fixed physics steps, a watchdog that stops the wheels
// when commands stop coming, and ground-truth collisions with the world that block motion.
class SimulatedRobot {
 public:
  // Places the robot at base_link pose X_WB at sim time 0. Throws std::invalid_argument naming the pixel when the
  // footprint collides with the world there. The world must outlive the robot.
  SimulatedRobot(const SimWorld& world, const RobotPreset& preset, const geometry::Pose2& X_WB);
  // The same for a pixel world, which the robot copies.
  SimulatedRobot(const World& world, const RobotPreset& preset, const geometry::Pose2& X_WB);

  // Drives the wheels at the command's speeds from now until the watchdog period, or the command's own expiry if
  // sooner, has passed; both speeds are scaled down together when one exceeds the preset's maximum (keeping the
  // path's curvature). A stop command, or one with non-finite speeds, stops the wheels now.
  void command(const WheelCommand& command);

  // Advances sim time by one physics step. The robot moves only when the footprint at the new pose is clear at the new
  // time; otherwise it stays put, and the first blocked step after moving freely counts as one collision. In a world
  // with moving obstacles a standing robot is tested too, so an obstacle running into it counts as a collision.
  void step();

  // Physics steps taken since the start.
  [[nodiscard]] std::int64_t step_count() const { return step_count_; }
  // Sim time since the start, seconds.
  [[nodiscard]] double time_s() const { return static_cast<double>(step_count_) * kPhysicsStep_s; }
  // True base_link pose in the world.
  [[nodiscard]] const geometry::Pose2& pose() const { return X_WB_; }
  // Body velocity actually achieved during the last step: zero while stopped or blocked.
  [[nodiscard]] const geometry::BodyVelocity& velocity() const { return velocity_; }
  // Wheel speeds the next step will drive at, m/s (zero once the command lapsed).
  [[nodiscard]] geometry::WheelSpeeds wheel_speeds() const;
  // Sum of the position changes of all steps, metres.
  [[nodiscard]] double distance_m() const { return distance_m_; }
  // Number of times the robot ran into an obstacle (transitions into contact, not blocked steps).
  [[nodiscard]] std::uint64_t collisions() const { return collisions_; }

 private:
  SimulatedRobot(std::shared_ptr<const SimWorld> owned_world, const RobotPreset& preset, const geometry::Pose2& X_WB);
  SimulatedRobot(std::shared_ptr<const SimWorld> owned_world, const SimWorld& world, const RobotPreset& preset,
                 const geometry::Pose2& X_WB);

  std::shared_ptr<const SimWorld> owned_world_;  // set only when the robot copied a pixel world
  const SimWorld* world_;
  geometry::DifferentialDriveParams drive_;
  geometry::BoxFootprint footprint_;
  std::int64_t watchdog_steps_;
  geometry::Pose2 X_WB_;
  std::int64_t step_count_ = 0;
  geometry::WheelSpeeds commanded_{};
  std::int64_t drive_until_step_ = 0;  // the wheels drive during steps that start before this one
  geometry::BodyVelocity velocity_{};
  double distance_m_ = 0.0;
  std::uint64_t collisions_ = 0;
  bool in_contact_ = false;
};

}  // namespace occgeo::sim
