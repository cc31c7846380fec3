#include "occgeo/service/control/behaviour.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include "height_band_layer.h"
#include "occgeo/geometry/cell.h"
#include "occgeo/geometry/convex_polygon.h"
#include "occgeo/service/control/global_path.h"
#include "occgeo/service/control/loop_detector.h"
#include "occgeo/service/control/ptem_guidance.h"

namespace occgeo::service::control {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// What an escape reports as its plan: from the robot at position_W along what is left of path_W after `segment`.
std::vector<Eigen::Vector2d> remaining_path(const Eigen::Vector2d& position_W,
                                            const std::vector<Eigen::Vector2d>& path_W, std::size_t segment) {
  std::vector<Eigen::Vector2d> path{position_W};
  path.insert(path.end(), path_W.begin() + static_cast<std::ptrdiff_t>(std::min(segment + 1, path_W.size())),
              path_W.end());
  return path;
}

double footprint_width(const geometry::Footprint& footprint) {
  if (const auto* box = std::get_if<geometry::BoxFootprint>(&footprint)) return box->width;
  if (const auto* polygon = std::get_if<geometry::ConvexPolygonFootprint>(&footprint)) {
    return geometry::extent_along(polygon->vertices_B, Eigen::Vector2d::UnitY());
  }
  return 2.0 * std::get<geometry::CylinderFootprint>(footprint).radius;
}

// The largest disc about base_link inside the footprint.
double inscribed_radius(const geometry::Footprint& footprint) {
  if (const auto* box = std::get_if<geometry::BoxFootprint>(&footprint)) {
    return std::max(0.0, std::min(box->width / 2.0, box->length / 2.0 - std::abs(box->center_x)));
  }
  if (const auto* polygon = std::get_if<geometry::ConvexPolygonFootprint>(&footprint)) {
    return geometry::origin_inscribed_radius(polygon->vertices_B);
  }
  return std::get<geometry::CylinderFootprint>(footprint).radius;
}

double footprint_front(const geometry::Footprint& footprint) {
  if (const auto* box = std::get_if<geometry::BoxFootprint>(&footprint)) return box->center_x + box->length / 2.0;
  if (const auto* polygon = std::get_if<geometry::ConvexPolygonFootprint>(&footprint)) {
    return geometry::farthest_along(polygon->vertices_B, Eigen::Vector2d::UnitX());
  }
  return std::get<geometry::CylinderFootprint>(footprint).radius;
}

class BearcatAdapter final : public Behaviour {
 public:
  explicit BearcatAdapter(const BearcatParams& params) : behaviour_(params) {}
  [[nodiscard]] std::string_view name() const override { return "bearcat"; }
  BehaviourCommand decide(const BehaviourInput& input) override {
    const BearcatDecision decision = behaviour_.decide(input.scan);
    BehaviourCommand command;
    command.linear_mps = decision.linear_mps;
    command.angular_radps = decision.angular_radps;
    command.wheels = geometry::WheelSpeeds{decision.left_wheel_mps, decision.right_wheel_mps};
    command.stop = decision.stop;
    command.state = decision.state;
    return command;
  }

 private:
  BearcatBehaviour behaviour_;
};

// Beyond seed 001, for a sonar ring: a specular sonar hears a wall only along the wall's normal, so its reading d at
// bearing b is the wall's perpendicular distance, and the wall crosses the heading (d - r) / cos b beyond the body's
// radius r (less a side margin). Each element within +-90 degrees becomes a straight-ahead reading of that distance, so
// a wall met at a glancing angle (heard only by a side element) blocks the front as soon as the robot would reach it
// within the threshold; elements behind are left out. A wall beside the robot keeps at least this clear of the body's
// circle, so the robot can still turn on the spot.
constexpr double kRingSideMargin_m = 0.15;

RangeSet ring_as_ahead(const RangeSet& ring, double body_radius_m) {
  RangeSet ahead;
  ahead.range_max_m = ring.range_max_m;
  for (const BeamReading& beam : ring.beams) {
    const double bearing = geometry::wrap_angle(beam.bearing_rad);
    const double along = std::cos(bearing);
    if (along <= 1e-3) continue;
    if (!(beam.range_m < ring.range_max_m)) {
      ahead.beams.push_back({0.0, beam.range_m});
      continue;
    }
    const double clearance_m = std::max(0.0, beam.range_m - body_radius_m - kRingSideMargin_m);
    ahead.beams.push_back({0.0, std::min(body_radius_m + clearance_m / along, ring.range_max_m)});
  }
  return ahead;
}

class WanderAdapter final : public Behaviour {
 public:
  WanderAdapter(const WanderParams& params, double body_radius_m) : behaviour_(params), body_radius_m_(body_radius_m) {}
  [[nodiscard]] std::string_view name() const override { return "wander"; }
  BehaviourCommand decide(const BehaviourInput& input) override {
    WanderProgress progress;
    if (last_stamp_s_) progress.elapsed_s = std::max(0.0, input.stamp_s - *last_stamp_s_);
    if (input.X_WB && last_pose_) {
      progress.travelled_m = std::hypot(input.X_WB->x - last_pose_->x, input.X_WB->y - last_pose_->y);
      progress.turned_rad = std::abs(geometry::wrap_angle(input.X_WB->theta - last_pose_->theta));
    }
    last_stamp_s_ = input.stamp_s;
    last_pose_ = input.X_WB;
    if (input.ring) {
      // Beyond the seed: something inside the circle the body's corners sweep turning on the spot. Turning would hit
      // it, so first move straight away from it (along the heading, whichever way leads off).
      const BeamReading* nearest = nullptr;
      for (const BeamReading& beam : input.ring->beams) {
        if (!nearest || beam.range_m < nearest->range_m) nearest = &beam;
      }
      if (nearest != nullptr && nearest->range_m < body_radius_m_ + kTurnSweepMargin_m) {
        BehaviourCommand command;
        command.linear_mps = std::cos(nearest->bearing_rad) >= 0.0 ? -kEaseOffSpeed_mps : kEaseOffSpeed_mps;
        command.state = BehaviourState::kAvoidEaseOff;
        return command;
      }
    }
    const WanderDecision decision = behaviour_.decide(
        input.ring ? ring_as_ahead(*input.ring, body_radius_m_) : range_set_from_scan(input.scan), progress);
    BehaviourCommand command;
    command.linear_mps = decision.linear_mps;
    command.angular_radps = decision.angular_radps;
    command.stop = decision.stop;
    command.state = decision.state;
    return command;
  }

