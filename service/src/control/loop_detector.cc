#include "occgeo/service/control/loop_detector.h"
#include "occgeo/geometry/pose.h"

#include <cmath>
#include <functional>
#include <limits>
#include <numbers>

#include "param_checks.h"

namespace occgeo::service::control {
namespace {

using detail::require;
using detail::require_non_negative;
using detail::require_positive;

constexpr double kInfinity = std::numeric_limits<double>::infinity();

using geometry::wrap_angle;

}  // namespace

void LoopDetectorParams::validate() const {
  require_positive("revisit_radius_m", revisit_radius_m);
  require(
      std::isfinite(heading_tolerance_rad) && heading_tolerance_rad > 0.0 && heading_tolerance_rad <= std::numbers::pi,
      "heading_tolerance_rad", "must be in (0, pi] radians", heading_tolerance_rad);
  require(revisit_count >= 1, "revisit_count", "must be at least 1", revisit_count);
  require_non_negative("min_revisit_interval_s", min_revisit_interval_s);
  require_non_negative("min_loop_length_m", min_loop_length_m);
  require_non_negative("progress_epsilon_m", progress_epsilon_m);
  require_positive("stall_time_s", stall_time_s);
  require_positive("window_s", window_s);
  require_positive("sample_spacing_m", sample_spacing_m);
  require(max_samples >= 2, "max_samples", "must be at least 2", static_cast<double>(max_samples));
}

LoopDetector::LoopDetector(const LoopDetectorParams& params) : params_(params) {
  params_.validate();
  reset();
}

void LoopDetector::reset() {
  samples_.clear();
  status_ = LoopStatus{};
  status_.reason = LoopReason::kNone;
  path_length_m_ = 0.0;
  progress_mark_m_ = kInfinity;
  // Progress is measured from now on: a stall needs another stall_time_s without progress.
  if (last_time_s_.has_value()) progress_time_s_ = *last_time_s_;
}

int LoopDetector::count_passes(const Sample& now) const {
  // Earlier passes are runs of consecutive matching samples; the samples of the current pass never match because
  // they are too recent in time or path length.
  int passes = 0;
  bool in_run = false;
  for (const Sample& earlier : samples_) {
    const bool matches = now.time_s - earlier.time_s >= params_.min_revisit_interval_s &&
                         now.path_length_m - earlier.path_length_m >= params_.min_loop_length_m &&
                         (now.p_W - earlier.p_W).norm() <= params_.revisit_radius_m &&
                         std::abs(wrap_angle(now.theta - earlier.theta)) <= params_.heading_tolerance_rad &&
                         earlier.state == now.state &&
                         // The excursion since then brought no new record closeness to the goal.
                         now.best_goal_distance_m >= earlier.best_goal_distance_m - params_.progress_epsilon_m;
    if (matches && !in_run) ++passes;
    in_run = matches;
  }
  return passes;
}

LoopStatus LoopDetector::update(const LoopObservation& observation) {
  const Pose2& pose = observation.pose;
  require(std::isfinite(pose.x), "pose.x", "must be finite", pose.x);
  require(std::isfinite(pose.y), "pose.y", "must be finite", pose.y);
  require(std::isfinite(pose.theta), "pose.theta", "must be finite", pose.theta);
  require(std::isfinite(observation.time_s), "time_s", "must be finite", observation.time_s);
  if (last_time_s_.has_value()) {
    require(observation.time_s >= *last_time_s_, "time_s", "must not go backwards", observation.time_s);
  }
  if (observation.goal_W.has_value()) {
    require(std::isfinite(observation.goal_W->x()), "goal_W.x", "must be finite", observation.goal_W->x());
    require(std::isfinite(observation.goal_W->y()), "goal_W.y", "must be finite", observation.goal_W->y());
  }

  const Eigen::Vector2d p_W(pose.x, pose.y);
  const bool first = !last_time_s_.has_value();
  if (observation.goal_W != goal_W_) {
    // A new goal: the old distances say nothing about progress toward it.
    goal_W_ = observation.goal_W;
    last_time_s_ = observation.time_s;
    reset();
  }
  if (!first) path_length_m_ += (p_W - last_p_W_).norm();
  if (first) progress_time_s_ = observation.time_s;
  last_time_s_ = observation.time_s;
  last_p_W_ = p_W;

  // Progress toward the goal.
  double best_goal_distance_m = kInfinity;
  if (goal_W_.has_value()) {
    const double distance_m = (*goal_W_ - p_W).norm();
    if (!status_.best_goal_distance_m.has_value() || distance_m < *status_.best_goal_distance_m) {
      status_.best_goal_distance_m = distance_m;
    }
    best_goal_distance_m = *status_.best_goal_distance_m;
    if (distance_m < progress_mark_m_ - params_.progress_epsilon_m) {
      progress_mark_m_ = distance_m;
      progress_time_s_ = observation.time_s;
    }
    status_.since_progress_s = observation.time_s - progress_time_s_;
    if (!status_.stalled && status_.since_progress_s >= params_.stall_time_s) {
      status_.stalled = true;
      if (!status_.loop) status_.reason = LoopReason::kStall;
    }
  }

  // Forget what is too old.
  while (!samples_.empty() &&
         (observation.time_s - samples_.front().time_s > params_.window_s || samples_.size() >= params_.max_samples)) {
    samples_.pop_front();
  }

  const Sample now{p_W, pose.theta, observation.time_s, path_length_m_, best_goal_distance_m, observation.state};
  const bool store = samples_.empty() || (p_W - samples_.back().p_W).norm() >= params_.sample_spacing_m ||
                     std::abs(wrap_angle(pose.theta - samples_.back().theta)) >= params_.heading_tolerance_rad / 4.0 ||
                     now.state != samples_.back().state;
  if (store) {
    status_.passes = count_passes(now);
    if (!status_.loop && status_.passes >= params_.revisit_count) {
      status_.loop = true;
      status_.loop_point_W = p_W;
      if (!status_.stalled) status_.reason = LoopReason::kLoop;
    }
    samples_.push_back(now);
  }
  return status_;
}

}  // namespace occgeo::service::control
