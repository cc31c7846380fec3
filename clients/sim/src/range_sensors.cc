#include "occgeo/sim/range_sensors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

namespace occgeo::sim {

namespace {

Eigen::Vector2d unit(double angle_rad) { return {std::cos(angle_rad), std::sin(angle_rad)}; }

}  // namespace

RangeArraySimulator::RangeArraySimulator(const RangeArrayPreset& array, std::uint64_t seed)
    : array_(array), noise_(1.0, seed) {
  if (array.rays_per_beam % 2 == 0) {
    throw std::invalid_argument("range array '" + array.name +
                                "': rays_per_beam must be odd (one ray on the axis), got " +
                                std::to_string(array.rays_per_beam));
  }
  if (array.elements.empty()) throw std::invalid_argument("range array '" + array.name + "': has no elements");
  if (!(array.range_min_m >= 0.0 && array.range_min_m < array.range_max_m)) {
    throw std::invalid_argument("range array '" + array.name + "': needs 0 <= range_min_m < range_max_m");
  }
  if (!(array.specular_tolerance_rad > 0.0 && array.specular_tolerance_rad <= std::numbers::pi / 2.0)) {
    throw std::invalid_argument("range array '" + array.name +
                                "': specular_tolerance_rad must be in (0, pi/2] (the largest incidence angle that "
                                "still echoes), got " +
                                std::to_string(array.specular_tolerance_rad));
  }
}

SimulatedScan RangeArraySimulator::fire(const SimWorld& world, const geometry::Pose2& X_WB, double time_s) {
  const geometry::Pose2 X_WS = X_WB.compose(array_.X_BS);
  const std::uint32_t rays = array_.rays_per_beam;
  const std::uint32_t axis_ray = rays / 2;
  // cos(incidence) >= cos(tolerance) is the incidence test without an acos per ray.
  const double min_cos_incidence = std::cos(array_.specular_tolerance_rad);
  SimulatedScan scan;
  scan.ranges_m.reserve(array_.elements.size());
  for (const geometry::Pose2& X_SE : array_.elements) {
    const geometry::Pose2 X_WE = X_WS.compose(X_SE);
    const double noise = noise_.sample();
    std::optional<double> nearest_m;
    std::optional<RayHit> axis_hit;
    for (std::uint32_t ray = 0; ray < rays; ++ray) {
      // Offsets from -width/2 to +width/2; the middle ray's offset is exactly 0 (the acoustic axis).
      const double offset_rad = rays == 1 ? 0.0 : array_.beam_width_rad * (static_cast<double>(ray) / (rays - 1) - 0.5);
      const Eigen::Vector2d direction = unit(X_WE.theta + offset_rad);
      const auto hit = world.cast(X_WE.position(), direction, array_.range_max_m, time_s, array_.mount_height_m);
      if (!hit) continue;
      // Specular reflection: met more obliquely than the tolerance, the pulse bounces away and this ray hears nothing.
      if (-direction.dot(hit->normal_W) < min_cos_incidence) continue;
      if (!nearest_m || hit->distance_m < *nearest_m) nearest_m = hit->distance_m;
      if (ray == axis_ray) axis_hit = hit;
    }
    // The element hears the nearest echo in its cone: the axis cell is what it saw only when that echo is the axis's.
    constexpr double kSameEcho_m = 1e-3;
    if (axis_hit && axis_hit->distance_m <= *nearest_m + kSameEcho_m) {
      scan.hit_pixels.insert(scan.hit_pixels.end(), axis_hit->pixels.begin(), axis_hit->pixels.end());
    }
    if (!nearest_m) {
      scan.ranges_m.push_back(static_cast<float>(array_.range_max_m));
      continue;
    }
    const double sigma_m = array_.range_noise_fraction * *nearest_m;
    scan.ranges_m.push_back(
        static_cast<float>(std::clamp(*nearest_m + sigma_m * noise, array_.range_min_m, array_.range_max_m)));
  }
  return scan;
}

ServoRangeSimulator::ServoRangeSimulator(const ServoRangePreset& servo, std::uint64_t seed)
    : servo_(servo), steps_per_sweep_(0), noise_(1.0, seed) {
  const double steps = (servo.servo_max_rad - servo.servo_min_rad) / servo.servo_step_rad;
  const double whole = std::round(steps);
  if (!(std::isfinite(steps) && whole >= 1.0 && std::abs(steps - whole) < 1e-6)) {
    throw std::invalid_argument("servo range '" + servo.name +
                                "': (servo_max_rad - servo_min_rad) / servo_step_rad must be a positive whole number");
  }
  steps_per_sweep_ = static_cast<std::uint64_t>(whole);
}

double ServoRangeSimulator::servo_angle_of(std::uint64_t reading) const {
  const std::uint64_t phase = reading % (2 * steps_per_sweep_);
  const std::uint64_t step = phase <= steps_per_sweep_ ? phase : 2 * steps_per_sweep_ - phase;
  if (step == steps_per_sweep_) return servo_.servo_max_rad;  // exactly the limit, without rounding
  return servo_.servo_min_rad + static_cast<double>(step) * servo_.servo_step_rad;
}

ServoReading ServoRangeSimulator::measure(const SimWorld& world, const geometry::Pose2& X_WB, double time_s) {
  ServoReading reading;
  reading.servo_angle_rad = servo_angle_of(next_reading_++);
  const geometry::Pose2 X_WS = X_WB.compose(servo_.X_BS);
  const double noise = noise_.sample();
  const auto hit = world.cast(X_WS.position(), unit(X_WS.theta + reading.servo_angle_rad), servo_.range_max_m, time_s,
                              servo_.mount_height_m);
  if (!hit) {
    reading.range_m = static_cast<float>(servo_.range_max_m);
    return reading;
  }
  const double sigma_m =
      hit->distance_m < servo_.noise_far_from_m ? servo_.noise_sigma_near_m : servo_.noise_sigma_far_m;
  reading.range_m =
      static_cast<float>(std::clamp(hit->distance_m + sigma_m * noise, servo_.range_min_m, servo_.range_max_m));
  reading.hit_pixels = hit->pixels;
  return reading;
}

}  // namespace occgeo::sim
