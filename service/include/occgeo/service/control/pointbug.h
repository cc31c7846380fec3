#pragma once

#include <numbers>
#include <optional>
#include <span>
#include <string_view>

#include "occgeo/geometry/pose.h"
#include "occgeo/service/control/behaviour_state.h"

// The modified PointBug go-to-goal behaviour of seed 003 (§2.2, §4.1–4.4 and its Propeller C listing) for an
// ActivityBot with a servo-swept single-beam LIDAR: step toward the goal; on an obstacle within 30 cm sweep both
// sides for a sudden point (a range increase of more than 200 mm between consecutive 1 degree readings) followed by
// a 30 degree gap, add the robot-size corrections (+15 degrees, +120 mm), take the side with the smaller angle, drive
// to the corrected point and re-aim at the goal.
namespace occgeo::service::control {

// Poses are geometry's (x, y in metres, theta in radians counter-clockwise from +x; world frame here).
using geometry::Pose2;

// One single-beam reading of the swept sensor: the servo angle from straight ahead (radians, counter-clockwise
// positive, so left is positive and the seed's right side is negative) and the range (metres, +inf = no return).
struct SweepReading {
  double angle_rad = 0.0;
  double range_m = 0.0;
};

// One sweep in any order; readings are looked up at whole degrees (the seed's 10-tenth servo steps).
struct Sweep {
  std::span<const SweepReading> readings;
  double range_max_m = 0.0;  // readings at or beyond this mean no return, metres
};

// Tuning of PointBug; defaults are the seed's values in SI units unless marked as an assumption.
struct PointBugParams {
  double obstacle_range_m = 0.30;           // a forward reading at or below this stops the approach (§4.2, dis > 300)
  double sudden_jump_m = 0.20;              // a range increase beyond this is a sudden point (listing: (a-a0) > 200)
  double sweep_step_deg = 1.0;              // servo step between readings, degrees (listing: j -= 10 tenths)
  int sweep_limit_deg = 90;                 // each side is swept up to this angle, degrees (listing: j <= 0, k >= 1800)
  int gap_deg = 30;                         // the gap after an edge must stay open this many degrees (§4.2, listing)
  double angle_extension_deg = 15.0;        // ang_ext added to the sudden point's angle, degrees (§4.1.1, listing +15)
  double distance_extension_m = 0.120;      // added to the sudden point's range, metres (§4.1.2, listing a0 + 120)
  double step_m = 3.0 * 3.25e-3;            // one approach step, metres (§4.2: 3 ticks of 3.25 mm)
  double goal_tolerance_m = 3.0 * 3.25e-3;  // reached within one step: the listing stops after floor(d / step) steps
  double heading_tolerance_rad = 0.5 * std::numbers::pi / 180.0;  // turns end within this (assumption)
  double linear_speed_mps = 4.0 * 3.25e-3;  // drive_setMaxSpeed(4) ticks/s times 3.25 mm per tick, m/s
  // In-place turn rate: both wheels at linear_speed_mps on the ActivityBot's 105.8 mm track (664.76 mm = 2 pi track).
  double turn_speed_radps = 2.0 * 4.0 * 3.25e-3 / (664.76e-3 / std::numbers::pi);

  // Throws std::invalid_argument naming the first field that is not finite or out of range.
  void validate() const;
};

enum class SweepSide { kRight, kLeft };

// A sudden point and the corrected target the robot drives to.
struct SuddenPoint {
  SweepSide side = SweepSide::kRight;
  int edge_angle_deg = 0;     // the last reading on the obstacle before the jump, degrees from ahead (unsigned)
  double edge_range_m = 0.0;  // that reading's range, metres
  double turn_deg = 0.0;      // edge_angle_deg + angle_extension_deg, degrees (unsigned; side gives the sign)
  double distance_m = 0.0;    // edge_range_m + distance_extension_m, metres
  double turn_rad = 0.0;      // the signed body turn toward it, radians (right negative)
  double world_x_m = 0.0;     // the corrected point in the world frame, metres (set by the behaviour)
  double world_y_m = 0.0;
};

// The seed's per-side search (listing labels L3/L4 and L5/L6): from 0 degrees outwards, the first reading more
// than sudden_jump_m beyond the previous one marks an edge one degree earlier; readings edge+1 .. edge+gap_deg must
// all stay at least sudden_jump_m beyond the edge's range, else the search resumes after the closer reading. None
// when the side has no such edge before sweep_limit_deg - 1 (the listing's last usable jump is at 88 degrees).
// Unmeasured angles read as range 0 (blocked); gap angles beyond the sweep limit read the limit's reading, as the
// servo stops there. Throws std::invalid_argument naming the Sweep field when the sweep is malformed.
std::optional<SuddenPoint> find_sudden_point(const Sweep& sweep, SweepSide side, const PointBugParams& params);

// The drive_goto-style remainder of the current motion: turn in place, then drive straight.
struct MotionTarget {
  double turn_rad = 0.0;    // counter-clockwise turn still to make, radians
  double distance_m = 0.0;  // straight distance to drive after the turn, metres
};

struct PointBugDecision {
  BehaviourState state = BehaviourState::kAimAtGoal;  // kAimAtGoal, kStepToGoal, kTurnToSuddenPoint,
                                                      // kDriveToSuddenPoint, kReached or kNoPath
  double linear_mps = 0.0;                            // body velocity for a MotionCommand, m/s
  double angular_radps = 0.0;                         // counter-clockwise yaw rate, rad/s
  bool stop = false;                                  // reached or no_path: stand still
  MotionTarget target;                                // the same motion as a drive_goto-style turn and distance
  double goal_distance_m = 0.0;
  std::optional<SuddenPoint> sudden_point;  // the point being driven to, while in the sudden point states
  std::optional<SuddenPoint> right;         // what the last search found on each side (set on the decision
  std::optional<SuddenPoint> left;          // that searched)
};

// The PointBug state machine. decide() is called with the current odometry pose and a sweep each control cycle;
// a server sends linear_mps/angular_radps as a MotionCommand (its only motion message) and may instead execute
// target with a blocking drive_goto, then call again. The sweep needs the reading at 0 degrees in step_to_goal and
// the whole +-90 degree, 1 degree sweep when that reading is inside obstacle_range_m; other states ignore it.
class PointBugBehaviour {
 public:
  enum class State { kAimAtGoal, kStepToGoal, kTurnToSuddenPoint, kDriveToSuddenPoint, kReached, kNoPath };

  // Throws std::invalid_argument naming the bad field of params.
  PointBugBehaviour(const PointBugParams& params, double goal_x_m, double goal_y_m);

  // Throws std::invalid_argument naming the field when the pose or sweep is malformed.
  PointBugDecision decide(const Pose2& pose, const Sweep& sweep);

  State state() const { return state_; }
  const PointBugParams& params() const { return params_; }

 private:
  PointBugParams params_;
  double goal_x_m_;
  double goal_y_m_;
  State state_ = State::kAimAtGoal;
  std::optional<SuddenPoint> target_;  // while in the sudden point states
  double target_yaw_rad_ = 0.0;        // heading toward the sudden point, world frame
};

}  // namespace occgeo::service::control