 private:
  static constexpr double kTurnSweepMargin_m = 0.1;
  static constexpr double kEaseOffSpeed_mps = 0.1;
  WanderBehaviour behaviour_;
  double body_radius_m_;  // the footprint's bounding radius, for ring readings
  std::optional<double> last_stamp_s_;
  std::optional<geometry::Pose2> last_pose_;
};

// PointBug's decision as a velocity held for one control cycle of period_s.
BehaviourCommand pointbug_command(const PointBugDecision& decision, double period_s) {
  BehaviourCommand command;
  command.state = decision.state;
  command.stop = decision.stop;
  // The seed's drive_goto ends each turn and leg exactly; a velocity held for one control cycle must not
  // overshoot them, or the heading tolerance would make the robot oscillate.
  command.angular_radps =
      std::copysign(std::min(std::abs(decision.angular_radps), std::abs(decision.target.turn_rad) / period_s),
                    decision.angular_radps);
  command.linear_mps = decision.linear_mps;
  if (decision.linear_mps > 0.0) {
    command.linear_mps = std::min(decision.linear_mps, decision.target.distance_m / period_s);
    // Small heading errors while driving are corrected on the way rather than by stopping to re-aim.
    command.angular_radps = std::clamp(decision.target.turn_rad / period_s / 4.0, -0.3, 0.3);
  }
  return command;
}

class GotoAdapter final : public Behaviour {
 public:
  GotoAdapter(const PointBugParams& params, double goal_x_m, double goal_y_m, double period_s,
              double corridor_half_width_m)
      : behaviour_(params, goal_x_m, goal_y_m),
        goal_W_(goal_x_m, goal_y_m),
        period_s_(period_s),
        corridor_half_width_m_(corridor_half_width_m) {}
  [[nodiscard]] std::string_view name() const override { return "goto"; }
  [[nodiscard]] std::optional<Eigen::Vector2d> current_goal() const override { return goal_W_; }
  [[nodiscard]] std::vector<Eigen::Vector2d> planned_path() const override {
    if (!position_W_ || done_) return {};
    return {*position_W_, goal_W_};
  }
  BehaviourCommand decide(const BehaviourInput& input) override {
    BehaviourCommand command;
    if (!input.X_WB) {
      command.stop = true;
      command.state = BehaviourState::kNoPose;
      return command;
    }
    position_W_ = Eigen::Vector2d(input.X_WB->x, input.X_WB->y);
    std::vector<SweepReading> readings = sweep_from_scan(input.scan);
    // Beyond the seed: the ActivityBot's one forward beam stands for its whole 0.13 m width, a wider robot's does
    // not; straight ahead reads the nearest return inside the corridor the body sweeps driving forward.
    if (corridor_half_width_m_ > 0.0) {
      for (SweepReading& reading : readings) {
        if (reading.angle_rad == 0.0) reading.range_m = std::min(reading.range_m, corridor_range(input.scan));
      }
    }
    const Sweep sweep{readings, input.scan.range_max_m};
    const Pose2 pose{input.X_WB->x, input.X_WB->y, input.X_WB->theta};
    const PointBugDecision decision = behaviour_.decide(pose, sweep);
    command = pointbug_command(decision, period_s_);
    done_ = command.state == BehaviourState::kReached || command.state == BehaviourState::kNoPath;
    return command;
  }

 private:
  // Forward distance to the nearest return whose lateral offset lies within the corridor, sensor frame.
  [[nodiscard]] double corridor_range(const ScanView& scan) const {
    double nearest = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
      const double range = static_cast<double>(scan.ranges_m[i]);
      if (!(range < scan.range_max_m)) continue;
      const double bearing = scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad;
      const double ahead = range * std::cos(bearing);
      if (ahead > 0.0 && std::abs(range * std::sin(bearing)) <= corridor_half_width_m_) {
        nearest = std::min(nearest, ahead);
      }
    }
    return nearest;
  }

  PointBugBehaviour behaviour_;
  Eigen::Vector2d goal_W_;
  std::optional<Eigen::Vector2d> position_W_;  // at the latest decision
  bool done_ = false;                          // reached, or no path: nothing planned any more
  double period_s_;
  double corridor_half_width_m_;
};

// PointBug on a servo-swept beam (make_servo_goto).
class ServoGotoAdapter final : public Behaviour {
 public:
  ServoGotoAdapter(const PointBugParams& params, const ServoSweepLimits& limits, double servo_yaw_rad, double goal_x_m,
                   double goal_y_m, double period_s)
      : behaviour_(params, goal_x_m, goal_y_m),
        assembler_(limits),
        servo_yaw_rad_(servo_yaw_rad),
        goal_W_(goal_x_m, goal_y_m),
        period_s_(period_s) {}
  [[nodiscard]] std::string_view name() const override { return "goto"; }
  [[nodiscard]] std::optional<Eigen::Vector2d> current_goal() const override { return goal_W_; }
  [[nodiscard]] std::vector<Eigen::Vector2d> planned_path() const override {
    if (!position_W_ || done_) return {};
    return {*position_W_, goal_W_};
  }
  BehaviourCommand decide(const BehaviourInput& input) override {
    BehaviourCommand command;
    command.stop = true;
    if (!input.servo) {
      command.state = BehaviourState::kNoSweepReading;
      return command;
    }
    const bool swept = assembler_.add(input.servo->servo_angle_rad, input.servo->range_m, input.servo->stamp_s);
    if (!input.X_WB) {
      command.state = BehaviourState::kNoPose;
      return command;
    }
    const Pose2 pose{input.X_WB->x, input.X_WB->y, input.X_WB->theta};
    position_W_ = Eigen::Vector2d(pose.x, pose.y);
    const ServoSweepLimits& limits = assembler_.limits();
    if (std::abs(input.servo->servo_angle_rad + servo_yaw_rad_) <= 0.5 * limits.servo_step_rad) {
      const double range =
          input.servo->range_m >= limits.range_max_m ? std::numeric_limits<double>::infinity() : input.servo->range_m;
      ahead_ = Ahead{range, pose};
    }
    if (awaiting_sweep_) {
      if (!swept) {
        command.state = BehaviourState::kSweep;
        return command;
      }
      awaiting_sweep_ = false;
      std::vector<SweepReading> readings = assembler_.last_sweep();
      for (SweepReading& reading : readings) reading.angle_rad += servo_yaw_rad_;
      ahead_.reset();  // PointBug turns toward its sudden point now
      return finish(behaviour_.decide(pose, Sweep{readings, limits.range_max_m}));
    }
    // The reading straight ahead, if it was taken facing this way, less what has been driven toward it since. A
    // missing one reads as blocked, which PointBug can only answer with no_path on a sweep of one reading.
    double ahead_m = 0.0;
    const bool ahead_known =
        ahead_ &&
        std::abs(geometry::wrap_angle(ahead_->pose.theta - pose.theta)) <=
            std::max(kAheadHeadingTolerance_rad, kReaimHeadingTolerances * behaviour_.params().heading_tolerance_rad);
    if (ahead_known) {
      const double driven_m =
          (pose.x - ahead_->pose.x) * std::cos(pose.theta) + (pose.y - ahead_->pose.y) * std::sin(pose.theta);
      ahead_m = std::max(0.0, ahead_->range_m - std::max(0.0, driven_m));
    }
    const std::array<SweepReading, 1> forward{SweepReading{0.0, ahead_m}};
    PointBugBehaviour trial = behaviour_;
    const PointBugDecision decision = trial.decide(pose, Sweep{forward, limits.range_max_m});
    if (trial.state() == PointBugBehaviour::State::kNoPath && behaviour_.state() != PointBugBehaviour::State::kNoPath) {
      if (!ahead_known) {
        command.state = BehaviourState::kLookAhead;
        return command;
      }
      // Something within obstacle_range_m ahead: stand and take a whole sweep from here.
      awaiting_sweep_ = true;
      assembler_.restart();
      command.state = BehaviourState::kSweep;
      return command;
    }
    behaviour_ = trial;
    return finish(decision);
  }

 private:
  // A reading ahead counts while the heading stays this close to the one it was taken at (assumption: the beam is
  // about as wide as the ActivityBot at the obstacle range), and at least while PointBug keeps stepping without
  // re-aiming: wheel speeds in whole ticks correct the heading in steps of a tick-quantised heading.
  static constexpr double kAheadHeadingTolerance_rad = 3.0 * kDeg;
  static constexpr double kReaimHeadingTolerances = 4.0;  // PointBug's step_to_goal re-aims beyond this many

  struct Ahead {
    double range_m = 0.0;
    Pose2 pose;  // where the robot was when the servo pointed ahead
  };

  BehaviourCommand finish(const PointBugDecision& decision) {
    BehaviourCommand command = pointbug_command(decision, period_s_);
    done_ = command.state == BehaviourState::kReached || command.state == BehaviourState::kNoPath;
    if (command.state == BehaviourState::kDriveToSuddenPoint) {
      if (last_state_ != command.state) {
        ++leg_id_;
        leg_m_ = decision.target.distance_m;
      }
      command.leg_m = leg_m_;
      command.leg_id = leg_id_;
    }
    last_state_ = command.state;
    return command;
  }

