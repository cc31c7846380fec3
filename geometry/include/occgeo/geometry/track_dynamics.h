#pragma once

#include "occgeo/geometry/kinematics.h"

namespace occgeo::geometry {

// A first-order lag dy/dt = (u - y) / tau: the response of a powertrain whose speed follows its command with time
// constant tau (63% of a step after tau). Stepped exactly for an input held constant over each step, so the result
// does not depend on the step length.
class FirstOrderLag {
 public:
  // time_constant_s = 0 follows the input at once. Throws std::invalid_argument naming the time constant unless it is
  // finite and non-negative, or naming the initial value unless it is finite.
  explicit FirstOrderLag(double time_constant_s, double initial = 0.0);

  // Holds input for dt_s seconds (dt_s >= 0) and returns the new output.
  double step(double input, double dt_s);

  [[nodiscard]] double value() const { return value_; }
  [[nodiscard]] double time_constant_s() const { return time_constant_s_; }
  // Sets the output to value, e.g. to stop at once.
  void reset(double value) { value_ = value; }

 private:
  double time_constant_s_;
  double value_;
};

// The rim speeds r*omega of a tracked base's two tracks, each following its commanded rim speed through the same
// first-order powertrain lag (seed 004 §3.3.1 models the motors in Simulink; the lag is the simplest such model).
class TrackDynamics {
 public:
  explicit TrackDynamics(double time_constant_s) : left_(time_constant_s), right_(time_constant_s) {}

  // Holds the commanded rim speeds (m/s) for dt_s seconds and returns the rim speeds reached.
  WheelSpeeds step(const WheelSpeeds& commanded, double dt_s);

  // Current rim speeds, m/s.
  [[nodiscard]] WheelSpeeds speeds() const { return {left_.value(), right_.value()}; }
  // Stops both tracks at once.
  void stop() {
    left_.reset(0.0);
    right_.reset(0.0);
  }

 private:
  FirstOrderLag left_;
  FirstOrderLag right_;
};

}  // namespace occgeo::geometry
