#include "occgeo/sim/robot.h"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace occgeo::sim {

namespace {

// The number of whole physics steps closest to duration_s.
std::int64_t steps_in(double duration_s) { return std::llround(duration_s / kPhysicsStep_s); }

}  // namespace

SimulatedRobot::SimulatedRobot(const World& world, const RobotPreset& preset, const geometry::Pose2& X_WB)
    : SimulatedRobot(std::make_shared<const PixelWorld>(world), preset, X_WB) {}

SimulatedRobot::SimulatedRobot(std::shared_ptr<const SimWorld> owned_world, const RobotPreset& preset,
                               const geometry::Pose2& X_WB)
    : SimulatedRobot(owned_world, *owned_world, preset, X_WB) {}

SimulatedRobot::SimulatedRobot(const SimWorld& world, const RobotPreset& preset, const geometry::Pose2& X_WB)
    : SimulatedRobot(nullptr, world, preset, X_WB) {}

SimulatedRobot::SimulatedRobot(std::shared_ptr<const SimWorld> owned_world, const SimWorld& world,
                               const RobotPreset& preset, const geometry::Pose2& X_WB)
    : owned_world_(std::move(owned_world)),
      world_(&world),
      drive_(preset.drive),
      footprint_(preset.footprint),
      watchdog_steps_(steps_in(preset.command_timeout_s)),
      X_WB_(X_WB) {
  if (const auto obstacle = world.find_collision(footprint_, X_WB, 0.0)) {
    std::ostringstream message;
    message << "the footprint at (" << X_WB.x << ", " << X_WB.y << ", " << X_WB.theta << ") collides with "
            << *obstacle;
    throw std::invalid_argument(message.str());
  }
}

void SimulatedRobot::command(const WheelCommand& command) {
  if (command.stop || !std::isfinite(command.left_mps) || !std::isfinite(command.right_mps)) {
    drive_until_step_ = step_count_;
    return;
  }
  commanded_ = geometry::clamp_to_max_speed({command.left_mps, command.right_mps}, drive_);
  std::int64_t drive_steps = watchdog_steps_;
  if (command.expires_after_s > 0.0 &&
      command.expires_after_s < static_cast<double>(watchdog_steps_) * kPhysicsStep_s) {
    drive_steps = steps_in(command.expires_after_s);
  }
  drive_until_step_ = step_count_ + drive_steps;
}

geometry::WheelSpeeds SimulatedRobot::wheel_speeds() const {
  return step_count_ < drive_until_step_ ? commanded_ : geometry::WheelSpeeds{};
}

void SimulatedRobot::step() {
  const geometry::WheelSpeeds wheels = wheel_speeds();
  ++step_count_;
  velocity_ = {};
  if (wheels.left_mps == 0.0 && wheels.right_mps == 0.0) {
    // Standing still: only a moving obstacle can run into the robot.
    if (world_->has_moving_obstacles()) {
      const bool contact = world_->find_collision(footprint_, X_WB_, time_s()).has_value();
      if (contact && !in_contact_) ++collisions_;
      in_contact_ = contact;
    }
    return;
  }
  const geometry::BodyVelocity body = geometry::to_body(wheels, drive_);
  const geometry::Pose2 X_WB_next = geometry::integrate(X_WB_, body, kPhysicsStep_s);
  if (world_->find_collision(footprint_, X_WB_next, time_s())) {
    if (!in_contact_) ++collisions_;
    in_contact_ = true;
    return;
  }
  distance_m_ += (X_WB_next.position() - X_WB_.position()).norm();
  X_WB_ = X_WB_next;
  velocity_ = body;
  in_contact_ = false;
}

}  // namespace occgeo::sim