  PointBugBehaviour behaviour_;
  ServoSweepAssembler assembler_;
  double servo_yaw_rad_;
  Eigen::Vector2d goal_W_;
  double period_s_;
  std::optional<Ahead> ahead_;
  bool awaiting_sweep_ = false;
  BehaviourState last_state_ = BehaviourState::kNone;  // of the last decision that moved or stopped by PointBug
  std::uint64_t leg_id_ = 0;                           // counts the legs to sudden points
  double leg_m_ = 0.0;                                 // the current leg's length where it began
  std::optional<Eigen::Vector2d> position_W_;
  bool done_ = false;
};

// No threat anywhere: the guidance then just tracks its target (a world whose PTEM has not been published yet).
class NoThreat final : public ThreatField {
 public:
  [[nodiscard]] mapping::PtemThreat threat_and_gradient(const Eigen::Vector2d& /*p_W*/) const override { return {}; }
  [[nodiscard]] std::optional<double> restricted_threshold() const override { return std::nullopt; }
};

class WaypointsAdapter final : public Behaviour {
 public:
  WaypointsAdapter(const PtemGuidanceParams& params, std::vector<Eigen::Vector2d> waypoints_W)
      : guidance_(params, std::move(waypoints_W)) {}
  [[nodiscard]] std::string_view name() const override { return "waypoints"; }
  [[nodiscard]] std::optional<Eigen::Vector2d> current_goal() const override {
    return guidance_.waypoints_W()[std::min(guidance_.waypoint_index(), guidance_.waypoints_W().size() - 1)];
  }
  [[nodiscard]] std::vector<Eigen::Vector2d> planned_path() const override {
    const std::vector<Eigen::Vector2d>& waypoints_W = guidance_.waypoints_W();
    if (!position_W_ || reached_ || guidance_.waypoint_index() >= waypoints_W.size()) return {};
    std::vector<Eigen::Vector2d> path{*position_W_};
    path.insert(path.end(), waypoints_W.begin() + static_cast<std::ptrdiff_t>(guidance_.waypoint_index()),
                waypoints_W.end());
    return path;
  }
  BehaviourCommand decide(const BehaviourInput& input) override {
    BehaviourCommand command;
    if (!input.X_WB) {
      command.stop = true;
      command.state = BehaviourState::kNoPose;
      return command;
    }
    position_W_ = Eigen::Vector2d(input.X_WB->x, input.X_WB->y);
    const Pose2 pose{input.X_WB->x, input.X_WB->y, input.X_WB->theta};
    const PtemGuidanceDecision decision = input.ptem != nullptr ? guidance_.decide(pose, input.stamp_s, *input.ptem)
                                                                : guidance_.decide(pose, input.stamp_s, NoThreat{});
    command.linear_mps = decision.linear_mps;
    command.angular_radps = decision.angular_radps;
    command.stop = decision.stop;
    command.state = decision.reached ? BehaviourState::kReached : decision.state;
    reached_ = decision.reached;
    return command;
  }

 private:
  PtemGuidance guidance_;
  std::optional<Eigen::Vector2d> position_W_;  // at the latest decision
  bool reached_ = false;
};

// While an escape runs: its command, or when the guard would stop it (a corner of the footprint swinging into what
// stands beside the robot, its nose into a pillar, a turn on the spot into a door frame the robot backed up to) a
// motion the guard lets through, kept up for kHold_s unless the guard would stop it too: the same turn on the spot,
// the same turn on an arc forward (which moves the corner that would swing into something along instead), backing,
// the turn the other way round, creeping forward. Without it the robot stands for good where every way out starts with
// a motion the guard stops; going back to the escape's own command as soon as it passes again swings the robot to and
// fro at the edge of what the guard allows.
class Unwedger {
 public:
  Unwedger(const geometry::Footprint& footprint, const GuardParams& guard) : footprint_(footprint), guard_(guard) {}

  [[nodiscard]] BehaviourCommand apply(const BehaviourInput& input, const Pose2& pose, BehaviourCommand command) {
    if (!guard_.enabled || input.grid == nullptr) return command;
    const GuardModels models{input.grid, input.octomap, guard_.check_ptem ? input.ptem : nullptr, input.ptem,
                             input.moving_tracks};
    const auto passes = [&](double linear_mps, double angular_radps) {
      return guard_command(models, footprint_, pose, linear_mps, angular_radps, guard_).action != GuardAction::kStop;
    };
    const auto apply_motion = [&command](const Motion& motion) {
      command.linear_mps = motion.linear_mps;
      command.angular_radps = motion.angular_radps;
      command.wheels.reset();
      if (motion.linear_mps < 0.0) command.state = BehaviourState::kEscapeBackOff;
      return command;
    };
    if (input.stamp_s < until_s_ && passes(motion_.linear_mps, motion_.angular_radps)) return apply_motion(motion_);
    if (passes(command.linear_mps, command.angular_radps)) return command;
    const double turn = command.angular_radps < 0.0 ? -1.0 : 1.0;
    const std::array<Motion, 5> motions{{{0.0, turn * kTurn_radps},
                                         {kArc_mps, turn * kTurn_radps},
                                         {-kCreep_mps, 0.0},
                                         {0.0, -turn * kTurn_radps},
                                         {kCreep_mps, 0.0}}};
    for (const Motion& motion : motions) {
      if (!passes(motion.linear_mps, motion.angular_radps)) continue;
      motion_ = motion;
      until_s_ = input.stamp_s + kHold_s;
      return apply_motion(motion);
    }
    return command;
  }

 private:
  static constexpr double kTurn_radps = 0.6;
  static constexpr double kCreep_mps = 0.1;
  static constexpr double kArc_mps = 0.2;
  static constexpr double kHold_s = 1.5;
  struct Motion {
    double linear_mps = 0.0;
    double angular_radps = 0.0;
  };

  geometry::Footprint footprint_;
  GuardParams guard_;
  Motion motion_;  // what the robot does while the guard stops the escape's own command
  double until_s_ = -std::numeric_limits<double>::infinity();
};

class EscapeWrapper final : public Behaviour {
 public:
  EscapeWrapper(std::function<std::unique_ptr<Behaviour>()> rebuild, const RobotShape& robot, const GuardParams& guard)
      : rebuild_(std::move(rebuild)),
        inner_(rebuild_()),
        detector_(detector_params()),
        unwedger_(robot.footprint, guard),
        height_m_(geometry::footprint_height(robot.footprint)) {
    // Hard limit at the inscribed radius, so a gap the body fits through aligned stays open; a cost gradient out to
    // the circumscribed radius keeps the path off walls where there is room (the guard checks the real footprint).
    planner_.footprint_radius_m = inscribed_radius(robot.footprint);
    planner_.cost_radius_m = geometry::bounding_radius(robot.footprint);
    planner_.near_obstacle_extra_cost = 2.0;
    planner_.window_margin_m = 6.0;
    follower_.linear_speed_mps = std::min(0.4, robot.max_linear_mps);
    follower_.lookahead_m = 0.6;
    follower_.goal_tolerance_m = 0.15;
    follower_.max_angular_radps = 0.8;
  }
  [[nodiscard]] std::string_view name() const override { return inner_->name(); }
  [[nodiscard]] std::optional<Eigen::Vector2d> current_goal() const override { return inner_->current_goal(); }
  [[nodiscard]] std::vector<Eigen::Vector2d> planned_path() const override {
    if (path_.empty() || !position_W_) return inner_->planned_path();
    return remaining_path(*position_W_, path_, segment_);
  }

