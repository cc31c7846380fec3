#include "occgeo/service/control/pointbug.h"
#include "occgeo/geometry/pose.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <numbers>
#include <string>

#include "param_checks.h"

namespace occgeo::service::control {
namespace {

using detail::require;
using detail::require_positive;

constexpr double kRadiansPerDegree = std::numbers::pi / 180.0;

// step_to_goal re-aims only when the heading is off by this many heading tolerances, so odometry noise around the
// tolerance does not alternate aiming and stepping every cycle (assumption; the seed drives blind between turns).
constexpr double kReaimFactor = 4.0;

// Each state change happens within one decide(); the longest chain is drive_to_sudden_point -> aim_at_goal ->
// step_to_goal -> turn_to_sudden_point -> drive_to_sudden_point.
constexpr int kMaxTransitionsPerDecision = 8;

using geometry::wrap_angle;

void check_sweep(const Sweep& sweep) {
  require_positive("Sweep.range_max_m", sweep.range_max_m);
  for (const SweepReading& reading : sweep.readings) {
    require(std::isfinite(reading.angle_rad), "Sweep.readings.angle_rad", "must be finite", reading.angle_rad);
    require(!std::isnan(reading.range_m) && reading.range_m >= 0.0, "Sweep.readings.range_m",
            "must hold non-negative ranges", reading.range_m);
  }
}

// The range at a servo angle in degrees (signed, left positive), clamped to range_max_m, from the reading nearest
// that angle within half a step; none when the sweep did not measure it.
std::optional<double> range_at(const Sweep& sweep, double angle_deg, const PointBugParams& params) {
  const double angle_rad = angle_deg * kRadiansPerDegree;
  const double half_step_rad = 0.5 * params.sweep_step_deg * kRadiansPerDegree;
  std::optional<double> best_range;
  double best_offset = half_step_rad;
  for (const SweepReading& reading : sweep.readings) {
    const double offset = std::abs(wrap_angle(reading.angle_rad - angle_rad));
    if (offset <= best_offset) {
      best_offset = offset;
      best_range = std::min(reading.range_m, sweep.range_max_m);
    }
  }
  return best_range;
}

}  // namespace

void PointBugParams::validate() const {
  require_positive("obstacle_range_m", obstacle_range_m);
  require_positive("sudden_jump_m", sudden_jump_m);
  require(std::isfinite(sweep_step_deg) && sweep_step_deg > 0.0 && sweep_step_deg <= 10.0, "sweep_step_deg",
          "must be in (0, 10] degrees", sweep_step_deg);
  require(sweep_limit_deg >= 2 && sweep_limit_deg <= 180, "sweep_limit_deg", "must be in [2, 180] degrees",
          sweep_limit_deg);
  require(gap_deg >= 1 && gap_deg <= 180, "gap_deg", "must be in [1, 180] degrees", gap_deg);
  require(std::isfinite(angle_extension_deg) && angle_extension_deg >= 0.0 && angle_extension_deg <= 90.0,
          "angle_extension_deg", "must be in [0, 90] degrees", angle_extension_deg);
  require(std::isfinite(distance_extension_m) && distance_extension_m >= 0.0, "distance_extension_m",
          "must be non-negative and finite", distance_extension_m);
  require_positive("step_m", step_m);
  require_positive("goal_tolerance_m", goal_tolerance_m);
  require(std::isfinite(heading_tolerance_rad) && heading_tolerance_rad > 0.0 &&
              heading_tolerance_rad < std::numbers::pi / 4.0,
          "heading_tolerance_rad", "must be in (0, pi/4) radians", heading_tolerance_rad);
  require_positive("linear_speed_mps", linear_speed_mps);
  require_positive("turn_speed_radps", turn_speed_radps);
}

std::optional<SuddenPoint> find_sudden_point(const Sweep& sweep, SweepSide side, const PointBugParams& params) {
  check_sweep(sweep);
  // The listing counts degrees outwards on both sides (angr = (900 - j) / 10, angl = (k - 900) / 10); the sign turns
  // them into servo angles, the right side being clockwise.
  const double sign = side == SweepSide::kRight ? -1.0 : 1.0;
  const auto read = [&](int degrees_out) {
    return range_at(sweep, sign * degrees_out * params.sweep_step_deg, params).value_or(0.0);
  };
  // Gap readings past the sweep limit repeat the limit's reading: the listing's gap loop has no limit check and
  // keeps commanding the servo past its end stop, where it stays.
  const auto read_gap = [&](int degrees_out) { return read(std::min(degrees_out, params.sweep_limit_deg)); };

  double a = read(0);  // the listing's a = a0 = dis: the forward reading that stopped the robot
  int next = 0;        // the next angle to read, in steps outwards
  while (true) {
    // L3/L5: look for a jump. The limit check follows the read, as in the listing, so a jump at the last step
    // (89 degrees) is never used.
    double a0 = a;
    int angle = 0;
    do {
      a0 = a;
      a = read(next);
      angle = next;
      ++next;
      if (next >= params.sweep_limit_deg) return std::nullopt;
    } while (a - a0 <= params.sudden_jump_m);
    const int edge = angle - 1;  // angr = angr - 1: the last reading still on the obstacle
    // The gap loop: readings stay at least sudden_jump_m beyond the edge's range (a0 is not updated) until one is
    // more than gap_deg past the edge; that reading itself is not checked, as in the listing. A closer reading
    // inside the gap ends the loop and the jump search resumes after it (goto L3 / L5).
    while (a - a0 >= params.sudden_jump_m) {
      a = read_gap(next);
      const int gap_angle = next;
      ++next;
      if (gap_angle - edge > params.gap_deg) {
        SuddenPoint point;
        point.side = side;
        point.edge_angle_deg = edge;
        point.edge_range_m = a0;
        point.turn_deg = edge * params.sweep_step_deg + params.angle_extension_deg;
        point.distance_m = a0 + params.distance_extension_m;
        point.turn_rad = sign * point.turn_deg * kRadiansPerDegree;
        return point;
      }
    }
  }
}

PointBugBehaviour::PointBugBehaviour(const PointBugParams& params, double goal_x_m, double goal_y_m)
    : params_(params), goal_x_m_(goal_x_m), goal_y_m_(goal_y_m) {
  params_.validate();
  require(std::isfinite(goal_x_m), "goal_x_m", "must be finite", goal_x_m);
  require(std::isfinite(goal_y_m), "goal_y_m", "must be finite", goal_y_m);
}

PointBugDecision PointBugBehaviour::decide(const Pose2& pose, const Sweep& sweep) {
  require(std::isfinite(pose.x), "Pose2.x", "must be finite", pose.x);
  require(std::isfinite(pose.y), "Pose2.y", "must be finite", pose.y);
  require(std::isfinite(pose.theta), "Pose2.theta", "must be finite", pose.theta);
  check_sweep(sweep);

  PointBugDecision decision;
  const double goal_dx = goal_x_m_ - pose.x;
  const double goal_dy = goal_y_m_ - pose.y;
  decision.goal_distance_m = std::hypot(goal_dx, goal_dy);
  const double goal_error_rad = wrap_angle(std::atan2(goal_dy, goal_dx) - pose.theta);
  const auto turn_by = [&](double error_rad) {
    decision.angular_radps = std::copysign(params_.turn_speed_radps, error_rad);
  };

  for (int transition = 0; transition < kMaxTransitionsPerDecision; ++transition) {
    switch (state_) {
      case State::kAimAtGoal:
        if (decision.goal_distance_m <= params_.goal_tolerance_m) {
          state_ = State::kReached;
          continue;
        }
        if (std::abs(goal_error_rad) <= params_.heading_tolerance_rad) {
          state_ = State::kStepToGoal;
          continue;
        }
        decision.state = BehaviourState::kAimAtGoal;
        turn_by(goal_error_rad);
        decision.target = MotionTarget{goal_error_rad, 0.0};
        return decision;

      case State::kStepToGoal: {
        if (decision.goal_distance_m <= params_.goal_tolerance_m) {
          state_ = State::kReached;
          continue;
        }
        if (std::abs(goal_error_rad) > kReaimFactor * params_.heading_tolerance_rad) {
          state_ = State::kAimAtGoal;
          continue;
        }
        const std::optional<double> forward_m = range_at(sweep, 0.0, params_);
        require(forward_m.has_value(), "Sweep.readings", "must hold the reading at 0 degrees while stepping",
                static_cast<double>(sweep.readings.size()));
        if (*forward_m <= params_.obstacle_range_m) {
          decision.right = find_sudden_point(sweep, SweepSide::kRight, params_);
          decision.left = find_sudden_point(sweep, SweepSide::kLeft, params_);
          // The listing's choice: right when angr < angl, else left (ties go left); a side without a sudden point
          // has angle 100 + 15, so any found side wins. With neither, the listing would still turn left by 115
          // degrees; here that is the no_path the text describes.
          if (!decision.right && !decision.left) {
            state_ = State::kNoPath;
            continue;
          }
          const bool go_right =
              decision.right && (!decision.left || decision.right->turn_deg < decision.left->turn_deg);
          SuddenPoint chosen = go_right ? *decision.right : *decision.left;
          target_yaw_rad_ = wrap_angle(pose.theta + chosen.turn_rad);
          chosen.world_x_m = pose.x + chosen.distance_m * std::cos(target_yaw_rad_);
          chosen.world_y_m = pose.y + chosen.distance_m * std::sin(target_yaw_rad_);
          target_ = chosen;
          state_ = State::kTurnToSuddenPoint;
          continue;
        }
        decision.state = BehaviourState::kStepToGoal;
        decision.linear_mps = params_.linear_speed_mps;
        decision.target = MotionTarget{goal_error_rad, std::min(params_.step_m, decision.goal_distance_m)};
        return decision;
      }

      case State::kTurnToSuddenPoint: {
        const double error_rad = wrap_angle(target_yaw_rad_ - pose.theta);
        if (std::abs(error_rad) <= params_.heading_tolerance_rad) {
          state_ = State::kDriveToSuddenPoint;
          continue;
        }
        const double remaining_m = (target_->world_x_m - pose.x) * std::cos(target_yaw_rad_) +
                                   (target_->world_y_m - pose.y) * std::sin(target_yaw_rad_);
        decision.state = BehaviourState::kTurnToSuddenPoint;
        turn_by(error_rad);
        decision.target = MotionTarget{error_rad, std::max(remaining_m, 0.0)};
        decision.sudden_point = target_;
        return decision;
      }

      case State::kDriveToSuddenPoint: {
        // Progress is measured along the heading to the point, so sideways odometry drift does not stall it.
        const double remaining_m = (target_->world_x_m - pose.x) * std::cos(target_yaw_rad_) +
                                   (target_->world_y_m - pose.y) * std::sin(target_yaw_rad_);
        if (remaining_m <= params_.goal_tolerance_m) {
          // The listing re-aims at the goal on arrival (angturned) and then steps again.
          target_.reset();
          state_ = State::kAimAtGoal;
          continue;
        }
        decision.state = BehaviourState::kDriveToSuddenPoint;
        decision.linear_mps = params_.linear_speed_mps;
        decision.target = MotionTarget{0.0, remaining_m};
        decision.sudden_point = target_;
        return decision;
      }

      case State::kReached:
        decision.state = BehaviourState::kReached;
        decision.stop = true;
        return decision;

      case State::kNoPath:
        decision.state = BehaviourState::kNoPath;
        decision.stop = true;
        return decision;
    }
  }
  std::abort();  // every chain of transitions above ends in a return well within kMaxTransitionsPerDecision
}

}  // namespace occgeo::service::control
