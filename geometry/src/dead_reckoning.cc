#include "occgeo/geometry/dead_reckoning.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace occgeo::geometry {
namespace {

void require_positive(double value, const char* field) {
  if (!(std::isfinite(value) && value > 0.0)) {
    throw std::invalid_argument(std::string("EncoderParams.") + field + " must be positive and finite, got " +
                                std::to_string(value));
  }
}

// Seed 003 §3.2.3 (line 722) and §3.4 (line 869): "Each encoder tick makes the wheel travel 3.25 mm", 64 ticks per
// wheel turn.
constexpr double kActivityBotMetresPerTick = 3.25e-3;
constexpr double kActivityBotTicksPerRevolution = 64.0;
// Seed 003 §3.4.2 (line 896): pivoting about a held wheel, the other wheel runs on a circle of "turning radius (R)
// = 105.8 mm", i.e. the wheel separation, whose circumference 2 pi R is the thesis's 664.76 mm. (The 5 cm "distance
// between the wheel axle center" S of §3.5, line 945, is a different quantity and is not used here.)
constexpr double kActivityBotWheelSeparationM = 0.1058;

// The largest tick count abdrive's drive_goto(int, int) accepts: the Propeller's int is 32 bits.
constexpr double kDriveGotoMaxTicks = static_cast<double>(std::numeric_limits<std::int32_t>::max());

std::int64_t checked_ticks(double ticks, double input, const char* what) {
  if (!std::isfinite(input)) {
    throw std::invalid_argument(std::string(what) + " must be finite, got " + std::to_string(input));
  }
  const double rounded = std::round(ticks);
  if (std::abs(rounded) > kDriveGotoMaxTicks) {
    throw std::invalid_argument(std::string(what) + " " + std::to_string(input) +
                                " needs more ticks than drive_goto's 32-bit int holds");
  }
  return static_cast<std::int64_t>(rounded);
}

}  // namespace

void validate(const EncoderParams& params) {
  require_positive(params.ticks_per_revolution, "ticks_per_revolution");
  require_positive(params.wheel_radius_m, "wheel_radius_m");
  require_positive(params.wheel_separation_m, "wheel_separation_m");
  if (params.counter_bits < 1 || params.counter_bits > 64) {
    throw std::invalid_argument("EncoderParams.counter_bits must be in [1, 64], got " +
                                std::to_string(params.counter_bits));
  }
}

double metres_per_tick(const EncoderParams& params) {
  return 2.0 * M_PI * params.wheel_radius_m / params.ticks_per_revolution;
}

EncoderParams activitybot_encoder_params() {
  EncoderParams params;
  params.ticks_per_revolution = kActivityBotTicksPerRevolution;
  // The thesis gives travel per tick, not a radius: 64 x 3.25 mm = 208 mm per turn, radius 208 mm / (2 pi).
  params.wheel_radius_m = kActivityBotTicksPerRevolution * kActivityBotMetresPerTick / (2.0 * M_PI);
  params.wheel_separation_m = kActivityBotWheelSeparationM;
  params.counter_bits = 32;  // abdrive reports ticks as a 32-bit int.
  return params;
}

EncoderParams minesrover_encoder_params() {
  // shared/datasets/urg04lx-mines/SOURCE.txt: "2000 ticks per wheel revolution; wheel radius 77 mm, half axle
  // 165 mm, as used by BreezySLAM for this robot". The log does not state the counter width: 32 bits is the default.
  EncoderParams params;
  params.ticks_per_revolution = 2000.0;
  params.wheel_radius_m = 0.077;
  params.wheel_separation_m = 2.0 * 0.165;
  params.counter_bits = 32;
  return params;
}

EncoderOdometry::EncoderOdometry(const EncoderParams& params, const Pose2& X_WB_initial)
    : params_(params), X_WB_(X_WB_initial) {
  validate(params_);
  metres_per_tick_ = metres_per_tick(params_);
}

std::int64_t EncoderOdometry::tick_delta(std::int64_t previous, std::int64_t current, int counter_bits) {
  // Unsigned arithmetic wraps modulo 2^64 by definition; masking then reduces the difference modulo 2^counter_bits.
  std::uint64_t difference = static_cast<std::uint64_t>(current) - static_cast<std::uint64_t>(previous);
  if (counter_bits >= 64) return static_cast<std::int64_t>(difference);
  const std::uint64_t mask = (std::uint64_t{1} << counter_bits) - 1;
  const std::uint64_t half = std::uint64_t{1} << (counter_bits - 1);
  difference &= mask;
  if (difference < half) return static_cast<std::int64_t>(difference);
  return -static_cast<std::int64_t>(mask - difference + 1);  // At most half, so it fits for counter_bits <= 63.
}

