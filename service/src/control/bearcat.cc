#include "occgeo/service/control/bearcat.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "param_checks.h"

namespace occgeo::service::control {
namespace {

using detail::require;
using detail::require_non_negative;
using detail::require_positive;

constexpr double kDegreesPerRadian = 180.0 / std::numbers::pi;

// Beams this close beyond +-90 degrees still look forward, radians; absorbs rounding in angle_min + i * increment.
constexpr double kForwardBearingTolerance_rad = 1e-9;

// Zones in the thesis's order; ob_factor uses index + 1.
enum ZoneIndex : std::size_t { kRightZone = 0, kMiddleZone = 1, kLeftZone = 2 };

// The contiguous index range [first, end) of the beams whose bearing lies within +-90 degrees; backward-looking
// beams (e.g. of a 240 degree scanner) are ignored, so every layout sees what the LMS200's half-plane sees. All of
// these beams count, including the LMS200's 181st at +90 degrees that the original's loops (i < 180) skipped.
struct ForwardBeams {
  std::size_t first = 0;
  std::size_t end = 0;
};

double bearing_of(const ScanView& scan, std::size_t beam) {
  return scan.angle_min_rad + static_cast<double>(beam) * scan.angle_increment_rad;
}

// The range of a beam in metres, no-return readings (and +inf) clamped to range_max_m.
double range_of(const ScanView& scan, std::size_t beam) {
  return std::min(static_cast<double>(scan.ranges_m[beam]), scan.range_max_m);
}

ForwardBeams checked_forward_beams(const ScanView& scan) {
  require(std::isfinite(scan.angle_min_rad), "ScanView.angle_min_rad", "must be finite", scan.angle_min_rad);
  require_positive("ScanView.angle_increment_rad", scan.angle_increment_rad);
  require_positive("ScanView.range_max_m", scan.range_max_m);
  for (const float range : scan.ranges_m) {
    require(!std::isnan(range) && range >= 0.0F, "ScanView.ranges_m", "must hold non-negative ranges",
            static_cast<double>(range));
  }
  const double right_limit = -std::numbers::pi / 2.0 - kForwardBearingTolerance_rad;
  const double left_limit = std::numbers::pi / 2.0 + kForwardBearingTolerance_rad;
  ForwardBeams forward;
  while (forward.first < scan.ranges_m.size() && bearing_of(scan, forward.first) < right_limit) ++forward.first;
  forward.end = forward.first;
  while (forward.end < scan.ranges_m.size() && bearing_of(scan, forward.end) <= left_limit) ++forward.end;
  if (forward.end == forward.first) {
    throw std::invalid_argument("ScanView.ranges_m must hold a beam within +-90 degrees of straight ahead");
  }
  return forward;
}

// Zones are split by bearing at the rectangle's front corners, atan2(width / 2, depth) = 22.0007 degrees with the
// defaults; the original's integer split put the LMS200's +-22 degree beams into the side zones, here they are
// middle beams, and at those beams both tests agree to within 0.1 mm.
ZoneIndex zone_of(double bearing_rad, double corner_bearing_rad) {
  if (bearing_rad < -corner_bearing_rad) return kRightZone;
  if (bearing_rad > corner_bearing_rad) return kLeftZone;
  return kMiddleZone;
}

// Whether a beam of the given zone ends inside the frontal rectangle: side beams leave it through its long sides
// (lateral offset <= width / 2, the original's d <= 80 / cos), middle beams through its front (forward distance
// < depth, the original's d < 198 / sin).
bool ends_inside_rectangle(ZoneIndex zone, const BeamReading& beam, const BearcatParams& params) {
  if (zone == kMiddleZone) return beam.range_m * std::cos(beam.bearing_rad) < params.zone_depth_m;
  return beam.range_m * std::abs(std::sin(beam.bearing_rad)) <= params.zone_width_m / 2.0;
}

// The thesis's per-zone sweep from each zone's right edge counter-clockwise; ob_near is the true minimum (the
// thesis's pseudo-code compares with the previous beam only, which tracks the last decrease instead).
std::array<ZoneObservation, 3> observe_zones(const ScanView& scan, ForwardBeams forward, const BearcatParams& params) {
  const double corner_bearing_rad = std::atan2(params.zone_width_m / 2.0, params.zone_depth_m);
  std::array<ZoneObservation, 3> zones;
  for (std::size_t beam_index = forward.first; beam_index < forward.end; ++beam_index) {
    const BeamReading beam{bearing_of(scan, beam_index), range_of(scan, beam_index)};
    const ZoneIndex zone_index = zone_of(beam.bearing_rad, corner_bearing_rad);
    if (!ends_inside_rectangle(zone_index, beam, params)) continue;
    ZoneObservation& zone = zones[zone_index];
    if (!zone.obstacle_present) {
      zone.obstacle_present = true;
      zone.ob_right = beam;
      zone.ob_near = beam;
    }
    if (beam.range_m < zone.ob_near.range_m) zone.ob_near = beam;
    zone.ob_left = beam;
  }
  return zones;
}

int ob_factor_of(const std::array<ZoneObservation, 3>& zones) {
  int ob_factor = 0;
  for (std::size_t zone_index = 0; zone_index < zones.size(); ++zone_index) {
    if (zones[zone_index].obstacle_present) ob_factor = ob_factor * 10 + static_cast<int>(zone_index) + 1;
  }
  return ob_factor;
}

// The gap whose edges are the endpoints of two beams, its width the chord between them.
Gap gap_between(const ScanView& scan, std::size_t right_beam, std::size_t left_beam) {
  const double right_bearing = bearing_of(scan, right_beam);
  const double left_bearing = bearing_of(scan, left_beam);
  const double right_range = range_of(scan, right_beam);
  const double left_range = range_of(scan, left_beam);
  const double chord_x = left_range * std::cos(left_bearing) - right_range * std::cos(right_bearing);
  const double chord_y = left_range * std::sin(left_bearing) - right_range * std::sin(right_bearing);
  return Gap{right_bearing, left_bearing, (right_bearing + left_bearing) / 2.0, std::hypot(chord_x, chord_y)};
}

// The appendix's open-gap finder. A run is a maximal sequence of consecutive beams with range >= gap_range_m, of
// more than one beam; its width is the smaller of the chord between its edge beams and the chord with the run
// extended by one beam on each side that has one (the edges follow the chord chosen, as the original's
// start--/end++); the widest run of at least gap_min_width_m wins, the rightmost of equals. Fixed from the
// original: a run reaching the end of the scan is evaluated (the original only closed a run on a short beam),
// each run's width is its own (the original compared an uninitialised or stale gap_width2), and each run's size
// starts from zero (the original reset gap_size only after a qualifying gap).
std::optional<Gap> find_widest_gap(const ScanView& scan, ForwardBeams forward, const BearcatParams& params) {
  const auto is_open = [&](std::size_t beam) { return range_of(scan, beam) >= params.gap_range_m; };
  std::optional<Gap> widest;
  std::size_t beam = forward.first;
  while (beam < forward.end) {
    if (!is_open(beam)) {
      ++beam;
      continue;
    }
    const std::size_t run_first = beam;
    while (beam < forward.end && is_open(beam)) ++beam;
    const std::size_t run_last = beam - 1;
    if (run_last == run_first) continue;
    const std::size_t extended_first = run_first > forward.first ? run_first - 1 : run_first;
    const std::size_t extended_last = run_last + 1 < forward.end ? run_last + 1 : run_last;
    const Gap inner = gap_between(scan, run_first, run_last);
    const Gap extended = gap_between(scan, extended_first, extended_last);
    const Gap& gap = inner.width_m < extended.width_m ? inner : extended;
    if (gap.width_m >= params.gap_min_width_m && (!widest || gap.width_m > widest->width_m)) widest = gap;
  }
  return widest;
}

// With an obstacle only in the middle and no qualifying gap, turn toward the half of the forward scan (right:
// bearing < 0, left: bearing > 0) whose nearest return is farther away; equal halves turn left, the thesis's
// default for this case. Returns the steer in degrees.
double steer_toward_freer_side(const ScanView& scan, ForwardBeams forward, const BearcatParams& params) {
  double nearest_right_m = std::numeric_limits<double>::infinity();
  double nearest_left_m = std::numeric_limits<double>::infinity();
  for (std::size_t beam = forward.first; beam < forward.end; ++beam) {
    const double bearing = bearing_of(scan, beam);
    if (bearing < 0.0) nearest_right_m = std::min(nearest_right_m, range_of(scan, beam));
    if (bearing > 0.0) nearest_left_m = std::min(nearest_left_m, range_of(scan, beam));
  }
  return nearest_left_m >= nearest_right_m ? params.turn_large_deg : -params.turn_large_deg;
}

// The steer, stop flag and state the case table of the appendix assigns to an ob_factor.
struct Manoeuvre {
  double steer_deg = 0.0;
  bool stop = false;
  BehaviourState state;
};

Manoeuvre manoeuvre_for(int ob_factor, const std::optional<Gap>& widest_gap, const ScanView& scan, ForwardBeams forward,
                        const BearcatParams& params) {
  switch (ob_factor) {
    case 0:
      return {0.0, false, BehaviourState::kClear};
    case 1:
      return {params.turn_small_deg, false, BehaviourState::kAvoidRightObstacle};
    case 12:
      return {params.turn_large_deg, false, BehaviourState::kAvoidRightObstacle};
    case 3:
    case 23:
      return {-params.turn_large_deg, false, BehaviourState::kAvoidLeftObstacle};
    case 2:
      if (widest_gap) return {widest_gap->center_bearing_rad * kDegreesPerRadian, false, BehaviourState::kSteerGap};
      return {steer_toward_freer_side(scan, forward, params), false, BehaviourState::kNoGap};
    case 13:
      return {0.0, false, BehaviourState::kPassBetween};
    case 123:
      return {0.0, true, BehaviourState::kDeadlock};
    default:
      break;
  }
  std::abort();  // ob_factor_of only builds the eight values above from zones 1, 2, 3 in order.
}

}  // namespace

void BearcatParams::validate() const {
  require_positive("zone_width_m", zone_width_m);
  require_positive("zone_depth_m", zone_depth_m);
  require_positive("gap_range_m", gap_range_m);
  require_positive("gap_min_width_m", gap_min_width_m);
  require_non_negative("straight_deadband_deg", straight_deadband_deg);
  require_non_negative("base_speed_mps", base_speed_mps);
  require_non_negative("speed_per_degree_mps", speed_per_degree_mps);
  require_positive("max_wheel_speed_mps", max_wheel_speed_mps);
  require(base_speed_mps <= max_wheel_speed_mps, "base_speed_mps", "must not exceed max_wheel_speed_mps",
          base_speed_mps);
  require_positive("wheel_separation_m", wheel_separation_m);
  require(std::isfinite(turn_small_deg) && turn_small_deg > 0.0 && turn_small_deg <= 90.0, "turn_small_deg",
          "must be in (0, 90] degrees", turn_small_deg);
  require(std::isfinite(turn_large_deg) && turn_large_deg > 0.0 && turn_large_deg <= 90.0, "turn_large_deg",
          "must be in (0, 90] degrees", turn_large_deg);
}

// The original's extra branches for steers beyond +-30 degrees (10000/4000 counts) are dead code: its else branch
// always overwrites them, so every steer outside the deadband uses the linear law below.
WheelCommand wheel_command_for_steer(double steer_deg, const BearcatParams& params) {
  double left_mps = params.base_speed_mps;
  double right_mps = params.base_speed_mps;
  if (std::abs(steer_deg) >= params.straight_deadband_deg) {
    left_mps -= params.speed_per_degree_mps * steer_deg;
    right_mps += params.speed_per_degree_mps * steer_deg;
  }
  left_mps = std::clamp(left_mps, -params.max_wheel_speed_mps, params.max_wheel_speed_mps);
  right_mps = std::clamp(right_mps, -params.max_wheel_speed_mps, params.max_wheel_speed_mps);
  return WheelCommand{left_mps, right_mps, (left_mps + right_mps) / 2.0,
                      (right_mps - left_mps) / params.wheel_separation_m};
}

BearcatDecision decide(const ScanView& scan, const BearcatParams& params) {
  const ForwardBeams forward = checked_forward_beams(scan);
  BearcatDecision decision;
  decision.zones = observe_zones(scan, forward, params);
  decision.ob_factor = ob_factor_of(decision.zones);
  decision.widest_gap = find_widest_gap(scan, forward, params);
  const Manoeuvre manoeuvre = manoeuvre_for(decision.ob_factor, decision.widest_gap, scan, forward, params);
  decision.steer_deg = manoeuvre.steer_deg;
  decision.stop = manoeuvre.stop;
  decision.state = manoeuvre.state;
  if (!manoeuvre.stop) {
    const WheelCommand command = wheel_command_for_steer(manoeuvre.steer_deg, params);
    decision.left_wheel_mps = command.left_wheel_mps;
    decision.right_wheel_mps = command.right_wheel_mps;
    decision.linear_mps = command.linear_mps;
    decision.angular_radps = command.angular_radps;
  }
  return decision;
}

BearcatBehaviour::BearcatBehaviour(const BearcatParams& params) : params_(params) { params_.validate(); }

BearcatDecision BearcatBehaviour::decide(const ScanView& scan) const { return control::decide(scan, params_); }

}  // namespace occgeo::service::control
