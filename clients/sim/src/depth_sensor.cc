#include "occgeo/sim/depth_sensor.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "occgeo/sim/shape_world.h"

namespace occgeo::sim {

std::optional<double> cast_depth_ray(const SimWorld& world, const Eigen::Vector3d& p_W,
                                     const Eigen::Vector3d& direction_W, double max_range_m, double time_s) {
  if (!p_W.allFinite() || !direction_W.allFinite() || !(max_range_m >= 0.0)) {
    throw std::invalid_argument("cast_depth_ray: inputs must be finite and max_range_m >= 0");
  }
  std::optional<double> best;
  // The ground: a ray pointing down from above it meets z = 0.
  if (direction_W.z() < 0.0 && p_W.z() >= 0.0) best = -p_W.z() / direction_W.z();
  if (const auto* shapes = dynamic_cast<const ShapeWorld*>(&world)) {
    if (const auto t = shapes->cast_3d(p_W, direction_W, max_range_m, time_s); t && (!best || *t < *best)) best = t;
  } else {
    // Obstacles of other worlds are infinitely tall: the ray meets one where its ground track does.
    const double horizontal = direction_W.head<2>().norm();
    if (horizontal > 1e-12) {
      const Eigen::Vector2d track_W = direction_W.head<2>() / horizontal;
      if (const auto hit = world.cast(p_W.head<2>(), track_W, max_range_m * horizontal, time_s, p_W.z())) {
        const double t = hit->distance_m / horizontal;
        if (!best || t < *best) best = t;
      }
    }
  }
  if (!best || !(*best < max_range_m)) return std::nullopt;
  return best;
}

Eigen::Vector3d depth_ray_direction_S(const DepthSensorPreset& sensor, std::uint32_t row, std::uint32_t column) {
  const auto fraction = [](std::uint32_t index, std::uint32_t count) {
    return count > 1 ? static_cast<double>(index) / static_cast<double>(count - 1) : 0.5;
  };
  const double azimuth = sensor.horizontal_fov_rad * (0.5 - fraction(column, sensor.columns));
  const double elevation = sensor.vertical_fov_rad * (0.5 - fraction(row, sensor.rows));
  return {std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth), std::sin(elevation)};
}

DepthSensorSimulator::DepthSensorSimulator(const DepthSensorPreset& sensor, std::uint64_t seed)
    : sensor_(sensor), noise_(sensor.range_noise_sigma_m, seed) {
  directions_S_.reserve(static_cast<std::size_t>(sensor.rows) * sensor.columns);
  for (std::uint32_t row = 0; row < sensor.rows; ++row) {
    for (std::uint32_t column = 0; column < sensor.columns; ++column) {
      directions_S_.push_back(depth_ray_direction_S(sensor, row, column));
    }
  }
}

std::vector<float> DepthSensorSimulator::capture(const SimWorld& world, const geometry::Pose2& X_WB, double time_s) {
  const geometry::Pose3 X_WS = geometry::Pose3::from_pose2(X_WB).compose(sensor_.X_BS);
  const Eigen::Vector3d origin_W = X_WS.translation();
  std::vector<float> xyz_S;
  xyz_S.reserve(directions_S_.size() * 3);
  for (const Eigen::Vector3d& direction_S : directions_S_) {
    const double noise_m = noise_.sample();
    const auto t = cast_depth_ray(world, origin_W, X_WS.transform.linear() * direction_S, sensor_.range_max_m, time_s);
    if (!t || *t < sensor_.range_min_m) continue;
    // Noise never pushes a return outside the sensor's span (the server rejects points beyond range_max; the margin
    // covers rounding to float).
    const double range_m = std::clamp(*t + noise_m, sensor_.range_min_m, sensor_.range_max_m - 1e-3);
    for (int axis = 0; axis < 3; ++axis) xyz_S.push_back(static_cast<float>(direction_S[axis] * range_m));
  }
  return xyz_S;
}

}  // namespace occgeo::sim
