#pragma once

#include <cstdint>
#include <utility>

#include "occgeo/geometry/kinematics.h"
#include "occgeo/geometry/pose.h"

namespace occgeo::geometry {

// Wheel encoders on a differential-drive base: the geometry that turns tick counts into wheel travel (see validate).
struct EncoderParams {
  double ticks_per_revolution = 0.0;  // Encoder ticks per full turn of a wheel, positive.
  double wheel_radius_m = 0.0;        // Rolling radius of each wheel, metres, positive.
  double wheel_separation_m = 0.0;    // Distance between the wheels' contact points, metres, positive.
  int counter_bits = 32;              // Width of the driver's tick counters in bits, 1 to 64; they wrap modulo 2^bits.
};

// Throws std::invalid_argument naming the first field that is out of range.
void validate(const EncoderParams& params);

// Distance a wheel rolls per encoder tick, metres: 2 pi wheel_radius_m / ticks_per_revolution.
double metres_per_tick(const EncoderParams& params);

// Parallax ActivityBot of seed 003 (§3.2.3, §3.4): 64 ticks per revolution, 3.25 mm per tick, wheels 105.8 mm apart.
EncoderParams activitybot_encoder_params();

// MinesRover of the URG-04LX log (datasets/urg04lx-mines/SOURCE.txt): 2000 ticks per revolution, 0.077 m wheel
// radius, 2 x 0.165 m wheel separation.
EncoderParams minesrover_encoder_params();

// One sample from an encoder driver: cumulative tick counts, positive forwards, and when they were read, seconds.
struct EncoderReading {
  std::int64_t left_ticks = 0;
  std::int64_t right_ticks = 0;
  double time_s = 0.0;
};

// Dead reckoning from cumulative wheel tick counts: each increment between readings is integrated exactly as a
// circular arc, so the pose does not depend on the reading rate when the wheels turn at a constant ratio.
class EncoderOdometry {
 public:
  // Starts at X_WB_initial with no reference reading; throws std::invalid_argument if params are invalid.
  explicit EncoderOdometry(const EncoderParams& params, const Pose2& X_WB_initial = {});

  // Applies one reading and returns the new pose: the first reading only sets the tick reference; later ones move the
  // pose by the increment (counter wrap-around undone) whatever their timestamps, and update velocity() only when
  // time has advanced past the last reading used for it (an earlier timestamp restarts the interval from there).
  // Throws std::invalid_argument for a non-finite time_s.
  const Pose2& update(const EncoderReading& reading);

  // Pose of base_link in the odometry frame, metres and radians.
  [[nodiscard]] const Pose2& pose() const { return X_WB_; }

  // Mean body velocity over the latest interval with increasing timestamps, zero before there is one.
  [[nodiscard]] const BodyVelocity& velocity() const { return velocity_; }

  // True once a first reading has set the tick reference.
  [[nodiscard]] bool has_reference() const { return has_reference_; }

  // Moves the pose to X_WB and forgets the tick reference and velocity, so the next reading only sets a reference.
  void reset(const Pose2& X_WB);

  [[nodiscard]] const EncoderParams& params() const { return params_; }

  // Signed tick increment from previous to current counter value, undoing one wrap of a counter_bits-wide counter:
  // a jump of more than half the counter range is read as a wrap, a jump of exactly half as backwards.
  [[nodiscard]] static std::int64_t tick_delta(std::int64_t previous, std::int64_t current, int counter_bits);

 private:
  EncoderParams params_;
  double metres_per_tick_ = 0.0;
  Pose2 X_WB_;
  BodyVelocity velocity_;
  bool has_reference_ = false;
  EncoderReading last_;
  // Travel accumulated since velocity_time_s_, metres along the path and radians of yaw.
  double pending_distance_m_ = 0.0;
  double pending_yaw_rad_ = 0.0;
  double velocity_time_s_ = 0.0;
};

// The drive_goto(left, right) tick command that drives the ActivityBot straight for this many metres (negative:
// backwards), rounded to the nearest 3.25 mm tick per seed 003 §3.4 ("ticks = distance mm / 3.25 mm"); throws
// std::invalid_argument if metres is not finite or needs more ticks than drive_goto's int holds.
std::pair<std::int64_t, std::int64_t> drive_goto_ticks_for_distance(double metres);

// The drive_goto(left, right) command that turns the ActivityBot in place by angle_rad, counter-clockwise positive:
// per seed 003 §3.4.2, t = 664.76 mm * turns / 3.25 mm and the wheels get (-t/2, t/2), rounded to whole ticks;
// throws std::invalid_argument if angle_rad is not finite or too large for drive_goto's int.
std::pair<std::int64_t, std::int64_t> drive_goto_ticks_for_turn(double angle_rad);

// The drive_goto(left, right) command that turns the ActivityBot by angle_rad about one held wheel (seed 003 §3.4.2,
// fig. 3.13): counter-clockwise turns move only the right wheel, t = 664.76 mm * turns / 3.25 mm ticks, and
// clockwise turns only the left wheel; throws std::invalid_argument as drive_goto_ticks_for_turn does.
std::pair<std::int64_t, std::int64_t> drive_goto_ticks_for_pivot_turn(double angle_rad);

}  // namespace occgeo::geometry
