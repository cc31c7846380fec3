#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <numbers>
#include <optional>
#include <string_view>
#include <vector>

#include "occgeo/mapping/ptem.h"
#include "occgeo/service/control/behaviour_state.h"
#include "occgeo/service/control/pointbug.h"

// PTEM waypoint guidance (seed 004 §4.4–4.5): a virtual target moves along the waypoints at a constant speed, ignoring
// obstacles, and waits at each waypoint until the vehicle is inside its proximity circle; the vehicle's desired heading
// and speed track the target. Near the PTEM's restricted region only headings along which the threat does not rise
// (directional derivative of the PTEM <= 0) are admissible, and the commanded heading is the admissible one closest to
// the desired heading; the speed is limited so that the vehicle, along its current heading, cannot reach the
// restricted region within a horizon. Priorities (§4.5): 1. stay out of the restricted region, 2. keep the target's
// proximity, 3. least threat exposure (it breaks ties between the two sides of an obstacle).
namespace occgeo::service::control {

// The threat field the guidance avoids, in the world frame: the PTEM snapshot in the server, anything in tests.
class ThreatField {
 public:
  virtual ~ThreatField() = default;
  // Threat density f (1/m²) and its gradient (1/m³) at p_W.
  [[nodiscard]] virtual mapping::PtemThreat threat_and_gradient(const Eigen::Vector2d& p_W) const = 0;
  // f_r, the density from which a point is restricted (1/m²); nullopt while there is none (no avoidance then).
  [[nodiscard]] virtual std::optional<double> restricted_threshold() const = 0;
};

// A PtemSnapshot as a ThreatField; holds a reference, so the snapshot must outlive it.
class PtemSnapshotField final : public ThreatField {
 public:
  explicit PtemSnapshotField(const mapping::PtemSnapshot& snapshot) : snapshot_(snapshot) {}
  [[nodiscard]] mapping::PtemThreat threat_and_gradient(const Eigen::Vector2d& p_W) const override {
    return snapshot_.threat_and_gradient(p_W);
  }
  [[nodiscard]] std::optional<double> restricted_threshold() const override { return snapshot_.restricted_threshold(); }

 private:
  const mapping::PtemSnapshot& snapshot_;
};

// Tuning of the guidance. The seed gives the structure only (its reference [30] holds the controller); every value
// below is an assumption, sized for the seed's UGV (0.381 m wide) at walking pace.
struct PtemGuidanceParams {
  double target_speed_mps = 0.25;    // the virtual target's speed along the waypoint legs, m/s
  double max_speed_mps = 0.4;        // the vehicle's largest commanded speed, m/s (> target_speed_mps to catch up)
  double max_turn_rate_radps = 1.2;  // the vehicle's largest commanded yaw rate, rad/s
  double heading_gain_per_s = 2.5;   // yaw rate per radian of heading error, 1/s
  double speed_gain_per_s = 0.8;     // extra speed per metre the target is beyond the proximity circle, 1/s
  // The target proximity circle (§4.4): the vehicle keeps the target within this radius, and a target waiting at a
  // waypoint moves on once the vehicle is inside it, metres.
  double proximity_radius_m = 0.5;
  // The last waypoint is reached when the vehicle's centre is within this distance of it, metres.
  double arrival_tolerance_m = 0.15;
  // The target also pauses while it is farther than this from the vehicle (a detour around an obstacle must not let
  // it run away; beyond the seed, which only waits at waypoints), metres; >= proximity_radius_m.
  double max_target_lead_m = 1.5;
  // The vehicle's radius: clearance to the restricted region is measured from the vehicle's body, metres (0: a point
  // vehicle, as in the seed).
  double body_radius_m = 0.0;
  // The heading constraint applies while the body is closer than this to the restricted region, metres. The vehicle
  // then keeps about this berth around a cluster, as it may not head toward it at all.
  double avoidance_distance_m = 0.3;
  // Within this clearance the admissible headings narrow from the half-plane (derivative <= 0) toward the escape cone,
  // pushing the vehicle back out, metres; <= avoidance_distance_m.
  double safety_margin_m = 0.1;
  // Half-angle of the admissible cone about the steepest descent of the threat when the body touches or is inside the
  // restricted region, radians, in [0, pi/2].
  double escape_half_angle_rad = std::numbers::pi / 4.0;
  // The speed along a heading that approaches the restricted region is limited so that the vehicle needs at least
  // this long to reach it, seconds.
  double speed_horizon_s = 1.0;
  // While avoiding, the vehicle stays on the side of the obstacle it chose unless the desired heading is more than
  // this far from straight into the threat on the other side (no chattering when the target is right behind it),
  // radians, in [0, pi/2].
  double side_hysteresis_rad = 0.35;

