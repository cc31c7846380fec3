#pragma once

#include <array>
#include <optional>
#include <span>
#include <string_view>
#include "occgeo/service/control/behaviour_state.h"

// The Bearcat III obstacle-avoidance behaviour (seed 000 §4.2–4.3 and its appendix source): a frontal rectangle
// split into right, middle and left zones, the ob_factor case table, the open-gap finder and steerCAR.
namespace occgeo::service::control {

// One planar laser sweep in its sensor frame (x forward, y left); beam i has bearing
// angle_min_rad + i * angle_increment_rad, counter-clockwise positive; ranges >= range_max_m mean no return.
struct ScanView {
  double angle_min_rad = 0.0;        // bearing of the first beam, radians
  double angle_increment_rad = 0.0;  // bearing step between beams, radians, must be positive
  std::span<const float> ranges_m;   // one range per beam, metres, non-negative (+inf means no return)
  double range_max_m = 0.0;          // readings at or beyond this mean no return, metres
};

// Tuning of the Bearcat behaviour; the defaults are the thesis's values converted to SI units.
struct BearcatParams {
  double zone_width_m = 1.6;                             // lateral size of the frontal rectangle, metres
  double zone_depth_m = 1.98;                            // forward size of the frontal rectangle, metres
  double gap_range_m = 3.0;                              // beams at least this long are open, metres (RADIAL)
  double gap_min_width_m = 1.6;                          // narrower openings are not gaps, metres
  double straight_deadband_deg = 5.0;                    // smaller steers drive straight, degrees
  double base_speed_mps = 0.5;                           // wheel speed when driving straight, m/s
  double speed_per_degree_mps = 0.5 * 134.5 / 15000.0;   // wheel speed difference per steer degree, m/s
  double max_wheel_speed_mps = 0.5 * 36000.0 / 15000.0;  // wheel speeds are clamped to +-this, m/s
  double wheel_separation_m = 0.7;                       // distance between the drive wheels, metres
  double turn_small_deg = 10.0;                          // steer away from a right-zone obstacle, degrees
  double turn_large_deg = 15.0;                          // steer away from larger blockages, degrees

  // Throws std::invalid_argument naming the first field that is not finite or out of range.
  void validate() const;
};

// One beam of the scan: its bearing (radians, CCW from x) and its range (metres).
struct BeamReading {
  double bearing_rad = 0.0;
  double range_m = 0.0;
};

// What one zone saw: the thesis's ob_right, ob_left and ob_near with their distances; readings are zero when
// obstacle_present is false.
struct ZoneObservation {
  bool obstacle_present = false;  // some beam of the zone ends inside the frontal rectangle
  BeamReading ob_right;           // first obstacle beam sweeping counter-clockwise from the zone's right edge
  BeamReading ob_left;            // last obstacle beam of that sweep
  BeamReading ob_near;            // obstacle beam with the smallest range (the first of equals)
};

// An opening between obstacles, bounded by two beam endpoints; bearings in radians, CCW from x.
struct Gap {
  double right_edge_bearing_rad = 0.0;  // bearing of the right boundary beam
  double left_edge_bearing_rad = 0.0;   // bearing of the left boundary beam
  double center_bearing_rad = 0.0;      // mean of the two edge bearings, where the robot steers
  double width_m = 0.0;                 // chord between the two boundary beams' endpoints, metres
};

// Differential wheel speeds and the equivalent body velocity for one steer angle.
struct WheelCommand {
  double left_wheel_mps = 0.0;   // left wheel surface speed, m/s
  double right_wheel_mps = 0.0;  // right wheel surface speed, m/s
  double linear_mps = 0.0;       // forward speed of the robot, m/s
  double angular_radps = 0.0;    // counter-clockwise yaw rate, rad/s
};

// Everything one Bearcat decision found and commands; zones are ordered right (1), middle (2), left (3).
struct BearcatDecision {
  int ob_factor = 0;                              // ob_factor * 10 + zone over the zones with obstacles, e.g. 12
  std::array<ZoneObservation, 3> zones;           // right, middle, left
  std::optional<Gap> widest_gap;                  // widest open gap of at least gap_min_width_m, if any
  double steer_deg = 0.0;                         // commanded steer, degrees, positive turns left
  double left_wheel_mps = 0.0;                    // left wheel speed, m/s
  double right_wheel_mps = 0.0;                   // right wheel speed, m/s
  double linear_mps = 0.0;                        // forward speed of the robot, m/s
  double angular_radps = 0.0;                     // counter-clockwise yaw rate, rad/s
  bool stop = false;                              // the robot must stand still (deadlock)
  BehaviourState state = BehaviourState::kClear;  // kClear, kAvoidRightObstacle, kAvoidLeftObstacle,
                                                  // kSteerGap, kNoGap, kPassBetween or kDeadlock
};

// The thesis's steerCAR: wheel speeds for a steer angle in degrees (positive turns left); params must be valid.
WheelCommand wheel_command_for_steer(double steer_deg, const BearcatParams& params);

// One Bearcat decision for a scan; params must be valid; throws std::invalid_argument naming the ScanView field
// when the scan is malformed or has no beam within +-90 degrees of straight ahead.
BearcatDecision decide(const ScanView& scan, const BearcatParams& params);

// The Bearcat behaviour with its validated params, held by the server per robot.
class BearcatBehaviour {
 public:
  // Throws std::invalid_argument naming the bad field of params.
  explicit BearcatBehaviour(const BearcatParams& params);

  // One decision for a scan; throws std::invalid_argument when the scan is malformed.
  BearcatDecision decide(const ScanView& scan) const;

  // The params this behaviour decides with.
  const BearcatParams& params() const { return params_; }

 private:
  BearcatParams params_;
};

}  // namespace occgeo::service::control
