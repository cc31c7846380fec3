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

void require_positive(double value, const char* field) {
  if (!(std::isfinite(value) && value > 0.0)) {
    throw std::invalid_argument(std::string("DifferentialDriveParams.") + field + " must be positive and finite, got " +
                                std::to_string(value));
  }
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