  BehaviourCommand decide(const BehaviourInput& input) override {
    const std::optional<Eigen::Vector2d> goal = inner_->current_goal();
    if (!goal || !input.X_WB) return inner_->decide(input);
    const Pose2 pose{input.X_WB->x, input.X_WB->y, input.X_WB->theta};
    position_W_ = Eigen::Vector2d(pose.x, pose.y);
    if (!path_.empty()) return follow(input, pose, *goal);
    // PointBug only sees what its sweep shows now; the map remembers more. When the straight way to the goal runs
    // into something remembered (the U of seed 000 Fig 5.3 seen from outside, the cup of seed 003 Fig 2.10), follow
    // the global path round it instead of driving in and finding out.
    if (inner_->name() == "goto" && input.grid != nullptr && input.stamp_s >= next_look_ahead_s_) {
      next_look_ahead_s_ = input.stamp_s + 0.5;
      const auto band = height_band(input);  // what the laser plane misses: a kerb, an overhang
      if (!segment_clear(*input.grid, {pose.x, pose.y}, *goal, planner_.footprint_radius_m) ||
          (band && !band->segment_clear({pose.x, pose.y}, *goal, planner_.footprint_radius_m))) {
        escape_state_ = BehaviourState::kEscapeBlocked;
        if (plan(input, pose, *goal)) return follow(input, pose, *goal);
      }
    }
    BehaviourCommand command = inner_->decide(input);
    if (command.state == BehaviourState::kReached) return command;
    const LoopStatus status = detector_.update({pose, input.stamp_s, goal, command.state});
    const bool stuck = command.state == BehaviourState::kNoPath || status.loop || status.stalled;
    if (stuck && input.stamp_s >= next_plan_s_) {
      escape_state_ = command.state == BehaviourState::kNoPath ? BehaviourState::kEscapeNoPath
                      : status.reason == LoopReason::kLoop     ? BehaviourState::kEscapeLoop
                                                               : BehaviourState::kEscapeStall;
      if (plan(input, pose, *goal)) return follow(input, pose, *goal);
      next_plan_s_ = input.stamp_s + 2.0;
    }
    return command;
  }

 private:
  static LoopDetectorParams detector_params() {
    LoopDetectorParams params;
    params.stall_time_s = 8.0;
    return params;
  }

  std::optional<HeightBandLayer> height_band(const BehaviourInput& input) const {
    if (input.octomap == nullptr) return std::nullopt;
    return std::optional<HeightBandLayer>(std::in_place, *input.octomap, height_m_);
  }

  bool plan(const BehaviourInput& input, const Pose2& pose, const Eigen::Vector2d& goal) {
    if (input.grid == nullptr) return false;
    const auto band = height_band(input);
    const GlobalPathResult result =
        plan_global_path(*input.grid, band ? &*band : nullptr, {pose.x, pose.y}, goal, planner_);
    if (result.status != GlobalPathStatus::kFound || result.waypoints_W.size() < 2) return false;
    path_ = result.waypoints_W;
    segment_ = 0;
    planned_at_s_ = input.stamp_s;
    return true;
  }

  BehaviourCommand follow(const BehaviourInput& input, const Pose2& pose, const Eigen::Vector2d& goal) {
    // The map grows while the robot drives: replan now and then so the path keeps up with what it has seen.
    if (input.stamp_s - planned_at_s_ > 3.0) {
      const std::vector<Eigen::Vector2d> previous = path_;
      const std::size_t previous_segment = segment_;
      // Keep the path being followed (its clear part, when the grown map blocks it further on) unless the new one is
      // clearly cheaper (GlobalPathParams::current_path_W).
      planner_.current_path_W = planned_path();
      const bool planned = plan(input, pose, goal);
      planner_.current_path_W.clear();
      if (!planned) {
        path_ = previous;
        segment_ = previous_segment;
        planned_at_s_ = input.stamp_s;
      }
    }
    const PurePursuitCommand step = pure_pursuit(pose, path_, follower_, segment_);
    segment_ = step.segment;
    BehaviourCommand command;
    command.linear_mps = step.linear_mps;
    command.angular_radps = step.angular_radps;
    command.state = escape_state_;
    if (step.reached) {
      // At the goal the escape ends the run; elsewhere a fresh inner behaviour resumes from here.
      path_.clear();
      detector_.reset();
      // PointBug's no_path is final, so goto starts afresh (at the goal it reports reached at once); the waypoint
      // guidance keeps its target, which waits at the waypoint the escape led to.
      if (inner_->name() == "goto") inner_ = rebuild_();
      return inner_->decide(input);
    }
    return unwedger_.apply(input, pose, command);
  }

  std::function<std::unique_ptr<Behaviour>()> rebuild_;
  std::unique_ptr<Behaviour> inner_;
  LoopDetector detector_;
  Unwedger unwedger_;
  GlobalPathParams planner_;
  PurePursuitParams follower_;
  std::vector<Eigen::Vector2d> path_;
  std::size_t segment_ = 0;
  std::optional<Eigen::Vector2d> position_W_;  // at the latest decision
  double planned_at_s_ = 0.0;
  double next_plan_s_ = -std::numeric_limits<double>::infinity();
  double next_look_ahead_s_ = -std::numeric_limits<double>::infinity();
  BehaviourState escape_state_ = BehaviourState::kEscapeStalled;  // what set the current escape off
  double height_m_;  // the robot's top: octree obstacles below it block the way
};

// Beyond the seeds (seed 000 §5.2: "memory mapping also enables the robot to get out of deadlock situations"): a
// behaviour without a goal (Bearcat, wander) that stops, or makes no headway for stall_time_s, gets a way out planned
// over the remembered grid: the first reachable point of a ring of candidates round the robot, those behind it first,
// followed by pure pursuit; then a fresh inner behaviour carries on from there, facing away from the trap.
class MapEscapeWrapper final : public Behaviour {
 public:
  MapEscapeWrapper(std::function<std::unique_ptr<Behaviour>()> rebuild, const RobotShape& robot,
                   const GuardParams& guard)
      : rebuild_(std::move(rebuild)),
        inner_(rebuild_()),
        unwedger_(robot.footprint, guard),
        height_m_(geometry::footprint_height(robot.footprint)) {
    // No goal to squeeze through to: the way out keeps the whole turning circle clear, and more where there is room.
    planner_.footprint_radius_m = geometry::bounding_radius(robot.footprint);
    planner_.cost_radius_m = planner_.footprint_radius_m + 0.4;
    planner_.near_obstacle_extra_cost = 2.0;
    planner_.window_margin_m = 2.0;
    planner_.unknown_extra_cost = 8.0;  // keep the way out on ground the map has seen
    follower_.linear_speed_mps = std::min(0.5, robot.max_linear_mps);
    follower_.lookahead_m = 0.6;
    follower_.goal_tolerance_m = 0.3;
    follower_.max_angular_radps = 0.8;
    clearance_m_ = geometry::bounding_radius(robot.footprint);
  }
  [[nodiscard]] std::string_view name() const override { return inner_->name(); }
  [[nodiscard]] std::vector<Eigen::Vector2d> planned_path() const override {
    if (path_.empty() || !position_W_) return inner_->planned_path();
    return remaining_path(*position_W_, path_, segment_);
  }

