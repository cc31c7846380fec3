#include "occgeo/service/control/ptem_guidance.h"
#include "occgeo/geometry/pose.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "param_checks.h"

namespace occgeo::service::control {
namespace {

using detail::require;
using detail::require_non_negative;
using detail::require_positive;

constexpr double kPi = std::numbers::pi;
constexpr double kInfinity = std::numeric_limits<double>::infinity();

using geometry::wrap_angle;

Eigen::Vector2d unit(double angle_rad) { return {std::cos(angle_rad), std::sin(angle_rad)}; }

// The threat at the vehicle, seen as a distance: clearance from the body to the restricted region and the direction
// in which the threat falls fastest.
struct ThreatView {
  double value = 0.0;
  double clearance_m = kInfinity;  // <= 0: touching or inside
  bool inside = false;             // f >= f_r at the centre
  bool present = false;            // there is a threat gradient to steer by
  double away_rad = 0.0;           // steepest descent of the threat
};

// Distance from p_W to the restricted contour f = f_r along the threat's gradient, from two samples of the field.
// Near an isolated cluster ln f is the quadratic ln(peak) - r²/2σ² of the distance r to its centre, so the slopes of
// ln f at p_W and kSecantStep_m further toward the threat give σ² and r, and the contour's radius R follows from
// f(p_W) / f_r: the distance r - R is then exact. Where several clusters overlap the fit is kept between the linear
// estimate ln(f_r / f) / |grad ln f| and the other bound that holds for one Gaussian.
double clearance_to_restricted(const ThreatField& field, const Eigen::Vector2d& p_W, const mapping::PtemThreat& threat,
                               double f_r) {
  constexpr double kSecantStep_m = 0.05;
  const double slope = threat.gradient_W.norm() / threat.value;  // |grad ln f|, 1/m
  const double log_ratio = std::log(f_r / threat.value);         // > 0 outside the region
  const double linear_m = log_ratio / slope;
  const Eigen::Vector2d toward = threat.gradient_W / threat.gradient_W.norm();
  const mapping::PtemThreat ahead = field.threat_and_gradient(p_W + kSecantStep_m * toward);
  if (!(ahead.value > 0.0) || !std::isfinite(ahead.value) || !ahead.gradient_W.allFinite()) return linear_m;
  const double slope_ahead = ahead.gradient_W.dot(toward) / ahead.value;
  if (!(slope > slope_ahead)) return linear_m;
  const double sigma_sq = kSecantStep_m / (slope - slope_ahead);
  const double r_m = slope * sigma_sq;
  const double contour_sq = r_m * r_m - 2.0 * sigma_sq * log_ratio;
  const double fitted_m = r_m - std::sqrt(std::max(0.0, contour_sq));
  if (!std::isfinite(fitted_m)) return linear_m;
  // One Gaussian: the true distance is linear_m * 2r / (r + R), in [linear_m, 2 linear_m) outside, (linear_m, 0]
  // inside.
  return linear_m >= 0.0 ? std::clamp(fitted_m, linear_m, 2.0 * linear_m) : std::clamp(fitted_m, linear_m, 0.0);
}

ThreatView view_threat(const ThreatField& field, const Eigen::Vector2d& p_W, double yaw_rad, double body_radius_m) {
  ThreatView view;
  const std::optional<double> f_r = field.restricted_threshold();
  const mapping::PtemThreat threat = field.threat_and_gradient(p_W);
  view.value = threat.value;
  if (!f_r.has_value() || !(*f_r > 0.0) || !std::isfinite(threat.value) || threat.value <= 0.0) return view;
  const double gradient_norm = threat.gradient_W.norm();
  view.inside = threat.value >= *f_r;
  if (!(gradient_norm > 0.0) || !std::isfinite(gradient_norm)) {
    // A flat spot: outside, nothing to avoid; inside (a cluster's very centre), drive on to get out.
    if (view.inside) {
      view.present = true;
      view.clearance_m = -body_radius_m;
      view.away_rad = yaw_rad;
    }
    return view;
  }
  view.present = true;
  view.away_rad = std::atan2(-threat.gradient_W.y(), -threat.gradient_W.x());
  view.clearance_m = clearance_to_restricted(field, p_W, threat, *f_r) - body_radius_m;
  return view;
}

}  // namespace

void PtemGuidanceParams::validate() const {
  require_positive("target_speed_mps", target_speed_mps);
  require_positive("max_speed_mps", max_speed_mps);
  require(max_speed_mps >= target_speed_mps, "max_speed_mps", "must be at least target_speed_mps", max_speed_mps);
  require_positive("max_turn_rate_radps", max_turn_rate_radps);
  require_positive("heading_gain_per_s", heading_gain_per_s);
  require_non_negative("speed_gain_per_s", speed_gain_per_s);
  require_positive("proximity_radius_m", proximity_radius_m);
  require_positive("arrival_tolerance_m", arrival_tolerance_m);
  require(std::isfinite(max_target_lead_m) && max_target_lead_m >= proximity_radius_m, "max_target_lead_m",
          "must be finite and at least proximity_radius_m", max_target_lead_m);
  require_non_negative("body_radius_m", body_radius_m);
  require_positive("avoidance_distance_m", avoidance_distance_m);
  require(std::isfinite(safety_margin_m) && safety_margin_m >= 0.0 && safety_margin_m <= avoidance_distance_m,
          "safety_margin_m", "must be in [0, avoidance_distance_m] metres", safety_margin_m);
  require(std::isfinite(escape_half_angle_rad) && escape_half_angle_rad >= 0.0 && escape_half_angle_rad <= kPi / 2.0,
          "escape_half_angle_rad", "must be in [0, pi/2] radians", escape_half_angle_rad);
  require_positive("speed_horizon_s", speed_horizon_s);
  require(std::isfinite(side_hysteresis_rad) && side_hysteresis_rad >= 0.0 && side_hysteresis_rad <= kPi / 2.0,
          "side_hysteresis_rad", "must be in [0, pi/2] radians", side_hysteresis_rad);
}

PtemGuidance::PtemGuidance(const PtemGuidanceParams& params, std::vector<Eigen::Vector2d> waypoints_W)
    : params_(params), waypoints_W_(std::move(waypoints_W)) {
  params_.validate();
  if (waypoints_W_.empty()) throw std::invalid_argument("waypoints must not be empty");
  for (std::size_t i = 0; i < waypoints_W_.size(); ++i) {
    if (!waypoints_W_[i].allFinite()) {
      throw std::invalid_argument("waypoints[" + std::to_string(i) + "] must be finite");
    }
  }
}

void PtemGuidance::advance_target(const Eigen::Vector2d& p_W, double dt_s, PtemGuidanceDecision& decision) {
  double time_left_s = dt_s;
  decision.target_waiting = false;
  // Each pass either stops or moves the target onto, or off, a waypoint: at most two passes per waypoint.
  for (std::size_t pass = 0; pass <= 2 * waypoints_W_.size() + 1; ++pass) {
    const Eigen::Vector2d& waypoint_W = waypoints_W_[waypoint_index_];
    if (at_waypoint_) {
      const double vehicle_to_waypoint_m = (p_W - waypoint_W).norm();
      if (waypoint_index_ + 1 == waypoints_W_.size()) {
        reached_ = vehicle_to_waypoint_m <= params_.arrival_tolerance_m;
        decision.target_waiting = true;
        return;
      }
      if (vehicle_to_waypoint_m > params_.proximity_radius_m) {
        decision.target_waiting = true;
        return;
      }
      ++waypoint_index_;
      at_waypoint_ = false;
      continue;
    }
    if ((target_W_ - p_W).norm() > params_.max_target_lead_m) {
      decision.target_waiting = true;
      return;
    }
    const Eigen::Vector2d to_waypoint = waypoints_W_[waypoint_index_] - target_W_;
    const double leg_left_m = to_waypoint.norm();
    const double step_m = params_.target_speed_mps * time_left_s;
    if (step_m >= leg_left_m) {
      target_W_ = waypoints_W_[waypoint_index_];
      time_left_s -= leg_left_m / params_.target_speed_mps;
      at_waypoint_ = true;
      continue;
    }
    target_W_ += to_waypoint * (step_m / leg_left_m);
    return;
  }
}

PtemGuidanceDecision PtemGuidance::decide(const Pose2& pose, double time_s, const mapping::PtemSnapshot& snapshot) {
  return decide(pose, time_s, PtemSnapshotField(snapshot));
}

PtemGuidanceDecision PtemGuidance::decide(const Pose2& pose, double time_s, const ThreatField& field) {
  require(std::isfinite(pose.x), "pose.x", "must be finite", pose.x);
  require(std::isfinite(pose.y), "pose.y", "must be finite", pose.y);
  require(std::isfinite(pose.theta), "pose.theta", "must be finite", pose.theta);
  require(std::isfinite(time_s), "time_s", "must be finite", time_s);
  if (started_) require(time_s >= last_time_s_, "time_s", "must not go backwards", time_s);

  const Eigen::Vector2d p_W(pose.x, pose.y);
  if (!started_) {
    started_ = true;
    target_W_ = p_W;
    last_time_s_ = time_s;
  }
  const double dt_s = time_s - last_time_s_;
  last_time_s_ = time_s;

  PtemGuidanceDecision decision;
  if (!reached_) advance_target(p_W, dt_s, decision);
  decision.waypoint_index = waypoint_index_;
  decision.target_W = target_W_;
  decision.target_distance_m = (target_W_ - p_W).norm();
  decision.target_waiting = decision.target_waiting || reached_;

  const ThreatView threat = view_threat(field, p_W, pose.theta, params_.body_radius_m);
  decision.threat = threat.value;
  decision.clearance_m = threat.clearance_m;

  if (reached_) {
    avoid_side_ = 0;
    decision.state = BehaviourState::kReached;
    decision.stop = true;
    decision.reached = true;
    decision.desired_heading_rad = wrap_angle(pose.theta);
    decision.commanded_heading_rad = decision.desired_heading_rad;
    return decision;
  }

  // Objective 2: keep the target within the proximity circle. A moving target is followed at the circle's radius; a
  // standing one is approached (it moves on, or the last waypoint is reached, once the vehicle is close).
  const Eigen::Vector2d to_target = target_W_ - p_W;
  const double distance_m = decision.target_distance_m;
  decision.desired_heading_rad = distance_m > 1e-9 ? std::atan2(to_target.y(), to_target.x()) : wrap_angle(pose.theta);
  if (decision.target_waiting) {
    decision.desired_speed_mps = std::min(params_.max_speed_mps, params_.speed_gain_per_s * distance_m);
  } else {
    decision.desired_speed_mps =
        std::clamp(params_.target_speed_mps + params_.speed_gain_per_s * (distance_m - params_.proximity_radius_m), 0.0,
                   params_.max_speed_mps);
  }

  // Objective 1: the admissible headings. Near the restricted region only headings along which the threat does not
  // rise (within pi/2 of its steepest descent); closer than safety_margin_m the range narrows toward the escape cone,
  // which pushes the vehicle back out instead of letting it creep along a contour into the region.
  double commanded_rad = decision.desired_heading_rad;
  bool heading_limited = false;
  const bool constrained = threat.present && (threat.inside || threat.clearance_m <= params_.avoidance_distance_m);
  if (constrained) {
    double half_width_rad = kPi / 2.0;
    if (threat.inside || threat.clearance_m <= 0.0) {
      half_width_rad = params_.escape_half_angle_rad;
    } else if (threat.clearance_m < params_.safety_margin_m) {
      half_width_rad = params_.escape_half_angle_rad +
                       (kPi / 2.0 - params_.escape_half_angle_rad) * threat.clearance_m / params_.safety_margin_m;
    }
    decision.heading_constrained = true;
    decision.admissible_centre_rad = threat.away_rad;
    decision.admissible_half_width_rad = half_width_rad;
    const double offset_rad = wrap_angle(decision.desired_heading_rad - threat.away_rad);
    if (std::abs(offset_rad) > half_width_rad) {
      int side = offset_rad >= 0.0 ? 1 : -1;
      const bool nearly_into_threat = std::abs(offset_rad) > kPi - params_.side_hysteresis_rad;
      if (avoid_side_ != 0 && side != avoid_side_ && nearly_into_threat) {
        side = avoid_side_;
      } else if (avoid_side_ == 0 && nearly_into_threat) {
        // Objective 3 decides a fresh near-tie: pass on the side where the threat a little ahead is lower, else on
        // the side the vehicle already faces.
        const double probe_m = params_.avoidance_distance_m + params_.body_radius_m;
        const double left = field.threat_and_gradient(p_W + probe_m * unit(threat.away_rad + half_width_rad)).value;
        const double right = field.threat_and_gradient(p_W + probe_m * unit(threat.away_rad - half_width_rad)).value;
        if (left < right) {
          side = 1;
        } else if (right < left) {
          side = -1;
        } else {
          side = wrap_angle(pose.theta - threat.away_rad) >= 0.0 ? 1 : -1;
        }
      }
      avoid_side_ = side;
      heading_limited = true;
      commanded_rad = wrap_angle(threat.away_rad + side * half_width_rad);
    }
  } else {
    avoid_side_ = 0;
  }
  decision.commanded_heading_rad = commanded_rad;

  // Speed: along the current heading the body must not reach the restricted region within speed_horizon_s.
  double max_speed_mps = params_.max_speed_mps;
  if (threat.present) {
    const double approach = -std::cos(pose.theta - threat.away_rad);  // cos of the angle to the gradient
    if (approach > 0.0) {
      max_speed_mps = threat.clearance_m <= 0.0
                          ? 0.0
                          : std::min(max_speed_mps, threat.clearance_m / (params_.speed_horizon_s * approach));
    }
  }
  decision.max_admissible_speed_mps = max_speed_mps;

  const double heading_error_rad = wrap_angle(commanded_rad - pose.theta);
  decision.angular_radps = std::clamp(params_.heading_gain_per_s * heading_error_rad, -params_.max_turn_rate_radps,
                                      params_.max_turn_rate_radps);
  // Far off the commanded heading the vehicle slows and turns first, so it does not sweep a wide arc.
  const double aligned_speed_mps = decision.desired_speed_mps * std::max(0.0, std::cos(heading_error_rad));
  decision.linear_mps = std::min(aligned_speed_mps, max_speed_mps);

  if (threat.present && (threat.inside || threat.clearance_m <= 0.0)) {
    decision.state = BehaviourState::kEscape;
  } else if (heading_limited || aligned_speed_mps > max_speed_mps) {
    decision.state = BehaviourState::kAvoid;
  } else {
    decision.state = BehaviourState::kTrackTarget;
  }
  return decision;
}

}  // namespace occgeo::service::control