const Pose2& EncoderOdometry::update(const EncoderReading& reading) {
  if (!std::isfinite(reading.time_s)) {
    throw std::invalid_argument("EncoderReading.time_s must be finite, got " + std::to_string(reading.time_s));
  }
  if (!has_reference_) {
    has_reference_ = true;
    last_ = reading;
    velocity_time_s_ = reading.time_s;
    return X_WB_;
  }
  const double left_m =
      static_cast<double>(tick_delta(last_.left_ticks, reading.left_ticks, params_.counter_bits)) * metres_per_tick_;
  const double right_m =
      static_cast<double>(tick_delta(last_.right_ticks, reading.right_ticks, params_.counter_bits)) * metres_per_tick_;
  last_ = reading;

  // Both wheels turned at a constant ratio over the increment, so base_link followed one circular arc: integrating
  // the displacement as a velocity over one unit of time gives that arc's end exactly, whatever the timestamps.
  const double distance_m = (right_m + left_m) / 2.0;
  const double yaw_rad = (right_m - left_m) / params_.wheel_separation_m;
  X_WB_ = integrate(X_WB_, {distance_m, yaw_rad}, 1.0);

  pending_distance_m_ += distance_m;
  pending_yaw_rad_ += yaw_rad;
  if (reading.time_s > velocity_time_s_) {
    const double dt_s = reading.time_s - velocity_time_s_;
    velocity_ = {pending_distance_m_ / dt_s, pending_yaw_rad_ / dt_s};
    pending_distance_m_ = 0.0;
    pending_yaw_rad_ = 0.0;
    velocity_time_s_ = reading.time_s;
  } else if (reading.time_s < velocity_time_s_) {
    // The clock went backwards: keep the velocity and measure the next interval from this reading.
    pending_distance_m_ = 0.0;
    pending_yaw_rad_ = 0.0;
    velocity_time_s_ = reading.time_s;
  }
  return X_WB_;
}

void EncoderOdometry::reset(const Pose2& X_WB) {
  X_WB_ = X_WB;
  velocity_ = {};
  has_reference_ = false;
  last_ = {};
  pending_distance_m_ = 0.0;
  pending_yaw_rad_ = 0.0;
  velocity_time_s_ = 0.0;
}

std::pair<std::int64_t, std::int64_t> drive_goto_ticks_for_distance(double metres) {
  // Seed 003 §3.4 (line 871): "ticks = distance mm / 3.25 mm", the same count for both wheels (§3.4.1, line 880).
  // The thesis's own code truncates to int; rounding to nearest halves the worst-case error to 1.625 mm.
  const std::int64_t ticks = checked_ticks(metres / kActivityBotMetresPerTick, metres, "distance");
  return {ticks, ticks};
}

std::pair<std::int64_t, std::int64_t> drive_goto_ticks_for_turn(double angle_rad) {
  // Seed 003 §3.4.2 (lines 896, 907-916): t = 664.76 * n / 3.25 ticks for n turns, split as drive_goto(-t/2, t/2)
  // for a counter-clockwise turn; 664.76 mm = 2 pi * 105.8 mm, so each wheel rolls angle * 105.8 mm / 2.
  const double half_t = angle_rad * kActivityBotWheelSeparationM / 2.0 / kActivityBotMetresPerTick;
  const std::int64_t ticks = checked_ticks(half_t, angle_rad, "turn angle");
  return {-ticks, ticks};
}

std::pair<std::int64_t, std::int64_t> drive_goto_ticks_for_pivot_turn(double angle_rad) {
  // Seed 003 §3.4.2 (lines 896-905): holding one wheel still, the other rolls t = 664.76 * n / 3.25 ticks for n turns;
  // drive_goto(0, t) turns counter-clockwise and drive_goto(t, 0) clockwise.
  const double t = std::abs(angle_rad) * kActivityBotWheelSeparationM / kActivityBotMetresPerTick;
  const std::int64_t ticks = checked_ticks(t, angle_rad, "turn angle");
  if (angle_rad >= 0.0) return {0, ticks};
  return {ticks, 0};
}

}  // namespace occgeo::geometry
