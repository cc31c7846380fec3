#include "model_ingest.h"

#include <algorithm>
#include <cmath>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "occgeo/geometry/cell.h"

namespace occgeo::service {

namespace {

// The world-frame direction of the scan's beam i from the (possibly upside-down) laser.
Eigen::Vector2d beam_direction_W(const PlanarSensorPose& sensor, const LaserModel& laser, std::size_t i) {
  const double sign = sensor.mirrored ? -1.0 : 1.0;
  const double bearing =
      sensor.X_WS.theta + sign * (laser.angle_min_rad + laser.angle_increment_rad * static_cast<double>(i));
  return {std::cos(bearing), std::sin(bearing)};
}

// Inserts the scan's readings into the grid; readings below the sensor's minimum range carry no
// information and are skipped.
void insert_scan(mapping::HimmGrid& grid, const PlanarSensorPose& sensor, const LaserModel& laser,
                 const v1::LaserScan& scan, std::span<const std::uint8_t> ended_on_moving) {
  const double sign = sensor.mirrored ? -1.0 : 1.0;
  const auto angle_min = static_cast<float>(sign * laser.angle_min_rad);
  const auto angle_increment = static_cast<float>(sign * laser.angle_increment_rad);
  const std::span<const float> ranges(scan.ranges().data(), static_cast<std::size_t>(scan.ranges_size()));
  const auto range_min = static_cast<float>(laser.range_min_m);
  const bool all_valid = std::all_of(ranges.begin(), ranges.end(), [&](float r) { return r >= range_min; });
  if (all_valid) {
    grid.insert_scan(sensor.X_WS, angle_min, angle_increment, ranges, static_cast<float>(laser.range_max_m),
                     laser.beam_limits, ended_on_moving);
    return;
  }
  const Eigen::Vector2d origin = sensor.X_WS.position();
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    if (ranges[i] < range_min) continue;
    const Eigen::Vector2d direction_W = beam_direction_W(sensor, laser, i);
    if (!ended_on_moving.empty() && ended_on_moving[i] != 0) {
      // Cleared up to something moving, which is not marked (see HimmGrid::insert_scan).
      const mapping::BeamUse use =
          mapping::beam_use(static_cast<double>(ranges[i]), laser.range_max_m, laser.beam_limits);
      const double free_m = std::min(static_cast<double>(ranges[i]) - grid.params().cell_size_m, use.free_m);
      if (free_m > 0.0) grid.insert_ray(origin, origin + free_m * direction_W, false);
      continue;
    }
    insert_limited_ray(grid, origin, direction_W, static_cast<double>(ranges[i]), laser.range_max_m, laser.beam_limits);
  }
}

// Inserts the scan into the world's OctoMap from the laser's full 6-DoF pose X_WS = X_WB (at z = 0)
// ∘ mount, so a pitched or rolled laser maps what it sees in 3D (an upside-down mount needs no
// mirroring here: the rotation does it). Readings below range_min_m become 0, which the model skips.
void insert_scan_3d(IngestTarget& target, const geometry::Pose2& X_WB, const LaserModel& laser,
                    const v1::LaserScan& scan, std::span<const std::uint8_t> ended_on_moving) {
  const geometry::Pose3 X_WS = geometry::Pose3::from_pose2(X_WB).compose(laser.X_BS);
  target.touch(X_WS.translation().head<2>(), laser.beam_limits.reach_m(laser.range_max_m));
  std::vector<float> ranges(scan.ranges().begin(), scan.ranges().end());
  const auto range_min = static_cast<float>(laser.range_min_m);
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    // A return from something moving is left out whole: the octree keeps no trail of a walker either.
    if (ranges[i] < range_min || (!ended_on_moving.empty() && ended_on_moving[i] != 0)) ranges[i] = 0.0F;
  }
  target.octree_work.emplace_back([X_WS, angle_min = static_cast<float>(laser.angle_min_rad),
                                   angle_increment = static_cast<float>(laser.angle_increment_rad),
                                   range_max = static_cast<float>(laser.range_max_m), limits = laser.beam_limits,
                                   ranges = std::move(ranges)](mapping::OctoMapModel& octomap) {
    octomap.insert_scan(X_WS, angle_min, angle_increment, ranges, range_max, limits);
  });
}

