#include "occgeo/service/control/wander.h"
#include "occgeo/geometry/pose.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>

#include "param_checks.h"

namespace occgeo::service::control {
namespace {

using detail::require;
using detail::require_non_negative;
using detail::require_positive;

// Bearings are compared wrapped into (-pi, pi], so a ring given in [0, 2 pi) works too.
using geometry::wrap_angle;

}  // namespace

RangeSet range_set_from_scan(const ScanView& scan) {
  RangeSet set;
  set.range_max_m = scan.range_max_m;
  set.beams.reserve(scan.ranges_m.size());
  for (std::size_t beam = 0; beam < scan.ranges_m.size(); ++beam) {
    set.beams.push_back(BeamReading{scan.angle_min_rad + static_cast<double>(beam) * scan.angle_increment_rad,
                                    static_cast<double>(scan.ranges_m[beam])});
  }
  return set;
}

RangeSet range_set_from_ring(std::span<const double> bearings_rad, std::span<const double> ranges_m,
                             double range_max_m) {
  require(bearings_rad.size() == ranges_m.size(), "ranges_m", "must have one range per bearing",
          static_cast<double>(ranges_m.size()));
  RangeSet set;
  set.range_max_m = range_max_m;
  for (std::size_t element = 0; element < ranges_m.size(); ++element) {
    set.beams.push_back(BeamReading{bearings_rad[element], ranges_m[element]});
  }
  return set;
}

std::vector<double> scout_sonar_bearings_rad() {
  std::vector<double> bearings;
  for (int sonar = 0; sonar < 16; ++sonar) bearings.push_back(wrap_angle(sonar * kScoutSonarSpacing_rad));
  return bearings;
}

void WanderParams::validate() const {
  require(std::isfinite(front_sector_right_rad) && front_sector_right_rad >= 0.0 &&
              front_sector_right_rad <= std::numbers::pi,
          "front_sector_right_rad", "must be in [0, pi] radians", front_sector_right_rad);
  require(
      std::isfinite(front_sector_left_rad) && front_sector_left_rad >= 0.0 && front_sector_left_rad <= std::numbers::pi,
      "front_sector_left_rad", "must be in [0, pi] radians", front_sector_left_rad);
  require_positive("obstacle_threshold_m", obstacle_threshold_m);
  require_positive("run_length_min_m", run_length_min_m);
  require_positive("run_length_max_m", run_length_max_m);
  require(run_length_max_m >= run_length_min_m, "run_length_max_m", "must not be below run_length_min_m",
          run_length_max_m);
  require(std::isfinite(turn_probability) && turn_probability >= 0.0 && turn_probability <= 1.0, "turn_probability",
          "must be in [0, 1]", turn_probability);
  require(std::isfinite(turn_little_min_rad) && turn_little_min_rad > 0.0 && turn_little_min_rad <= std::numbers::pi,
          "turn_little_min_rad", "must be in (0, pi] radians", turn_little_min_rad);
  require(std::isfinite(turn_little_max_rad) && turn_little_max_rad >= turn_little_min_rad &&
              turn_little_max_rad <= std::numbers::pi,
          "turn_little_max_rad", "must be in [turn_little_min_rad, pi] radians", turn_little_max_rad);
  require_positive("linear_speed_mps", linear_speed_mps);
  require_positive("turn_speed_radps", turn_speed_radps);
}

WanderBehaviour::WanderBehaviour(const WanderParams& params) : params_(params) {
  params_.validate();
  generator_.seed(params_.seed);
  start_run();
}

double WanderBehaviour::uniform(double low, double high) {
  // 53 random bits make a double in [0, 1) that every standard library computes alike.
  const double unit = static_cast<double>(generator_() >> 11U) * 0x1.0p-53;
  return low + (high - low) * unit;
}

bool WanderBehaviour::coin(double probability) { return uniform(0.0, 1.0) < probability; }

void WanderBehaviour::start_run() {
  state_ = State::kWanderStraight;
  remaining_m_ = uniform(params_.run_length_min_m, params_.run_length_max_m);
  remaining_rad_ = 0.0;
}

bool WanderBehaviour::front_blocked(const RangeSet& readings) const {
  require_positive("RangeSet.range_max_m", readings.range_max_m);
  bool any_front_beam = false;
  bool blocked = false;
  for (const BeamReading& beam : readings.beams) {
    require(std::isfinite(beam.bearing_rad), "RangeSet.beams.bearing_rad", "must be finite", beam.bearing_rad);
    require(!std::isnan(beam.range_m) && beam.range_m >= 0.0, "RangeSet.beams.range_m", "must hold non-negative ranges",
            beam.range_m);
    const double bearing = wrap_angle(beam.bearing_rad);
    if (bearing < -params_.front_sector_right_rad || bearing > params_.front_sector_left_rad) continue;
    any_front_beam = true;
    // A no-return reading is never an obstacle, even with a threshold beyond the sensor's range.
    if (beam.range_m < readings.range_max_m && beam.range_m < params_.obstacle_threshold_m) blocked = true;
  }
  // Without a frontal beam the robot is blind where it drives; that is a malformed input, not a clear front.
  require(any_front_beam, "RangeSet.beams", "must hold a beam in the frontal sector",
          static_cast<double>(readings.beams.size()));
  return blocked;
}

WanderDecision WanderBehaviour::decide(const RangeSet& readings, const WanderProgress& progress) {
  require_non_negative("WanderProgress.elapsed_s", progress.elapsed_s);
  if (progress.travelled_m)
    require(std::isfinite(*progress.travelled_m), "WanderProgress.travelled_m", "must be finite",
            *progress.travelled_m);
  if (progress.turned_rad)
    require(std::isfinite(*progress.turned_rad), "WanderProgress.turned_rad", "must be finite", *progress.turned_rad);
  const bool blocked = front_blocked(readings);
  const double travelled_m =
      progress.travelled_m ? std::abs(*progress.travelled_m) : std::abs(last_linear_mps_) * progress.elapsed_s;
  const double turned_rad =
      progress.turned_rad ? std::abs(*progress.turned_rad) : std::abs(last_angular_radps_) * progress.elapsed_s;

  // Figure 1's loop body, advanced by what the robot did; the draws happen in a fixed order (run length, then the
  // turn coin, then direction and angle) so a seed names one sequence of decisions.
  if (state_ == State::kWanderStraight) {
    remaining_m_ -= travelled_m;
    if (remaining_m_ <= 0.0) {
      remaining_m_ = 0.0;
      if (coin(params_.turn_probability)) {
        state_ = State::kWanderTurn;
        turn_direction_ = coin(0.5) ? 1.0 : -1.0;
        remaining_rad_ = uniform(params_.turn_little_min_rad, params_.turn_little_max_rad);
      } else {
        start_run();
      }
    }
  } else if (state_ == State::kWanderTurn) {
    remaining_rad_ -= turned_rad;
    if (remaining_rad_ <= 0.0) start_run();
  }

  // Figure 2: avoid subsumes wander while the front is blocked; its direction is drawn once on entry and kept,
  // and when the front clears wander starts over with a fresh run (Figure 1's loop restarts).
  if (blocked) {
    if (state_ != State::kAvoidTurn) {
      state_ = State::kAvoidTurn;
      turn_direction_ = coin(0.5) ? 1.0 : -1.0;
      remaining_m_ = 0.0;
      remaining_rad_ = 0.0;
    }
  } else if (state_ == State::kAvoidTurn) {
    start_run();
  }

  WanderDecision decision = command();
  decision.front_blocked = blocked;
  last_linear_mps_ = decision.linear_mps;
  last_angular_radps_ = decision.angular_radps;
  return decision;
}

WanderDecision WanderBehaviour::command() const {
  WanderDecision decision;
  switch (state_) {
    case State::kWanderStraight:
      decision.linear_mps = params_.linear_speed_mps;
      decision.state = BehaviourState::kWanderStraight;
      decision.remaining_m = remaining_m_;
      break;
    case State::kWanderTurn:
      // turn_little and avoid's turn are turns in place, so a round robot never sweeps into what it sees.
      decision.angular_radps = turn_direction_ * params_.turn_speed_radps;
      decision.state = BehaviourState::kWanderTurn;
      decision.remaining_rad = remaining_rad_;
      break;
    case State::kAvoidTurn:
      decision.angular_radps = turn_direction_ * params_.turn_speed_radps;
      decision.state = BehaviourState::kAvoidTurn;
      break;
  }
  return decision;
}

}  // namespace occgeo::service::control