  BehaviourCommand decide(const BehaviourInput& input) override {
    if (!input.X_WB) return inner_->decide(input);
    const Pose2 pose{input.X_WB->x, input.X_WB->y, input.X_WB->theta};
    position_W_ = Eigen::Vector2d(pose.x, pose.y);
    if (!path_.empty()) {
      BehaviourCommand command = follow(input, pose);
      if (command.state != BehaviourState::kNone) return unwedger_.apply(input, pose, command);
    }
    BehaviourCommand command = inner_->decide(input);
    // Headway: the robot left a disc round where it last made some; turning on the spot is not headway.
    if (!anchor_W_ || (*position_W_ - *anchor_W_).norm() > kHeadway_m) {
      anchor_W_ = position_W_;
      anchor_s_ = input.stamp_s;
    }
    if (input.stamp_s < back_off_until_s_) {
      BehaviourCommand back;
      back.linear_mps = -kBackOffSpeed_mps;
      back.state = BehaviourState::kEscapeBackOff;
      return back;
    }
    const bool stuck = command.stop || input.stamp_s - anchor_s_ > kStallTime_s;
    if (!stuck) return command;
    if (input.stamp_s < next_plan_s_) return unwedger_.apply(input, pose, command);
    if (held_up_ && !input.ring && clear_behind(input, pose)) {
      // The last way out was held up where it started (a wall the guard sees close ahead): back off first.
      held_up_ = false;
      back_off_until_s_ = input.stamp_s + kBackOffTime_s;
      anchor_W_ = position_W_;
      anchor_s_ = input.stamp_s + kBackOffTime_s;
      BehaviourCommand back;
      back.linear_mps = -kBackOffSpeed_mps;
      back.state = BehaviourState::kEscapeBackOff;
      return back;
    }
    // The inner behaviours without a goal stop only in the Bearcat's deadlock.
    escape_state_ = command.stop && command.state == BehaviourState::kDeadlock ? BehaviourState::kEscapeDeadlock
                                                                               : BehaviourState::kEscapeStalled;
    if (plan_out(input, pose)) {
      BehaviourCommand escape = follow(input, pose);
      if (escape.state != BehaviourState::kNone) return unwedger_.apply(input, pose, escape);
    }
    // A search cut short by its per-cycle budget goes on at the next cycle; one that found nothing waits a second.
    next_plan_s_ = next_candidate_ != 0 ? input.stamp_s : input.stamp_s + 1.0;
    if (command.stop) {
      // No way out on the map yet: turn on the spot so the sensors see more of the surroundings.
      command = BehaviourCommand{};
      command.angular_radps = 0.5;
      command.state = BehaviourState::kEscapeLookRound;
    }
    // Whatever it does meanwhile, not what the guard stops: a wander into a wall the ring no longer hears would stand
    // there for good.
    return unwedger_.apply(input, pose, command);
  }

 private:
  static constexpr double kHeadway_m = 0.5;
  static constexpr double kStallTime_s = 6.0;
  static constexpr double kEscapeTimeout_s = 40.0;
  static constexpr double kEscapeHeldUp_s = 4.0;
  static constexpr double kBackOffSpeed_mps = 0.15;
  static constexpr double kRingAheadClearance_m = 0.5;  // ring readings this far beyond the body block an escape
  static constexpr double kBackOffTime_s = 2.0;
  static constexpr double kHeadway_rad = 0.5;  // turning this far towards the way out is headway too

  // Whether reversing kBackOffSpeed_mps for kBackOffTime_s stays clear of what the ring hears behind (when the robot
  // has one) and of what the map remembers there.
  [[nodiscard]] bool clear_behind(const BehaviourInput& input, const Pose2& pose) const {
    const double reverse_m = kBackOffSpeed_mps * kBackOffTime_s;
    if (input.ring) {
      for (const BeamReading& beam : input.ring->beams) {
        if (std::abs(geometry::wrap_angle(beam.bearing_rad)) < 0.6 * std::numbers::pi) continue;
        if (beam.range_m < clearance_m_ + reverse_m + 0.2) return false;
      }
    }
    if (input.grid == nullptr) return input.ring.has_value();
    const Eigen::Vector2d here(pose.x, pose.y);
    const Eigen::Vector2d back = here - (reverse_m + 0.1) * Eigen::Vector2d(std::cos(pose.theta), std::sin(pose.theta));
    return segment_clear(*input.grid, here, back, clearance_m_);
  }

  [[nodiscard]] bool ring_blocks_ahead(const RangeSet& ring) const {
    const RangeSet ahead = ring_as_ahead(ring, clearance_m_);
    return std::any_of(ahead.beams.begin(), ahead.beams.end(),
                       [&](const BeamReading& beam) { return beam.range_m < clearance_m_ + kRingAheadClearance_m; });
  }

  bool plan_out(const BehaviourInput& input, const Pose2& pose) {
    if (input.grid == nullptr) return false;
    std::optional<HeightBandLayer> band;
    if (input.octomap != nullptr) band.emplace(*input.octomap, height_m_);
    const Eigen::Vector2d here(pose.x, pose.y);
    // Behind first, then ever closer to straight ahead, alternating sides; the side to try first alternates between
    // escapes so two traps in a row do not send the robot back and forth along the same line.
    constexpr std::array<double, 8> kOffsets_deg{180.0, 135.0, -135.0, 90.0, -90.0, 45.0, -45.0, 0.0};
    const double side = (escapes_ % 2 == 0) ? 1.0 : -1.0;
    constexpr std::array<double, 3> kRadii_m{4.0, 2.5, 1.5};
    constexpr std::size_t kCandidates = kRadii_m.size() * kOffsets_deg.size();
    int tried = 0;
    // A cycle plans at most kMaxPlansPerCycle candidates; the next one carries on where this one stopped.
    for (std::size_t k = next_candidate_; k < kCandidates; ++k) {
      const double radius_m = kRadii_m[k / kOffsets_deg.size()];
      const double bearing = pose.theta + side * kOffsets_deg[k % kOffsets_deg.size()] * kDeg;
      const Eigen::Vector2d target = here + radius_m * Eigen::Vector2d(std::cos(bearing), std::sin(bearing));
      // Only to ground the map has seen free: an unseen cell may be the far side of a wall no beam came back from
      // (a sonar's echo is specular).
      const geometry::CellIndex cell = geometry::GridGeometry(input.grid->cell_size()).cell_of(target);
      if (!input.grid->observed(cell) || input.grid->occupied(cell)) continue;
      if (!segment_clear(*input.grid, target, target, clearance_m_)) continue;
      if (++tried > kMaxPlansPerCycle) {
        next_candidate_ = k;
        return false;
      }
      const GlobalPathResult result = plan_global_path(*input.grid, band ? &*band : nullptr, here, target, planner_);
      if (result.status != GlobalPathStatus::kFound || result.waypoints_W.size() < 2) continue;
      path_ = result.waypoints_W;
      segment_ = 0;
      escape_started_s_ = input.stamp_s;
      ++escapes_;
      next_candidate_ = 0;
      return true;
    }
    next_candidate_ = 0;
    return false;
  }

  // One step along the escape path; an empty state once it has ended (reached, or given up after kEscapeTimeout_s),
  // with a fresh inner behaviour in place.
  BehaviourCommand follow(const BehaviourInput& input, const Pose2& pose) {
    const PurePursuitCommand step = pure_pursuit(pose, path_, follower_, segment_);
    segment_ = step.segment;
    if (!escape_anchor_W_ || (*position_W_ - *escape_anchor_W_).norm() > kHeadway_m ||
        std::abs(geometry::wrap_angle(pose.theta - escape_anchor_theta_)) > kHeadway_rad) {
      escape_anchor_W_ = position_W_;
      escape_anchor_theta_ = pose.theta;
      escape_anchor_s_ = input.stamp_s;
    }
    // Held up on the way out (the guard stops what the map did not show): give up and try another way.
    const bool held_up = input.stamp_s - escape_anchor_s_ > kEscapeHeldUp_s;
    // A sonar map is sparse (echoes are specular): the ring hearing a wall across the way ends the escape too, and the
    // inner behaviour avoids it.
    const bool heard_ahead = input.ring && step.linear_mps > 0.0 && ring_blocks_ahead(*input.ring);
    if (heard_ahead) next_plan_s_ = input.stamp_s + kStallTime_s;
    if (step.reached || held_up || heard_ahead || input.stamp_s - escape_started_s_ > kEscapeTimeout_s) {
      held_up_ = held_up;
      escape_anchor_W_.reset();
      path_.clear();
      inner_ = rebuild_();
      anchor_W_ = position_W_;
      anchor_s_ = input.stamp_s;
      return {};
    }
    BehaviourCommand command;
    command.linear_mps = step.linear_mps;
    command.angular_radps = step.angular_radps;
    command.state = escape_state_;
    return command;
  }