  // Throws std::invalid_argument naming the first field that is not finite or out of range.
  void validate() const;
};

// One guidance decision.
struct PtemGuidanceDecision {
  // kTrackTarget, kAvoid (heading or speed limited by the PTEM), kEscape (inside or touching the restricted region)
  // or kReached.
  BehaviourState state = BehaviourState::kTrackTarget;
  double linear_mps = 0.0;         // forward speed, m/s, in [0, max_speed_mps]
  double angular_radps = 0.0;      // counter-clockwise yaw rate, rad/s
  bool stop = false;               // the last waypoint is reached: stand still
  bool reached = false;            // same as stop
  std::size_t waypoint_index = 0;  // the waypoint the target heads for or waits at (the last one once reached)
  bool target_waiting = false;     // the target stands (at a waypoint or for max_target_lead_m)
  Eigen::Vector2d target_W = Eigen::Vector2d::Zero();  // the virtual target, world frame, metres
  double target_distance_m = 0.0;                      // vehicle to target, metres
  double desired_heading_rad = 0.0;                    // toward the target, world frame, in (-pi, pi]
  double desired_speed_mps = 0.0;                      // what tracking the target asks for, m/s
  double commanded_heading_rad = 0.0;                  // the admissible heading closest to the desired one
  bool heading_constrained = false;                    // the admissible heading range was in force
  // The admissible headings: within admissible_half_width_rad of admissible_centre_rad (the steepest descent of the
  // threat), when heading_constrained; all headings otherwise.
  double admissible_centre_rad = 0.0;
  double admissible_half_width_rad = std::numbers::pi;
  double max_admissible_speed_mps = 0.0;  // the speed limit along the current heading, m/s
  double threat = 0.0;                    // f at the vehicle, 1/m²
  // Estimated distance from the body to the restricted region along the threat's gradient, metres (+inf without
  // threat; <= 0 touching or inside): exact for an isolated cluster (a two-sample fit of its Gaussian), kept within the
  // bounds of a one-Gaussian field where clusters overlap.
  double clearance_m = 0.0;
};

// The guidance state machine: the virtual target and the side chosen around the current obstacle. Deterministic.
class PtemGuidance {
 public:
  // Throws std::invalid_argument naming the bad field of params, or "waypoints" when the list is empty or a waypoint
  // is not finite (naming its index).
  PtemGuidance(const PtemGuidanceParams& params, std::vector<Eigen::Vector2d> waypoints_W);

  // The command for the vehicle at pose (world frame) at time_s (seconds, any origin, non-decreasing). The first call
  // places the target at the vehicle. Throws std::invalid_argument naming the field when the pose or time is not
  // finite or time goes backwards, changing nothing.
  PtemGuidanceDecision decide(const Pose2& pose, double time_s, const ThreatField& field);
  // Same, against a PTEM snapshot.
  PtemGuidanceDecision decide(const Pose2& pose, double time_s, const mapping::PtemSnapshot& snapshot);

  [[nodiscard]] const PtemGuidanceParams& params() const { return params_; }
  [[nodiscard]] const std::vector<Eigen::Vector2d>& waypoints_W() const { return waypoints_W_; }
  [[nodiscard]] std::size_t waypoint_index() const { return waypoint_index_; }
  [[nodiscard]] bool reached() const { return reached_; }
  // The virtual target, world frame; meaningful after the first decide.
  [[nodiscard]] const Eigen::Vector2d& target_W() const { return target_W_; }

 private:
  // Moves the target by dt_s (waiting where it must) and sets reached_.
  void advance_target(const Eigen::Vector2d& p_W, double dt_s, PtemGuidanceDecision& decision);

  PtemGuidanceParams params_;
  std::vector<Eigen::Vector2d> waypoints_W_;
  std::size_t waypoint_index_ = 0;
  bool started_ = false;
  bool at_waypoint_ = false;  // the target stands on waypoints_W_[waypoint_index_]
  bool reached_ = false;
  double last_time_s_ = 0.0;
  Eigen::Vector2d target_W_ = Eigen::Vector2d::Zero();
  // The side of the steepest descent the commanded heading lies on while avoiding: +1 counter-clockwise of it, -1
  // clockwise, 0 while the heading constraint is not in force.
  int avoid_side_ = 0;
};

}  // namespace occgeo::service::control