// Feeds the scan's returns to the world's PTEM (seed 004 §4.2): the end points of the beams whose
// reading lies in [range_min_m, range_max_m) and within the laser's max_insert_range_m, placed in the
// world frame from the sensor's ground pose exactly as the grid insertion places them, with the sector
// the scan covered (centred on the middle beam, one angle increment per beam wide, out to the shorter
// of range_max_m and max_insert_range_m) for the single-scan rule.
void insert_ptem(World& world, const PlanarSensorPose& sensor, const LaserModel& laser, const v1::LaserScan& scan) {
  constexpr double kTwoPi = 2.0 * M_PI;
  const double sign = sensor.mirrored ? -1.0 : 1.0;
  const Eigen::Vector2d origin = sensor.X_WS.position();
  std::vector<Eigen::Vector2d> points_W;
  points_W.reserve(static_cast<std::size_t>(scan.ranges_size()));
  const double insert_range_m = laser.beam_limits.max_insert_range_m;
  for (int i = 0; i < scan.ranges_size(); ++i) {
    const double reading = static_cast<double>(scan.ranges(i));
    if (reading < laser.range_min_m || reading >= laser.range_max_m || reading > insert_range_m) continue;
    points_W.push_back(origin + reading * beam_direction_W(sensor, laser, static_cast<std::size_t>(i)));
  }
  const double beams = static_cast<double>(laser.beam_count);
  mapping::PtemScan ptem_scan;
  ptem_scan.stamp_s = scan.stamp_s();
  ptem_scan.p_WS = origin;
  ptem_scan.yaw_WS = sensor.X_WS.theta + sign * (laser.angle_min_rad + laser.angle_increment_rad * (beams - 1.0) / 2.0);
  ptem_scan.field_of_view_rad = std::clamp(std::abs(laser.angle_increment_rad) * beams, 1e-9, kTwoPi);
  ptem_scan.max_range_m = std::min(laser.range_max_m, insert_range_m);
  ptem_scan.points_W = points_W;
  world.insert_ptem_on_strand(ptem_scan);
}

// Flags the scan's beams whose return lies in a cluster the laser's tracker follows as moving (a person, a cart):
// empty when there is none.
std::vector<std::uint8_t> beams_ended_on_moving(World& world, const std::string& sensor_key,
                                                const PlanarSensorPose& sensor, const LaserModel& laser,
                                                const v1::LaserScan& scan) {
  const double sign = sensor.mirrored ? -1.0 : 1.0;
  const double last_beam_rad =
      laser.angle_min_rad + laser.angle_increment_rad * static_cast<double>(std::max(scan.ranges_size(), 1) - 1);
  const control::LaserArc arc{sensor.X_WS.theta, std::min(sign * laser.angle_min_rad, sign * last_beam_rad),
                              std::max(sign * laser.angle_min_rad, sign * last_beam_rad)};
  const Eigen::Vector2d origin = sensor.X_WS.position();
  const std::vector<control::TrackedObstacle> moving = world.moving_clusters_on_strand(
      sensor_key, origin, std::min(laser.range_max_m, laser.beam_limits.max_insert_range_m), arc);
  if (moving.empty()) return {};
  // A cluster's returns all lie inside its circle; the margin covers float rounding of the readings.
  constexpr double kMargin_m = 0.02;
  std::vector<std::uint8_t> flags(static_cast<std::size_t>(scan.ranges_size()), 0);
  for (int i = 0; i < scan.ranges_size(); ++i) {
    const double reading = static_cast<double>(scan.ranges(i));
    if (reading < laser.range_min_m || reading >= laser.range_max_m) continue;
    const Eigen::Vector2d end_W = origin + reading * beam_direction_W(sensor, laser, static_cast<std::size_t>(i));
    for (const control::TrackedObstacle& track : moving) {
      if ((end_W - track.centre_W).norm() <= track.radius_m + kMargin_m) {
        flags[static_cast<std::size_t>(i)] = 1;
        break;
      }
    }
  }
  return flags;
}

}  // namespace

