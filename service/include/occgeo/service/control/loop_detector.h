#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <string_view>

#include "occgeo/service/control/behaviour_state.h"
#include "occgeo/service/control/pointbug.h"

// Detects a behaviour going nowhere from the robot's poses: the endless loops of PointBug (seed 003 Fig 2.10) and of
// PTEM guidance (seed 004 §6.3.2), and plain stalls. A loop is the robot passing the same place, heading the same way,
// for the revisit_count-th time after earlier passes, each after a real excursion (time and path length), without the
// excursion having brought it closer to the goal than it had already been. A stall is no progress toward the goal for
// stall_time_s. Both are latched until reset(), so a caller can start an escape (e.g. a global path) and reset.
namespace occgeo::service::control {

struct LoopDetectorParams {
  double revisit_radius_m = 0.3;        // "the same place": within this of an earlier pose, metres
  double heading_tolerance_rad = 0.6;   // "heading the same way": yaw within this of the earlier pose's, radians
  int revisit_count = 2;                // earlier passes needed to call it a loop (2: the third pass), >= 1
  double min_revisit_interval_s = 4.0;  // an earlier pose counts only this long after it, seconds
  double min_loop_length_m = 1.0;       // ... and after the robot drove at least this far since, metres
  double progress_epsilon_m = 0.1;      // getting closer to the goal by less than this is no progress, metres
  double stall_time_s = 30.0;           // no progress toward the goal for this long is a stall, seconds
  double window_s = 180.0;              // poses older than this are forgotten, seconds
  double sample_spacing_m = 0.05;       // a pose is stored after the robot moved this far or turned heading_tolerance/4
  std::size_t max_samples = 20000;      // stored poses beyond this drop the oldest, >= 2

  // Throws std::invalid_argument naming the first field that is not finite or out of range.
  void validate() const;
};

enum class LoopReason : std::uint8_t { kNone, kLoop, kStall };

struct LoopStatus {
  bool loop = false;                      // a revisit loop was detected (latched)
  bool stalled = false;                   // no progress toward the goal for stall_time_s (latched; needs a goal)
  LoopReason reason = LoopReason::kNone;  // the first detected
  int passes = 0;                         // earlier passes through the current place with the same heading
  double since_progress_s = 0.0;          // time since the goal distance last improved by progress_epsilon_m, seconds
  std::optional<double> best_goal_distance_m;              // closest the robot has come to the goal since reset, metres
  Eigen::Vector2d loop_point_W = Eigen::Vector2d::Zero();  // where the loop was detected, world frame
};

// One observation: the robot's pose at a time, the goal it is heading for if any, and the behaviour's state if any
// (an earlier pose then only matches when it was taken in the same state).
struct LoopObservation {
  Pose2 pose;                                    // world frame
  double time_s = 0.0;                           // seconds, non-decreasing
  std::optional<Eigen::Vector2d> goal_W;         // world frame; a changed goal restarts progress tracking
  BehaviourState state = BehaviourState::kNone;  // e.g. kDriveToSuddenPoint; kNone without a state
};

class LoopDetector {
 public:
  // Throws std::invalid_argument naming the bad field of params.
  explicit LoopDetector(const LoopDetectorParams& params);

  // Adds one observation and returns the status. Throws std::invalid_argument naming the field when the pose, time or
  // goal is not finite or time goes backwards, changing nothing.
  LoopStatus update(const LoopObservation& observation);

  // Forgets the poses and the latched verdicts (e.g. after starting an escape); the goal is kept.
  void reset();

  [[nodiscard]] const LoopStatus& status() const { return status_; }
  [[nodiscard]] const LoopDetectorParams& params() const { return params_; }
  [[nodiscard]] std::size_t sample_count() const { return samples_.size(); }

 private:
  struct Sample {
    Eigen::Vector2d p_W;
    double theta;
    double time_s;
    double path_length_m;         // driven since reset, at this sample
    double best_goal_distance_m;  // best goal distance up to this sample (+inf without a goal)
    BehaviourState state;         // kNone without a state
  };

  int count_passes(const Sample& now) const;

  LoopDetectorParams params_;
  std::deque<Sample> samples_;
  LoopStatus status_;
  std::optional<Eigen::Vector2d> goal_W_;
  std::optional<double> last_time_s_;
  Eigen::Vector2d last_p_W_ = Eigen::Vector2d::Zero();
  double path_length_m_ = 0.0;
  double progress_mark_m_ = 0.0;  // goal distance at the last progress
  double progress_time_s_ = 0.0;  // time of the last progress
};

}  // namespace occgeo::service::control
