#include "occgeo/service/control/servo_sweep.h"

#include <cmath>
#include <limits>

#include "param_checks.h"

namespace occgeo::service::control {

using detail::require;
using detail::require_positive;

void ServoSweepLimits::validate() const {
  require(std::isfinite(servo_min_rad), "servo_min_rad", "must be finite", servo_min_rad);
  require(std::isfinite(servo_max_rad) && servo_max_rad > servo_min_rad, "servo_max_rad",
          "must be finite and above servo_min_rad", servo_max_rad);
  require_positive("servo_step_rad", servo_step_rad);
  require((servo_max_rad - servo_min_rad) / servo_step_rad <= 100000.0, "servo_step_rad",
          "must leave at most 100000 steps across the servo's travel", servo_step_rad);
  require_positive("range_max_m", range_max_m);
}

ServoSweepAssembler::ServoSweepAssembler(const ServoSweepLimits& limits) : limits_(limits) {
  limits_.validate();
  slots_ =
      static_cast<std::size_t>(std::llround((limits_.servo_max_rad - limits_.servo_min_rad) / limits_.servo_step_rad)) +
      1;
  current_.assign(slots_, std::nullopt);
}

std::size_t ServoSweepAssembler::slot_of(double servo_angle_rad) const {
  const double steps = std::round((servo_angle_rad - limits_.servo_min_rad) / limits_.servo_step_rad);
  if (steps <= 0.0) return 0;
  return std::min(static_cast<std::size_t>(steps), slots_ - 1);
}

bool ServoSweepAssembler::add(double servo_angle_rad, double range_m, double stamp_s) {
  const double half_step = 0.5 * limits_.servo_step_rad;
  require(std::isfinite(servo_angle_rad) && servo_angle_rad >= limits_.servo_min_rad - half_step &&
              servo_angle_rad <= limits_.servo_max_rad + half_step,
          "ServoRange.servo_angle_rad", "must lie within the servo's travel", servo_angle_rad);
  require(!std::isnan(range_m) && range_m >= 0.0, "ServoRange.range_m", "must be non-negative", range_m);
  const double range = range_m >= limits_.range_max_m ? std::numeric_limits<double>::infinity() : range_m;
  if (!current_started_s_) current_started_s_ = stamp_s;
  current_[slot_of(servo_angle_rad)] = range;
  covered_min_ = covered_min_ || servo_angle_rad <= limits_.servo_min_rad + half_step;
  covered_max_ = covered_max_ || servo_angle_rad >= limits_.servo_max_rad - half_step;
  if (!(covered_min_ && covered_max_)) return false;
  last_sweep_.clear();
  for (std::size_t i = 0; i < slots_; ++i) {
    if (!current_[i]) continue;
    last_sweep_.push_back({limits_.servo_min_rad + static_cast<double>(i) * limits_.servo_step_rad, *current_[i]});
  }
  last_sweep_started_s_ = *current_started_s_;
  ++sweeps_;
  // The end this reading reached begins the next sweep, which runs back to the other end.
  restart();
  current_started_s_ = stamp_s;
  current_[slot_of(servo_angle_rad)] = range;
  covered_min_ = servo_angle_rad <= limits_.servo_min_rad + half_step;
  covered_max_ = servo_angle_rad >= limits_.servo_max_rad - half_step;
  return true;
}

void ServoSweepAssembler::restart() {
  current_.assign(slots_, std::nullopt);
  current_started_s_.reset();
  covered_min_ = false;
  covered_max_ = false;
}

}  // namespace occgeo::service::control
