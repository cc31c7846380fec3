#pragma once

#include <algorithm>
#include <limits>

namespace occgeo::mapping {

// How far a sensor's readings change a map (octomap_server's sensor_model/max_range, split in three): a long-range
// sensor then costs each scan what its near field costs, not what its whole reach would. Metres, each >= 0; the
// defaults (infinite) use every reading as far as the sensor's range_max.
struct BeamLimits {
  static constexpr double kUnlimited = std::numeric_limits<double>::infinity();
  // A return farther than this is not marked occupied; its beam carves free space up to this distance.
  double max_insert_range_m = kUnlimited;
  // No beam carves free space farther than this from the sensor (a closer return is still marked).
  double max_free_range_m = kUnlimited;
  // A beam with no return (a reading at or beyond the sensor's range_max) carves free space up to this distance;
  // 0: such beams change nothing.
  double no_return_clear_m = kUnlimited;

  // The same limits, none above cap_m (e.g. a model's own longest beam).
  [[nodiscard]] BeamLimits capped(double cap_m) const {
    return {std::min(max_insert_range_m, cap_m), std::min(max_free_range_m, cap_m), std::min(no_return_clear_m, cap_m)};
  }
  // The farthest any beam of a sensor with this range_max can change a map.
  [[nodiscard]] double reach_m(double range_max_m) const {
    return std::min(range_max_m, std::max({max_insert_range_m, max_free_range_m, no_return_clear_m}));
  }
};

// What one reading does to a map under BeamLimits.
struct BeamUse {
  double free_m = 0.0;  // free space is carved from the sensor out to this distance (0: none)
  bool hit = false;     // the reading's end point is marked occupied
};

// The use of a reading (metres, >= 0) from a sensor whose readings at or beyond range_max_m mean "no return".
[[nodiscard]] inline BeamUse beam_use(double reading_m, double range_max_m, const BeamLimits& limits) {
  if (reading_m >= range_max_m) {
    return {std::min({range_max_m, limits.no_return_clear_m, limits.max_free_range_m}), false};
  }
  if (reading_m <= limits.max_insert_range_m) return {std::min(reading_m, limits.max_free_range_m), true};
  return {std::min(limits.max_insert_range_m, limits.max_free_range_m), false};
}

}  // namespace occgeo::mapping
