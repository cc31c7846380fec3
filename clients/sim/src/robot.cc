#include "occgeo/sim/robot.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "occgeo/geometry/dead_reckoning.h"

namespace occgeo::sim {

namespace {

// The number of whole physics steps closest to duration_s.
std::int64_t steps_in(double duration_s) { return std::llround(duration_s / kPhysicsStep_s); }

// Below this a lagging track speed counts as stopped, m/s; without it the exponential decay would never reach zero
// and a stopped tracked robot would never count as standing.
constexpr double kStoppedSpeed_mps = 1e-9;

// Travel within this of a drive_goto target has reached it, metres (floating-point rounding of the step sums).
constexpr double kGotoTolerance_m = 1e-9;

// Whole ticks of travel_m rounded toward zero, forgiving a billionth of a tick of floating-point rounding so that a
// travel of exactly n ticks reads n.
std::int64_t whole_ticks(double travel_m, double metres_per_tick) {
  const double ticks = travel_m / metres_per_tick;
  constexpr double kRounding = 1e-9;
  return static_cast<std::int64_t>(ticks >= 0.0 ? std::floor(ticks + kRounding) : std::ceil(ticks - kRounding));
}

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
      kinematics_(preset.kinematics),
      encoders_(preset.encoders),
      drive_goto_speed_mps_(preset.drive_goto_speed_mps),
      footprint_(preset.footprint),
      watchdog_steps_(steps_in(preset.command_timeout_s)),
      X_WB_(X_WB) {
  if (const auto* skid = std::get_if<SkidSteerPreset>(&kinematics_)) {
    tracks_.emplace(skid->powertrain_time_constant_s);
  }
  if (const auto obstacle = world.find_collision(footprint_, X_WB, 0.0)) {
    std::ostringstream message;
    message << "the footprint at (" << X_WB.x << ", " << X_WB.y << ", " << X_WB.theta << ") collides with "
            << *obstacle;
    throw std::invalid_argument(message.str());
  }
}

geometry::WheelSpeeds SimulatedRobot::clamp(const geometry::WheelSpeeds& wheels) const {
  if (const auto* skid = std::get_if<SkidSteerPreset>(&kinematics_)) {
    return geometry::clamp_to_max_speed(wheels, skid->params);
  }
  return geometry::clamp_to_max_speed(wheels, std::get<geometry::DifferentialDriveParams>(kinematics_));
}

geometry::BodyVelocity SimulatedRobot::body_velocity(const geometry::WheelSpeeds& rim) const {
  if (const auto* skid = std::get_if<SkidSteerPreset>(&kinematics_)) return geometry::to_body(rim, skid->params);
  return geometry::to_body(rim, std::get<geometry::DifferentialDriveParams>(kinematics_));
}

void SimulatedRobot::command(const WheelCommand& command) {
  goto_target_.reset();
  if (command.stop || !std::isfinite(command.left_mps) || !std::isfinite(command.right_mps)) {
    drive_until_step_ = step_count_;
    return;
  }
  commanded_ = clamp({command.left_mps, command.right_mps});
  std::int64_t drive_steps = watchdog_steps_;
  if (command.expires_after_s > 0.0 &&
      command.expires_after_s < static_cast<double>(watchdog_steps_) * kPhysicsStep_s) {
    drive_steps = steps_in(command.expires_after_s);
  }
  drive_until_step_ = step_count_ + drive_steps;
}

void SimulatedRobot::drive_goto(std::int64_t left_ticks, std::int64_t right_ticks, double speed_mps) {
  if (!encoders_ || !(drive_goto_speed_mps_ > 0.0)) {
    throw std::logic_error("drive_goto: the robot has no wheel encoders or no drive_goto speed");
  }
  const EncoderTicks now = encoder_ticks();
  goto_speed_mps_ = speed_mps > 0.0 ? std::min(speed_mps, drive_goto_speed_mps_) : drive_goto_speed_mps_;
  drive_until_step_ = step_count_;
  goto_target_ = EncoderTicks{.left = now.left + left_ticks, .right = now.right + right_ticks};
}

geometry::WheelSpeeds SimulatedRobot::wheel_speeds() const {
  return step_count_ < drive_until_step_ ? commanded_ : geometry::WheelSpeeds{};
}

EncoderTicks SimulatedRobot::encoder_ticks() const {
  if (!encoders_) return {};
  const double metres_per_tick = geometry::metres_per_tick(*encoders_);
  return {whole_ticks(left_travel_m_, metres_per_tick), whole_ticks(right_travel_m_, metres_per_tick)};
}

geometry::WheelSpeeds SimulatedRobot::next_rim_speeds() {
  if (goto_target_) {
    const double metres_per_tick = geometry::metres_per_tick(*encoders_);
    // Full speed towards the target, the last step shortened so the wheel stops on it.
    const auto speed_towards = [&](std::int64_t target_ticks, double travel_m) {
      const double remaining_m = static_cast<double>(target_ticks) * metres_per_tick - travel_m;
      if (std::abs(remaining_m) <= kGotoTolerance_m) return 0.0;
      return std::copysign(std::min(goto_speed_mps_, std::abs(remaining_m) / kPhysicsStep_s), remaining_m);
    };
    return {speed_towards(goto_target_->left, left_travel_m_), speed_towards(goto_target_->right, right_travel_m_)};
  }
  const geometry::WheelSpeeds commanded = wheel_speeds();
  if (!tracks_) return commanded;
  geometry::WheelSpeeds rim = tracks_->step(commanded, kPhysicsStep_s);
  if (commanded.left_mps == 0.0 && commanded.right_mps == 0.0 && std::abs(rim.left_mps) < kStoppedSpeed_mps &&
      std::abs(rim.right_mps) < kStoppedSpeed_mps) {
    tracks_->stop();
    rim = {};
  }
  return rim;
}

void SimulatedRobot::step() {
  const geometry::WheelSpeeds wheels = next_rim_speeds();
  rim_speeds_ = wheels;
  ++step_count_;
  velocity_ = {};
  if (wheels.left_mps == 0.0 && wheels.right_mps == 0.0) {
    if (goto_target_) {
      // Both wheels are on their targets: land exactly on them so the tick counts are exact.
      const double metres_per_tick = geometry::metres_per_tick(*encoders_);
      left_travel_m_ = static_cast<double>(goto_target_->left) * metres_per_tick;
      right_travel_m_ = static_cast<double>(goto_target_->right) * metres_per_tick;
      goto_target_.reset();
    }
    // Standing still: only a moving obstacle can run into the robot.
    if (world_->has_moving_obstacles()) {
      const std::optional<std::string> hit = world_->find_collision(footprint_, X_WB_, time_s());
      if (hit && !in_contact_) {
        ++collisions_at_rest_;
        if (collision_events_.size() < kMaxCollisionEvents) {
          collision_events_.push_back({time_s(), X_WB_, wheels, false, true, *hit});
        }
      }
      in_contact_ = hit.has_value();
    }
    return;
  }
  const geometry::BodyVelocity body = body_velocity(wheels);
  const geometry::Pose2 X_WB_next = geometry::integrate(X_WB_, body, kPhysicsStep_s);
  if (const std::optional<std::string> hit = world_->find_collision(footprint_, X_WB_next, time_s())) {
    if (!in_contact_) {
      // Where the robot stands, at the new time: an obstacle there came to the robot, not the robot to it.
      const bool ran_into_robot =
          world_->has_moving_obstacles() && world_->find_collision(footprint_, X_WB_, time_s()).has_value();
      ++(ran_into_robot ? collisions_hit_moving_ : collisions_moving_);
      if (collision_events_.size() < kMaxCollisionEvents) {
        collision_events_.push_back({time_s(), X_WB_, wheels, true, ran_into_robot, *hit});
      }
    }
    in_contact_ = true;
    return;
  }
  distance_m_ += (X_WB_next.position() - X_WB_.position()).norm();
  left_travel_m_ += wheels.left_mps * kPhysicsStep_s;
  right_travel_m_ += wheels.right_mps * kPhysicsStep_s;
  X_WB_ = X_WB_next;
  velocity_ = body;
  in_contact_ = false;
}

}  // namespace occgeo::sim