  static constexpr int kMaxPlansPerCycle = 6;  // bounds the strand time one control cycle spends planning

  std::function<std::unique_ptr<Behaviour>()> rebuild_;
  std::unique_ptr<Behaviour> inner_;
  Unwedger unwedger_;
  GlobalPathParams planner_;
  PurePursuitParams follower_;
  double clearance_m_ = 0.0;
  std::vector<Eigen::Vector2d> path_;
  std::size_t segment_ = 0;
  std::optional<Eigen::Vector2d> position_W_;
  std::optional<Eigen::Vector2d> anchor_W_;         // where the robot last made headway
  std::optional<Eigen::Vector2d> escape_anchor_W_;  // ... on the escape path
  double escape_anchor_theta_ = 0.0;                // and the heading there
  double escape_anchor_s_ = 0.0;
  bool held_up_ = false;            // the last escape path made no headway
  double back_off_until_s_ = -1.0;  // reversing until then
  double anchor_s_ = 0.0;
  double escape_started_s_ = 0.0;
  double next_plan_s_ = -std::numeric_limits<double>::infinity();
  int escapes_ = 0;
  std::size_t next_candidate_ = 0;                                // where the next cycle's search for a way out resumes
  BehaviourState escape_state_ = BehaviourState::kEscapeStalled;  // what set the current escape off
  double height_m_;
};

// Yields to moving obstacles around whatever the inner behaviour commands (make_yield).
class YieldWrapper final : public Behaviour {
 public:
  YieldWrapper(std::unique_ptr<Behaviour> inner, const RobotShape& robot, const GuardParams& guard)
      : inner_(std::move(inner)), robot_(robot), guard_(guard) {
    aside_linear_mps_ = std::min(0.4, robot.max_linear_mps);
  }
  [[nodiscard]] std::string_view name() const override { return inner_->name(); }
  [[nodiscard]] std::optional<Eigen::Vector2d> current_goal() const override { return inner_->current_goal(); }
  [[nodiscard]] std::vector<Eigen::Vector2d> planned_path() const override { return inner_->planned_path(); }
  [[nodiscard]] std::vector<TrackedObstacle> moving_obstacles() const override { return moving_; }

  BehaviourCommand decide(const BehaviourInput& input) override {
    BehaviourCommand command = inner_->decide(input);
    moving_.clear();
    if (!input.X_WB || !(guard_.predict_horizon_s > 0.0)) return command;
    const geometry::Pose2& X_WB = *input.X_WB;
    if (input.ptem != nullptr) {
      const Eigen::Vector2d p_WS =
          X_WB.position() + robot_.laser_x_m * Eigen::Vector2d(std::cos(X_WB.theta), std::sin(X_WB.theta));
      const double range_m =
          input.scan.range_max_m > 0.0 ? input.scan.range_max_m : std::numeric_limits<double>::infinity();
      std::optional<LaserArc> arc;
      if (!input.scan.ranges_m.empty()) {
        arc = LaserArc{X_WB.theta, input.scan.angle_min_rad,
                       input.scan.angle_min_rad +
                           input.scan.angle_increment_rad * static_cast<double>(input.scan.ranges_m.size() - 1)};
      }
      tracker_.update(*input.ptem, p_WS, range_m, arc);
    }
    // The robot's own velocity over the last cycle, world frame.
    Eigen::Vector2d robot_velocity_W = Eigen::Vector2d::Zero();
    if (last_position_W_ && input.stamp_s - last_stamp_s_ > 1e-6) {
      robot_velocity_W = (X_WB.position() - *last_position_W_) / (input.stamp_s - last_stamp_s_);
    }
    last_position_W_ = X_WB.position();
    last_stamp_s_ = input.stamp_s;
    for (const TrackedObstacle& track : tracker_.moving()) {
      // Returns that travel with the robot are where its laser plane meets a slope or reaches its range: the
      // viewpoint moves, not the thing seen (and a walker keeping pace ahead is no closer for it).
      if ((track.velocity_W - robot_velocity_W).norm() < kSameVelocity_mps) continue;
      // One going away from the robot is leaving its way (and where a laser plane meets a slope ahead, the returns
      // recede as the robot climbs): what it still blocks, the behaviour and the guard see as it stands.
      const Eigen::Vector2d away_W = track.centre_W - X_WB.position();
      if (away_W.norm() > 1e-6 && track.velocity_W.dot(away_W.normalized()) > kReceding_mps) continue;
      moving_.push_back(track);
    }
    if (const std::optional<TrackedObstacle> approaching = approaching_returns(input, X_WB)) {
      // What the tracker already follows is not counted twice.
      const bool tracked = std::any_of(moving_.begin(), moving_.end(), [&](const TrackedObstacle& track) {
        return (track.centre_W - approaching->centre_W).norm() < track.radius_m + approaching->radius_m;
      });
      if (!tracked) moving_.push_back(*approaching);
    }
    const std::vector<TrackedObstacle>& moving = moving_;
    if (moving.empty() || command.state == BehaviourState::kReached) {
      aside_ = std::nullopt;
      return command;
    }
    const double horizon_s = guard_.predict_horizon_s;
    const double margin_m = guard_.predict_margin_m;

    // Standing here, the robot would be run into: get out of the way rather than wait in it.
    const double rest_gap_m = predicted_gap(moving, robot_.footprint, X_WB, 0.0, 0.0, 0.0, horizon_s);
    if (rest_gap_m < margin_m) return step_aside(input, moving, command);
    aside_ = std::nullopt;
    if (command.stop || (command.linear_mps == 0.0 && command.angular_radps == 0.0)) return command;

    const std::optional<double> contact_s = predicted_contact_s(moving, robot_.footprint, X_WB, command.linear_mps,
                                                                command.angular_radps, horizon_s, margin_m);
    if (!contact_s) return command;
    if (*contact_s > horizon_s / 2.0) {
      // Far yet: arrive later, when the obstacle may have passed.
      command.linear_mps *= kYieldSlowRatio;
      command.angular_radps *= kYieldSlowRatio;
      if (command.wheels) {
        command.wheels = {command.wheels->left_mps * kYieldSlowRatio, command.wheels->right_mps * kYieldSlowRatio};
      }
      command.leg_m.reset();
      command.state = BehaviourState::kYieldSlow;
      return command;
    }
    return standing(command, BehaviourState::kYieldWait);
  }

 private:
  static constexpr double kYieldSlowRatio = 0.5;
  static constexpr double kSameVelocity_mps = 0.2;
  static constexpr double kReceding_mps = 0.1;
  static constexpr double kAsideTurn_radps = 0.7;
  static constexpr double kAsideHysteresis_m = 0.05;    // keep the previous arc unless another is clearly better
  static constexpr double kApproachingWithin_m = 1.5;   // returns this near the footprint are watched for approach
  static constexpr double kApproachingMoved_m = 0.03;   // a return this far from every return of the previous scan ...
  static constexpr double kApproachingCloser_m = 0.02;  // ... and this much closer to the footprint came at the robot
  static constexpr std::size_t kApproachingMinReturns = 3;
  // Their mean displacement at least this fast: a wall's returns sampled at other points shift every which way.
  static constexpr double kApproachingMinSpeed_mps = 0.15;
  static constexpr double kApproachingMinRadius_m = 0.2;
  static constexpr double kApproachingGroup_m = 0.5;       // one thing's returns lie this near the nearest of them
  static constexpr double kApproachingMovedShare = 0.5;    // ... and this share of the returns there moved
  static constexpr double kApproachingConsistent_m = 0.3;  // from one scan to the next, where its velocity led
  static constexpr double kApproachingKeep_s = 0.5;

