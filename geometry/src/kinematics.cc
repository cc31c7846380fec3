#include "occgeo/geometry/kinematics.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace occgeo::geometry {
namespace {

// sin(x) / x, continuous through x = 0.
double sinc(double x) {
  if (std::abs(x) < 1e-4) return 1.0 - x * x / 6.0;  // Taylor series; the next term, x^4/120, is below 1e-18.
  return std::sin(x) / x;
}

void require_positive(double value, const char* field, const char* params = "DifferentialDriveParams") {
  if (!(std::isfinite(value) && value > 0.0)) {
    throw std::invalid_argument(std::string(params) + "." + field + " must be positive and finite, got " +
                                std::to_string(value));
  }
}

void require_slip(double value, const char* field) {
  if (!(std::isfinite(value) && value >= 0.0 && value < 1.0)) {
    throw std::invalid_argument(std::string("SkidSteerParams.") + field + " must be in [0, 1), got " +
                                std::to_string(value));
  }
}

// Ground speeds of the two tracks, metres per second: the bracketed terms (1 - s) r omega of eq. 3.2–3.4.
struct TrackGroundSpeeds {
  double left_mps;
  double right_mps;
};

TrackGroundSpeeds ground_speeds(const SprocketRates& rates, const SkidSteerParams& params) {
  return {(1.0 - params.left_slip) * params.left_sprocket_radius_m * rates.left_radps,
          (1.0 - params.right_slip) * params.right_sprocket_radius_m * rates.right_radps};
}

BodyVelocity body_from_ground_speeds(const TrackGroundSpeeds& ground, const SkidSteerParams& params) {
  // Eq. 3.2 and 3.3 are this forward speed resolved along cos(theta) and sin(theta); eq. 3.4 is the yaw rate.
  return {(ground.right_mps + ground.left_mps) / 2.0, (ground.right_mps - ground.left_mps) / params.track_separation_m};
}

TrackGroundSpeeds ground_speeds_from_body(const BodyVelocity& body, const SkidSteerParams& params) {
  const double half_difference = body.angular_radps * params.track_separation_m / 2.0;
  return {body.linear_mps - half_difference, body.linear_mps + half_difference};
}

}  // namespace

void validate(const DifferentialDriveParams& params) {
  require_positive(params.wheel_separation_m, "wheel_separation_m");
  require_positive(params.wheel_radius_m, "wheel_radius_m");
  require_positive(params.max_wheel_speed_mps, "max_wheel_speed_mps");
}

BodyVelocity to_body(const WheelSpeeds& wheels, const DifferentialDriveParams& params) {
  return {(wheels.right_mps + wheels.left_mps) / 2.0, (wheels.right_mps - wheels.left_mps) / params.wheel_separation_m};
}

WheelSpeeds to_wheels(const BodyVelocity& body, const DifferentialDriveParams& params) {
  const double half_difference = body.angular_radps * params.wheel_separation_m / 2.0;
  return {body.linear_mps - half_difference, body.linear_mps + half_difference};
}

WheelSpeeds clamp_to_max_speed(const WheelSpeeds& wheels, const DifferentialDriveParams& params) {
  const double fastest = std::max(std::abs(wheels.left_mps), std::abs(wheels.right_mps));
  if (fastest <= params.max_wheel_speed_mps) return wheels;
  const double scale = params.max_wheel_speed_mps / fastest;
  return {wheels.left_mps * scale, wheels.right_mps * scale};
}

void validate(const SkidSteerParams& params) {
  require_positive(params.track_separation_m, "track_separation_m", "SkidSteerParams");
  require_positive(params.left_sprocket_radius_m, "left_sprocket_radius_m", "SkidSteerParams");
  require_positive(params.right_sprocket_radius_m, "right_sprocket_radius_m", "SkidSteerParams");
  require_slip(params.left_slip, "left_slip");
  require_slip(params.right_slip, "right_slip");
  require_positive(params.max_track_speed_mps, "max_track_speed_mps", "SkidSteerParams");
}

