#include "occgeo/sim/laser.h"

#include <algorithm>
#include <cmath>

#include "occgeo/sim/raycast.h"

namespace occgeo::sim {

LaserSimulator::LaserSimulator(const LaserPreset& laser, std::uint64_t seed)
    : laser_(laser), noise_(laser.range_noise_sigma_m, seed) {}

SimulatedScan LaserSimulator::scan(const World& world, const geometry::Pose2& X_WB) {
  const geometry::Pose2 X_WS = X_WB.compose(laser_.X_BS);
  SimulatedScan scan;
  scan.ranges_m.reserve(laser_.beam_count);
  for (std::uint32_t beam = 0; beam < laser_.beam_count; ++beam) {
    const double angle_W = X_WS.theta + laser_.angle_min_rad + beam * laser_.angle_increment_rad;
    const double noise_m = noise_.sample();
    const auto hit = cast_ray(world, X_WS.position(), {std::cos(angle_W), std::sin(angle_W)}, laser_.range_max_m);
    if (!hit) {
      scan.ranges_m.push_back(static_cast<float>(laser_.range_max_m));
      continue;
    }
    scan.ranges_m.push_back(
        static_cast<float>(std::clamp(hit->distance_m + noise_m, laser_.range_min_m, laser_.range_max_m)));
    scan.hit_pixels.insert(scan.hit_pixels.end(), hit->pixels.begin(), hit->pixels.end());
  }
  return scan;
}

}  // namespace occgeo::sim