PlanarSensorPose planar_sensor_pose(const geometry::Pose2& X_WB, const LaserModel& laser) {
  const geometry::Pose3 X_WS = geometry::Pose3::from_pose2(X_WB).compose(laser.X_BS);
  return {X_WS.to_pose2(), X_WS.transform.linear()(2, 2) < 0.0};
}

void insert_laser_scan(World& world, IngestTarget& target, const std::string& robot_id, const geometry::Pose2& X_WB,
                       const LaserModel& laser, const v1::LaserScan& scan) {
  const PlanarSensorPose sensor = planar_sensor_pose(X_WB, laser);
  insert_ptem(world, sensor, laser, scan);
  const std::vector<std::uint8_t> ended_on_moving =
      beams_ended_on_moving(world, robot_id + "/" + laser.name, sensor, laser, scan);
  insert_scan(target.grid, sensor, laser, scan, ended_on_moving);
  insert_scan_3d(target, X_WB, laser, scan, ended_on_moving);
}

// HIMM updates only the cells on each element's acoustic axis, traced from the element itself:
// tracing from the robot centre instead (seed 001 §3) shifts every obstacle by the ring's radius.
// The OctoMap gets the same axis from the element's full 6-DoF pose X_WB ∘ X_BS ∘ X_SE.
void insert_range_array(IngestTarget& target, const geometry::Pose2& X_WB, const RangeArrayModel& array,
                        const v1::RangeArray& message) {
  const geometry::Pose3 X_WS = geometry::Pose3::from_pose2(X_WB).compose(array.X_BS);
  for (std::size_t k = 0; k < array.X_SE.size(); ++k) {
    const double reading = static_cast<double>(message.ranges(static_cast<int>(k)));
    const geometry::Pose2 X_WE = planar_beam_pose(X_WB, array.X_BS, array.X_SE[k]);
    insert_beam(target.grid, X_WE, reading, array.range_min_m, array.range_max_m, array.beam_limits);
    insert_beam_3d(target, X_WS.compose(geometry::Pose3::from_pose2(array.X_SE[k])), reading, array.range_min_m,
                   array.range_max_m, array.beam_limits);
  }
}

void insert_servo_range(IngestTarget& target, const geometry::Pose2& X_WB, const ServoRangeModel& servo,
                        const v1::ServoRange& message) {
  // The servo turns the beam about the sensor frame's z axis.
  const geometry::Pose2 X_SE{0.0, 0.0, message.servo_angle_rad()};
  const geometry::Pose2 X_WE = planar_beam_pose(X_WB, servo.X_BS, X_SE);
  const auto reading = static_cast<double>(message.range_m());
  insert_beam(target.grid, X_WE, reading, servo.range_min_m, servo.range_max_m, servo.beam_limits);
  const geometry::Pose3 X_WE3 =
      geometry::Pose3::from_pose2(X_WB).compose(servo.X_BS).compose(geometry::Pose3::from_pose2(X_SE));
  insert_beam_3d(target, X_WE3, reading, servo.range_min_m, servo.range_max_m, servo.beam_limits);
}

