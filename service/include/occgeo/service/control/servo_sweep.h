#pragma once

#include <optional>
#include <vector>

#include "occgeo/service/control/pointbug.h"

// Seed 003's LIDAR-Lite sits on a servo and reads one range per 1 degree step; PointBug judges a whole sweep. This
// assembles one robot's readings, as they arrive one at a time, into sweeps.
namespace occgeo::service::control {

// The servo's travel, as its RobotSpec declares it.
struct ServoSweepLimits {
  double servo_min_rad = 0.0;   // smallest servo angle, radians
  double servo_max_rad = 0.0;   // largest servo angle, radians
  double servo_step_rad = 0.0;  // angle between consecutive readings, radians
  double range_max_m = 0.0;     // readings at or beyond this mean no return, metres

  // Throws std::invalid_argument naming the field when the limits are not finite, the range is empty or the step
  // is not positive.
  void validate() const;
};

// A sweep is complete once the servo has covered [servo_min, servo_max] (within half a step at each end) since the
// sweep began, in either direction; the reading that completes it also begins the next one, so a servo going back
// and forth gives one sweep per pass. Within a sweep the newest reading at each angle counts.
class ServoSweepAssembler {
 public:
  // Throws std::invalid_argument naming the bad field of limits.
  explicit ServoSweepAssembler(const ServoSweepLimits& limits);

  // Adds one reading (servo angle, radians; range, metres, at or beyond range_max_m or +inf for no return); true when
  // it completed a sweep, which last_sweep() then holds. Throws std::invalid_argument naming the field when the angle
  // is outside the servo's travel (more than half a step) or the range is negative or NaN.
  bool add(double servo_angle_rad, double range_m, double stamp_s);

  // Drops the sweep in progress: the next complete sweep holds only readings from here on (e.g. once the robot
  // stopped, so that every reading of it was taken from one pose).
  void restart();

  // The latest complete sweep, readings in servo angle order, no return as +inf; empty before the first.
  [[nodiscard]] const std::vector<SweepReading>& last_sweep() const { return last_sweep_; }
  // Stamp of the first reading of the latest complete sweep, seconds.
  [[nodiscard]] double last_sweep_started_s() const { return last_sweep_started_s_; }
  // Complete sweeps so far.
  [[nodiscard]] std::size_t sweeps() const { return sweeps_; }
  [[nodiscard]] const ServoSweepLimits& limits() const { return limits_; }

 private:
  [[nodiscard]] std::size_t slot_of(double servo_angle_rad) const;

  ServoSweepLimits limits_;
  std::size_t slots_ = 0;
  std::vector<std::optional<double>> current_;  // the sweep in progress: newest range per servo step
  std::optional<double> current_started_s_;
  bool covered_min_ = false;
  bool covered_max_ = false;
  std::vector<SweepReading> last_sweep_;
  double last_sweep_started_s_ = 0.0;
  std::size_t sweeps_ = 0;
};

}  // namespace occgeo::service::control