  // Returns near the robot that came closer to it since the previous scan, world frame (the robot's own motion drops
  // out), as one obstacle moving at their mean displacement: what the tracker misses, when a cart's cluster merges
  // with a door frame or splits in two, or a walker's merges with a shelf. A wall is sampled at other points from scan
  // to scan, and some of its returns seem to move: only a group round the return nearest the robot counts, when most
  // of the returns there moved, and only when the previous scan found it too, where its velocity led. The last one
  // found coasts for kApproachingKeep_s.
  std::optional<TrackedObstacle> approaching_returns(const BehaviourInput& input, const geometry::Pose2& X_WB) {
    if (input.scan.ranges_m.empty() || !(input.scan.angle_increment_rad > 0.0)) return coasting_approach(input);
    if (scan_stamp_s_ && input.stamp_s - *scan_stamp_s_ < 1e-6) return coasting_approach(input);
    const Eigen::Vector2d p_WS =
        X_WB.position() + robot_.laser_x_m * Eigen::Vector2d(std::cos(X_WB.theta), std::sin(X_WB.theta));
    std::vector<Eigen::Vector2d> near_W;
    for (std::size_t i = 0; i < input.scan.ranges_m.size(); ++i) {
      const double range = static_cast<double>(input.scan.ranges_m[i]);
      if (!std::isfinite(range) || range <= 0.0 || range >= input.scan.range_max_m) continue;
      const double bearing =
          X_WB.theta + input.scan.angle_min_rad + input.scan.angle_increment_rad * static_cast<double>(i);
      const Eigen::Vector2d p_W = p_WS + range * Eigen::Vector2d(std::cos(bearing), std::sin(bearing));
      if (distance_to_footprint(robot_.footprint, X_WB, p_W) < kApproachingWithin_m) near_W.push_back(p_W);
    }
    std::optional<TrackedObstacle> found;
    const double dt_s = scan_stamp_s_ ? input.stamp_s - *scan_stamp_s_ : 0.0;
    std::optional<TrackedObstacle> candidate;
    if (dt_s > 1e-3 && dt_s < 0.5 && !previous_near_W_.empty()) {
      // Each return that moved towards the footprint, with its displacement since the previous scan.
      std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> moved;
      const Eigen::Vector2d* nearest_moved = nullptr;
      double nearest_moved_m = std::numeric_limits<double>::infinity();
      for (const Eigen::Vector2d& p_W : near_W) {
        const Eigen::Vector2d* nearest = nullptr;
        const double nearest_squared = nearest_previous(p_W, nearest);
        if (nearest == nullptr || nearest_squared < kApproachingMoved_m * kApproachingMoved_m) continue;
        // Judged against the footprint where it stands now, so that only the return's own motion counts.
        const double now_m = distance_to_footprint(robot_.footprint, X_WB, p_W);
        if (distance_to_footprint(robot_.footprint, X_WB, *nearest) - now_m < kApproachingCloser_m) continue;
        moved.emplace_back(p_W, p_W - *nearest);
        if (now_m < nearest_moved_m) {
          nearest_moved_m = now_m;
          nearest_moved = &p_W;
        }
      }
      if (nearest_moved != nullptr) {
        // One thing: the moved returns round the one nearest the robot. A thing on the move moved all of its returns
        // there; a wall sampled at other points than before, only some.
        const Eigen::Vector2d seed_W = *nearest_moved;
        Eigen::Vector2d sum_W = Eigen::Vector2d::Zero(), moved_W = Eigen::Vector2d::Zero();
        std::size_t count = 0;
        for (const auto& [p_W, d_W] : moved) {
          if ((p_W - seed_W).norm() > kApproachingGroup_m) continue;
          sum_W += p_W;
          moved_W += d_W;
          ++count;
        }
        const auto around =
            static_cast<std::size_t>(std::count_if(near_W.begin(), near_W.end(), [&](const Eigen::Vector2d& p_W) {
              return (p_W - seed_W).norm() <= kApproachingGroup_m;
            }));
        const double n = static_cast<double>(count);
        if (count >= kApproachingMinReturns && n >= kApproachingMovedShare * static_cast<double>(around) &&
            moved_W.norm() / n / dt_s >= kApproachingMinSpeed_mps) {
          TrackedObstacle obstacle;
          obstacle.centre_W = sum_W / n;
          obstacle.velocity_W = moved_W / n / dt_s;
          double radius_m = kApproachingMinRadius_m;
          for (const auto& [p_W, d_W] : moved) {
            if ((p_W - seed_W).norm() <= kApproachingGroup_m) {
              radius_m = std::max(radius_m, (p_W - obstacle.centre_W).norm());
            }
          }
          obstacle.radius_m = radius_m;
          obstacle.stamp_s = input.stamp_s;
          obstacle.moving = true;
          candidate = obstacle;
        }
      }
    }
    // Taken when the previous scan found it too, where it then was headed.
    if (candidate && approach_candidate_ &&
        (approach_candidate_->predicted_W(input.stamp_s - approach_candidate_->stamp_s) - candidate->centre_W).norm() <
            kApproachingConsistent_m) {
      found = candidate;
    }
    approach_candidate_ = candidate;
    // By x, for nearest_previous.
    std::sort(near_W.begin(), near_W.end(),
              [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() < b.x(); });
    previous_near_W_ = std::move(near_W);
    scan_stamp_s_ = input.stamp_s;
    if (found) {
      approaching_ = found;
      return found;
    }
    return coasting_approach(input);
  }

  // The squared distance from p_W to the nearest of the previous scan's near returns (sorted by x), which nearest is
  // set to; infinity and nullptr when there are none. Outwards from p_W's x, until the x gap alone is farther: a few
  // hundred returns on each side in a narrow aisle, every scan.
  double nearest_previous(const Eigen::Vector2d& p_W, const Eigen::Vector2d*& nearest) const {
    double nearest_squared = std::numeric_limits<double>::infinity();
    const auto consider = [&](const Eigen::Vector2d& q_W) {
      const double dx = q_W.x() - p_W.x();
      if (dx * dx >= nearest_squared) return false;
      const double d_squared = (q_W - p_W).squaredNorm();
      if (d_squared < nearest_squared) {
        nearest_squared = d_squared;
        nearest = &q_W;
      }
      return true;
    };
    const auto from = std::lower_bound(previous_near_W_.begin(), previous_near_W_.end(), p_W.x(),
                                       [](const Eigen::Vector2d& q_W, double x) { return q_W.x() < x; });
    for (auto right = from; right != previous_near_W_.end(); ++right) {
      if (!consider(*right)) break;
    }
    for (auto left = from; left != previous_near_W_.begin(); --left) {
      if (!consider(*(left - 1))) break;
    }
    return nearest_squared;
  }

  // The approaching returns found last, predicted to now, while they are recent enough.
  std::optional<TrackedObstacle> coasting_approach(const BehaviourInput& input) {
    if (!approaching_) return std::nullopt;
    const double age_s = input.stamp_s - approaching_->stamp_s;
    if (age_s > kApproachingKeep_s || age_s < 0.0) {
      approaching_ = std::nullopt;
      return std::nullopt;
    }
    TrackedObstacle now = *approaching_;
    now.centre_W = approaching_->predicted_W(age_s);
    now.stamp_s = input.stamp_s;
    return now;
  }

  static BehaviourCommand standing(BehaviourCommand command, BehaviourState state) {
    command.linear_mps = 0.0;
    command.angular_radps = 0.0;
    command.wheels.reset();
    command.leg_m.reset();
    command.stop = true;
    command.state = state;
    return command;
  }