// The 2D grid holds what the robot would hit: points between the ground and the robot's height.
// Each is ray-cast from the sensor's position on the ground, clearing the cells before it and
// marking its own. Points above the robot (overhangs it passes under) or on the ground are left
// for a 3D model.
//
// The OctoMap takes every point (floor and overhangs too), through the PCL filters the `octomap:`
// config enables, each a 3D ray from the sensor's full 6-DoF pose.
void insert_point_cloud(IngestTarget& target, const geometry::Pose2& X_WB, const RobotModel& model,
                        const PointCloudModel& cloud, const v1::PointCloud& message) {
  const geometry::Pose3 X_WS = geometry::Pose3::from_pose2(X_WB).compose(cloud.X_BS);
  const Eigen::Vector2d origin_W = X_WS.translation().head<2>();
  target.touch(origin_W, cloud.beam_limits.reach_m(cloud.range_max_m));
  const double top_m = geometry::footprint_height(model.footprint);
  // Points lower than this above the ground are the ground itself (noise on a flat floor), not obstacles.
  const double ground_band_m = target.octomap_params.terrain.ground_band_m;
  std::vector<Eigen::Vector3f> points_S;
  points_S.reserve(static_cast<std::size_t>(message.xyz_size() / 3));
  for (int i = 0; i + 2 < message.xyz_size(); i += 3) {
    points_S.emplace_back(message.xyz(i), message.xyz(i + 1), message.xyz(i + 2));
    const Eigen::Vector3d p_W = X_WS.transform * points_S.back().cast<double>();
    if (p_W.z() < ground_band_m || p_W.z() > top_m) continue;
    const Eigen::Vector2d ray_W = p_W.head<2>() - origin_W;
    const double length_m = ray_W.norm();
    if (length_m == 0.0) {
      target.grid.insert_ray(origin_W, origin_W, true);
      continue;
    }
    // A point has no "no return": every one is a return, however far.
    insert_limited_ray(target.grid, origin_W, ray_W / length_m, length_m, std::numeric_limits<double>::infinity(),
                       cloud.beam_limits);
  }
  target.octree_work.emplace_back(
      [X_WS, limits = cloud.beam_limits, points_S = std::move(points_S)](mapping::OctoMapModel& octomap) {
        octomap.insert_cloud(X_WS, points_S, limits);
      });
}

void IngestTarget::touch(const Eigen::Vector2d& p_W, double radius_m) {
  const geometry::GridGeometry cells(grid.params().cell_size_m);
  const Eigen::Vector2d reach(radius_m, radius_m);
  geometry::CellIndex lo = cells.cell_of(p_W - reach);
  geometry::CellIndex hi = cells.cell_of(p_W + reach);
  lo = {lo.ix - 1, lo.iy - 1};
  hi = {hi.ix + 1, hi.iy + 1};
  if (touched) {
    lo = {std::min(lo.ix, touched->min.ix), std::min(lo.iy, touched->min.iy)};
    hi = {std::max(hi.ix, touched->max.ix), std::max(hi.iy, touched->max.iy)};
  }
  touched = mapping::CellBox{lo, hi};
}

void insert_beam_3d(IngestTarget& target, const geometry::Pose3& X_WE, double reading_m, double range_min_m,
                    double range_max_m, const mapping::BeamLimits& limits) {
  target.touch(X_WE.translation().head<2>(), limits.reach_m(range_max_m));
  if (reading_m < range_min_m) return;
  target.octree_work.emplace_back([X_WE, reading_m, range_max_m, limits](mapping::OctoMapModel& octomap) {
    octomap.insert_ray(X_WE, reading_m, range_max_m, limits);
  });
}

geometry::Pose2 planar_beam_pose(const geometry::Pose2& X_WB, const geometry::Pose3& X_BS,
                                 const geometry::Pose2& X_SE) {
  return geometry::Pose3::from_pose2(X_WB).compose(X_BS).compose(geometry::Pose3::from_pose2(X_SE)).to_pose2();
}

void insert_beam(mapping::HimmGrid& grid, const geometry::Pose2& X_WE, double reading_m, double range_min_m,
                 double range_max_m, const mapping::BeamLimits& limits) {
  if (reading_m < range_min_m) return;
  insert_limited_ray(grid, X_WE.position(), Eigen::Vector2d(std::cos(X_WE.theta), std::sin(X_WE.theta)), reading_m,
                     range_max_m, limits);
}

void insert_limited_ray(mapping::HimmGrid& grid, const Eigen::Vector2d& origin_W, const Eigen::Vector2d& direction_W,
                        double reading_m, double range_max_m, const mapping::BeamLimits& limits) {
  const mapping::BeamUse use = mapping::beam_use(reading_m, range_max_m, limits);
  if (use.hit && use.free_m >= reading_m) {
    grid.insert_ray(origin_W, origin_W + reading_m * direction_W, true);
    return;
  }
  if (use.free_m > 0.0) grid.insert_ray(origin_W, origin_W + use.free_m * direction_W, false);
  // A ray from the end to itself marks only the end cell.
  if (use.hit) grid.insert_ray(origin_W + reading_m * direction_W, origin_W + reading_m * direction_W, true);
}

}  // namespace occgeo::service