SkidSteerParams ugv_skid_steer_params() {
  constexpr double kMetresPerInch = 0.0254;
  SkidSteerParams params;
  // Seed 004 §3.3.2 defines b as the "diagonal width of the vehicle" without a value; §3.1 gives the platform as
  // 27 in x 15 in, so b is taken as that footprint's diagonal, sqrt(27^2 + 15^2) in = 30.89 in = 0.7845 m.
  params.track_separation_m = std::hypot(27.0 * kMetresPerInch, 15.0 * kMetresPerInch);
  // The thesis gives no sprocket radius (eq. 3.1's rNominal has no value): 2.5 in = 0.0635 m is a documented
  // placeholder of plausible size for a 27 in tracked platform, to be calibrated on the vehicle.
  params.left_sprocket_radius_m = 2.5 * kMetresPerInch;
  params.right_sprocket_radius_m = 2.5 * kMetresPerInch;
  // The thesis gives no values for s_l and s_r (it only notes that slippage corrupts dead reckoning, §5): no slip.
  params.left_slip = 0.0;
  params.right_slip = 0.0;
  // The thesis gives no top speed (its only speeds are the obstacles' 0.1 and 0.2 m/s, §6): 1 m/s is a default.
  params.max_track_speed_mps = 1.0;
  return params;
}

PoseRate pose_rate(const Pose2& X_WB, const SprocketRates& rates, const SkidSteerParams& params) {
  const TrackGroundSpeeds ground = ground_speeds(rates, params);
  const double sum = ground.right_mps + ground.left_mps;
  return {sum * std::cos(X_WB.theta) / 2.0,                                   // Eq. 3.2.
          sum * std::sin(X_WB.theta) / 2.0,                                   // Eq. 3.3.
          (ground.right_mps - ground.left_mps) / params.track_separation_m};  // Eq. 3.4.
}

BodyVelocity to_body(const SprocketRates& rates, const SkidSteerParams& params) {
  return body_from_ground_speeds(ground_speeds(rates, params), params);
}

SprocketRates to_sprocket_rates(const BodyVelocity& body, const SkidSteerParams& params) {
  const TrackGroundSpeeds ground = ground_speeds_from_body(body, params);
  return {ground.left_mps / ((1.0 - params.left_slip) * params.left_sprocket_radius_m),
          ground.right_mps / ((1.0 - params.right_slip) * params.right_sprocket_radius_m)};
}

BodyVelocity to_body(const WheelSpeeds& track_rim_speeds, const SkidSteerParams& params) {
  return body_from_ground_speeds(
      {(1.0 - params.left_slip) * track_rim_speeds.left_mps, (1.0 - params.right_slip) * track_rim_speeds.right_mps},
      params);
}

WheelSpeeds to_wheels(const BodyVelocity& body, const SkidSteerParams& params) {
  const TrackGroundSpeeds ground = ground_speeds_from_body(body, params);
  return {ground.left_mps / (1.0 - params.left_slip), ground.right_mps / (1.0 - params.right_slip)};
}

WheelSpeeds clamp_to_max_speed(const WheelSpeeds& track_rim_speeds, const SkidSteerParams& params) {
  const double fastest = std::max(std::abs(track_rim_speeds.left_mps), std::abs(track_rim_speeds.right_mps));
  if (fastest <= params.max_track_speed_mps) return track_rim_speeds;
  const double scale = params.max_track_speed_mps / fastest;
  return {track_rim_speeds.left_mps * scale, track_rim_speeds.right_mps * scale};
}

Pose2 integrate(const Pose2& X_WB, const BodyVelocity& v, double dt_s) {
  // The chord of an arc turning by dtheta has length v*dt*sinc(dtheta/2) and points halfway through the turn; this
  // form is exact for every yaw rate and needs no special case for straight lines.
  const double dtheta = v.angular_radps * dt_s;
  const double chord = v.linear_mps * dt_s * sinc(dtheta / 2.0);
  const double chord_heading = X_WB.theta + dtheta / 2.0;
  return {X_WB.x + chord * std::cos(chord_heading), X_WB.y + chord * std::sin(chord_heading),
          wrap_angle(X_WB.theta + dtheta)};
}

}  // namespace occgeo::geometry