  BehaviourCommand step_aside(const BehaviourInput& input, const std::vector<TrackedObstacle>& moving,
                              BehaviourCommand command) {
    const geometry::Pose2& X_WB = *input.X_WB;
    const GuardModels models{input.grid, input.octomap, nullptr, input.ptem, input.moving_tracks};
    struct Arc {
      double linear_mps;
      double angular_radps;
    };
    const double v = aside_linear_mps_;
    const std::array<Arc, 10> arcs{{{v, 0.0},
                                    {v, kAsideTurn_radps},
                                    {v, -kAsideTurn_radps},
                                    {v, 2.0 * kAsideTurn_radps},
                                    {v, -2.0 * kAsideTurn_radps},
                                    {-v, 0.0},
                                    {-v, kAsideTurn_radps},
                                    {-v, -kAsideTurn_radps},
                                    {-v, 2.0 * kAsideTurn_radps},
                                    {-v, -2.0 * kAsideTurn_radps}}};
    std::optional<std::size_t> best;
    double best_gap_m = predicted_gap(moving, robot_.footprint, X_WB, 0.0, 0.0, 0.0, 2.0 * guard_.predict_horizon_s);
    for (std::size_t i = 0; i < arcs.size(); ++i) {
      // Judged by where the arc leaves the robot, standing, as the obstacles go on for as long again: backing away
      // along an obstacle's path only puts the contact off, stepping out of its path avoids it.
      double gap_m = predicted_gap(moving, robot_.footprint, X_WB, arcs[i].linear_mps, arcs[i].angular_radps,
                                   guard_.predict_horizon_s, 2.0 * guard_.predict_horizon_s);
      if (aside_ && *aside_ == i) gap_m += kAsideHysteresis_m;
      if (gap_m <= best_gap_m) continue;
      // An arc the guard would stop at a wall or shelf is no way out.
      const GuardDecision static_check =
          guard_command(models, robot_.footprint, X_WB, arcs[i].linear_mps, arcs[i].angular_radps, guard_);
      if (static_check.action == GuardAction::kStop) continue;
      best = i;
      best_gap_m = gap_m;
    }
    aside_ = best;
    if (!best) return standing(command, BehaviourState::kYieldWait);
    command.linear_mps = arcs[*best].linear_mps;
    command.angular_radps = arcs[*best].angular_radps;
    command.wheels.reset();
    command.leg_m.reset();
    command.stop = false;
    command.state = BehaviourState::kYieldAside;
    return command;
  }

  std::unique_ptr<Behaviour> inner_;
  RobotShape robot_;
  GuardParams guard_;
  ClusterTracker tracker_;
  double aside_linear_mps_ = 0.4;
  std::optional<std::size_t> aside_;  // the arc stepped aside along in the previous cycle
  std::optional<Eigen::Vector2d> last_position_W_;
  double last_stamp_s_ = 0.0;
  std::vector<TrackedObstacle> moving_;                // as of the latest decision, for the guard
  std::vector<Eigen::Vector2d> previous_near_W_;       // the previous scan's returns near the robot, world frame, by x
  std::optional<double> scan_stamp_s_;                 // that scan's stamp
  std::optional<TrackedObstacle> approach_candidate_;  // the previous scan's approaching returns
  std::optional<TrackedObstacle> approaching_;         // the approaching returns found last
};

}  // namespace

std::unique_ptr<Behaviour> make_map_escape(std::function<std::unique_ptr<Behaviour>()> rebuild, const RobotShape& robot,
                                           const GuardParams& guard) {
  return std::make_unique<MapEscapeWrapper>(std::move(rebuild), robot, guard);
}

std::unique_ptr<Behaviour> make_bearcat(const BearcatParams& params) {
  return std::make_unique<BearcatAdapter>(params);
}

std::unique_ptr<Behaviour> make_wander(const WanderParams& params, const RobotShape& robot) {
  WanderParams scaled = params;
  const double front_m = footprint_front(robot.footprint) - robot.laser_x_m;
  scaled.obstacle_threshold_m = std::max(params.obstacle_threshold_m, front_m + 1.5 * footprint_width(robot.footprint));
  scaled.linear_speed_mps = std::min(params.linear_speed_mps, robot.max_linear_mps);
  return std::make_unique<WanderAdapter>(scaled, geometry::bounding_radius(robot.footprint));
}

PointBugParams pointbug_params_for(const RobotShape& robot) {
  PointBugParams params;
  const double width_m = footprint_width(robot.footprint);
  constexpr double kSeedWidth_m = 0.13;  // the ActivityBot the seed's corrections were made for
  if (width_m <= kSeedWidth_m * 1.5) return params;
  const double front_m = std::max(0.0, footprint_front(robot.footprint) - robot.laser_x_m);
  const double scale = width_m / kSeedWidth_m;
  params.obstacle_range_m = front_m + params.obstacle_range_m * scale / 2.0;
  params.distance_extension_m = width_m / 2.0 + 0.2;
  // The seed's +15° clears its half width plus a margin at its stopping range; keep that clearance for this robot.
  params.angle_extension_deg = std::clamp(std::atan2(width_m / 2.0 + 0.15, params.obstacle_range_m) / kDeg, 15.0, 45.0);
  params.step_m = 0.05;
  params.goal_tolerance_m = 0.05;
  params.heading_tolerance_rad = 2.0 * kDeg;
  params.linear_speed_mps = std::min(0.5, robot.max_linear_mps);
  params.turn_speed_radps = 0.8;
  return params;
}

std::unique_ptr<Behaviour> make_goto(const PointBugParams& params, double goal_x_m, double goal_y_m, double period_s,
                                     double corridor_half_width_m) {
  return std::make_unique<GotoAdapter>(params, goal_x_m, goal_y_m, std::max(period_s, 1e-3),
                                       std::max(corridor_half_width_m, 0.0));
}

std::unique_ptr<Behaviour> make_servo_goto(const PointBugParams& params, const ServoSweepLimits& limits,
                                           double servo_yaw_rad, double goal_x_m, double goal_y_m, double period_s) {
  return std::make_unique<ServoGotoAdapter>(params, limits, servo_yaw_rad, goal_x_m, goal_y_m,
                                            std::max(period_s, 1e-3));
}

std::unique_ptr<Behaviour> make_waypoints(const RobotShape& robot, std::vector<Eigen::Vector2d> waypoints_W) {
  PtemGuidanceParams params;
  params.body_radius_m = footprint_width(robot.footprint) / 2.0;
  params.max_speed_mps = std::min(params.max_speed_mps, robot.max_linear_mps);
  params.target_speed_mps = std::min(params.target_speed_mps, params.max_speed_mps);
  return std::make_unique<WaypointsAdapter>(params, std::move(waypoints_W));
}

std::unique_ptr<Behaviour> make_escape(std::function<std::unique_ptr<Behaviour>()> rebuild, const RobotShape& robot,
                                       const GuardParams& guard) {
  return std::make_unique<EscapeWrapper>(std::move(rebuild), robot, guard);
}

std::unique_ptr<Behaviour> make_yield(std::unique_ptr<Behaviour> inner, const RobotShape& robot,
                                      const GuardParams& guard) {
  return std::make_unique<YieldWrapper>(std::move(inner), robot, guard);
}

std::vector<SweepReading> sweep_from_scan(const ScanView& scan) {
  std::vector<SweepReading> readings;
  if (scan.ranges_m.empty() || !(scan.angle_increment_rad > 0.0)) return readings;
  const double tolerance_rad = std::max(scan.angle_increment_rad / 2.0, 0.5 * kDeg);
  readings.reserve(181);
  for (int degree = -90; degree <= 90; ++degree) {
    const double angle_rad = degree * kDeg;
    const double index = std::round((angle_rad - scan.angle_min_rad) / scan.angle_increment_rad);
    if (index < 0.0 || index >= static_cast<double>(scan.ranges_m.size())) continue;
    const auto i = static_cast<std::size_t>(index);
    const double bearing_rad = scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad;
    if (std::abs(bearing_rad - angle_rad) > tolerance_rad) continue;
    const double range_m = static_cast<double>(scan.ranges_m[i]);
    readings.push_back({angle_rad, range_m >= scan.range_max_m ? std::numeric_limits<double>::infinity() : range_m});
  }
  return readings;
}

}  // namespace occgeo::service::control
