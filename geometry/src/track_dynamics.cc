#include "occgeo/geometry/track_dynamics.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace occgeo::geometry {

FirstOrderLag::FirstOrderLag(double time_constant_s, double initial)
    : time_constant_s_(time_constant_s), value_(initial) {
  if (!std::isfinite(time_constant_s) || time_constant_s < 0.0) {
    throw std::invalid_argument("FirstOrderLag: time constant must be finite and >= 0 s, got " +
                                std::to_string(time_constant_s));
  }
  if (!std::isfinite(initial)) throw std::invalid_argument("FirstOrderLag: initial value must be finite");
}

double FirstOrderLag::step(double input, double dt_s) {
  if (time_constant_s_ == 0.0) {
    value_ = input;
    return value_;
  }
  // Exact solution over the step for a constant input: y(t + dt) = u + (y(t) - u) exp(-dt / tau).
  value_ = input + (value_ - input) * std::exp(-dt_s / time_constant_s_);
  return value_;
}

WheelSpeeds TrackDynamics::step(const WheelSpeeds& commanded, double dt_s) {
  return {left_.step(commanded.left_mps, dt_s), right_.step(commanded.right_mps, dt_s)};
}

}  // namespace occgeo::geometry
