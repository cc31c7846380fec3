#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "occgeo/geometry/pose.h"
#include "occgeo/sim/noise.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/sim_world.h"

namespace occgeo::sim {

// Where a 3-D ray from p_W along the unit vector direction_W (world frame, z up) first meets the world at sim time
// time_s: a shape of a shape world (any height, non-solid ones too), an obstacle pixel of a pixel world (infinitely
// tall), or the ground plane z = 0; the distance in metres, or nullopt when nothing is closer than max_range_m.
std::optional<double> cast_depth_ray(const SimWorld& world, const Eigen::Vector3d& p_W,
                                     const Eigen::Vector3d& direction_W, double max_range_m, double time_s);

// The unit direction of ray (row, column) of a depth sensor in its own frame (x forward along the optical axis, y
// left, z up): columns sweep the azimuth from +horizontal_fov/2 (left) to -horizontal_fov/2, rows the elevation from
// +vertical_fov/2 (top) to -vertical_fov/2, evenly in angle.
Eigen::Vector3d depth_ray_direction_S(const DepthSensorPreset& sensor, std::uint32_t row, std::uint32_t column);

// Simulates a depth camera or a 3-D lidar by casting each of its rows x columns rays in 3-D, with seeded Gaussian
// range noise. A ray with a return in [range_min, range_max] gives one point in the sensor frame; a ray without one
// gives none (the PointCloud carries returns only), so the floor in view appears as points at z = 0 in the world.
class DepthSensorSimulator {
 public:
  // One noise sample per ray per frame, so a ray's noise does not depend on what the others hit.
  DepthSensorSimulator(const DepthSensorPreset& sensor, std::uint64_t seed);

  // One frame from the robot's base_link pose X_WB at sim time time_s: x, y, z triples in the sensor frame, metres.
  std::vector<float> capture(const SimWorld& world, const geometry::Pose2& X_WB, double time_s);

  [[nodiscard]] const DepthSensorPreset& preset() const { return sensor_; }

 private:
  DepthSensorPreset sensor_;
  std::vector<Eigen::Vector3d> directions_S_;  // row-major, fixed by the preset
  GaussianNoise noise_;
};

}  // namespace occgeo::sim
