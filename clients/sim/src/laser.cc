#include "occgeo/sim/laser.h"

#include <algorithm>
#include <cmath>

#include "occgeo/sim/raycast.h"

namespace occgeo::sim {

LaserSimulator::LaserSimulator(const LaserPreset& laser, std::uint64_t seed)
    : laser_(laser), noise_(laser.range_noise_sigma_m, seed) {}

SimulatedScan LaserSimulator::scan(const World& world, const geometry::Pose2& X_WB) {
  return sweep(X_WB, [&](const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W) {
    return cast_ray(world, p_W, direction_W, laser_.range_max_m);
  });
}

SimulatedScan LaserSimulator::scan(const SimWorld& world, const geometry::Pose2& X_WB, double time_s) {
  return sweep(X_WB, [&](const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W) {
    return world.cast(p_W, direction_W, laser_.range_max_m, time_s, laser_.mount_height_m);
  });
}

template <typename Cast>
SimulatedScan LaserSimulator::sweep(const geometry::Pose2& X_WB, const Cast& cast) {
  const geometry::Pose2 X_WS = X_WB.compose(laser_.X_BS);
  SimulatedScan scan;
  scan.ranges_m.reserve(laser_.beam_count);
  for (std::uint32_t beam = 0; beam < laser_.beam_count; ++beam) {
    const double angle_W = X_WS.theta + laser_.angle_min_rad + beam * laser_.angle_increment_rad;
    const double noise_m = noise_.sample();
    const auto hit = cast(X_WS.position(), Eigen::Vector2d(std::cos(angle_W), std::sin(angle_W)));
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
