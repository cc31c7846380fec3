// Checks a driver's sensor messages (odometry, laser scans, range arrays, servo ranges, wheel encoders, point clouds)
// against its robot's spec, and the octree work a scan or cloud would cost.
#include "validation.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "validation_helpers.h"

namespace occgeo::service {

std::optional<FieldError> check_odometry(const v1::Odometry& odometry, const LimitsConfig& limits) {
  if (!std::isfinite(odometry.stamp_s())) return field_error("odometry.stamp_s", "must be finite");
  if (!odometry.has_pose()) return field_error("odometry.pose", "is required");
  if (auto error = check_pose(odometry.pose(), "odometry.pose", limits)) return error;
  if (!std::isfinite(odometry.linear_mps())) return field_error("odometry.linear_mps", "must be finite");
  if (!std::isfinite(odometry.angular_radps())) return field_error("odometry.angular_radps", "must be finite");
  return std::nullopt;
}

std::optional<FieldError> check_scan(const v1::LaserScan& scan, const RobotModel& model) {
  const LaserModel* laser = model.find_laser(scan.sensor());
  if (laser == nullptr) {
    return field_error("laser_scan.sensor", "'" + scan.sensor() + "' is not a laser in robot '" + model.id + "'s spec");
  }
  if (!std::isfinite(scan.stamp_s())) return field_error("laser_scan.stamp_s", "must be finite");
  if (static_cast<std::uint32_t>(scan.ranges_size()) != laser->beam_count) {
    return field_error("laser_scan.ranges", "has " + std::to_string(scan.ranges_size()) + " beams but sensor '" +
                                                laser->name + "' declares " + std::to_string(laser->beam_count));
  }
  for (int i = 0; i < scan.ranges_size(); ++i) {
    const float range = scan.ranges(i);
    if (!std::isfinite(range) || range < 0.0F) {
      return field_error("laser_scan.ranges[" + std::to_string(i) + "]",
                         "is " + std::to_string(range) + "; ranges must be finite and non-negative metres");
    }
  }
  return std::nullopt;
}

std::uint64_t scan_voxel_estimate(const v1::LaserScan& scan, const LaserModel& laser, double octree_max_range_m,
                                  double resolution_m) {
  // The lengths the octree carves (OctoMapModel::insert_scan), plus one voxel per beam for its end.
  const mapping::BeamLimits limits = laser.beam_limits.capped(octree_max_range_m);
  std::uint64_t voxels = 0;
  for (const float range : scan.ranges()) {
    const double length_m = mapping::beam_use(static_cast<double>(range), laser.range_max_m, limits).free_m;
    voxels += static_cast<std::uint64_t>(std::ceil(length_m / resolution_m)) + 1;
  }
  return voxels;
}

std::uint64_t cloud_voxel_estimate(const v1::PointCloud& message, const PointCloudModel& cloud,
                                   double octree_max_range_m, double resolution_m) {
  const mapping::BeamLimits limits = cloud.beam_limits.capped(octree_max_range_m);
  std::uint64_t voxels = 0;
  for (int i = 0; i + 2 < message.xyz_size(); i += 3) {
    const double length_m =
        mapping::beam_use(Eigen::Vector3d(message.xyz(i), message.xyz(i + 1), message.xyz(i + 2)).norm(),
                          std::numeric_limits<double>::infinity(), limits)
            .free_m;
    voxels += static_cast<std::uint64_t>(std::ceil(length_m / resolution_m)) + 1;
  }
  return voxels;
}

std::optional<FieldError> check_voxel_budget(std::uint64_t voxels, std::uint64_t limit, const std::string& field) {
  if (voxels <= limit) return std::nullopt;
  return field_error(field, "would touch about " + std::to_string(voxels) +
                                " octree voxels, more than limits.max_scan_voxels (" + std::to_string(limit) +
                                "); send fewer or shorter rays, or raise the limit");
}

namespace {

// Every sensor message's ranges: finite and non-negative metres, each one named when it is not.
std::optional<FieldError> check_ranges(const google::protobuf::RepeatedField<float>& ranges, const std::string& field) {
  for (int i = 0; i < ranges.size(); ++i) {
    const float range = ranges.Get(i);
    if (!std::isfinite(range) || range < 0.0F) {
      return field_error(field + "[" + std::to_string(i) + "]",
                         "is " + std::to_string(range) + "; ranges must be finite and non-negative metres");
    }
  }
  return std::nullopt;
}

}  // namespace

std::optional<FieldError> check_range_array(const v1::RangeArray& message, const RobotModel& model) {
  const RangeArrayModel* array = model.find_range_array(message.sensor());
  if (array == nullptr) {
    return field_error("range_array.sensor",
                       "'" + message.sensor() + "' is not a range array in robot '" + model.id + "'s spec");
  }
  if (!std::isfinite(message.stamp_s())) return field_error("range_array.stamp_s", "must be finite");
  if (static_cast<std::size_t>(message.ranges_size()) != array->X_SE.size()) {
    return field_error("range_array.ranges", "has " + std::to_string(message.ranges_size()) + " readings but sensor '" +
                                                 array->name + "' declares " + std::to_string(array->X_SE.size()) +
                                                 " elements");
  }
  return check_ranges(message.ranges(), "range_array.ranges");
}

std::optional<FieldError> check_servo_range(const v1::ServoRange& message, const RobotModel& model) {
  const ServoRangeModel* servo = model.find_servo_range(message.sensor());
  if (servo == nullptr) {
    return field_error("servo_range.sensor",
                       "'" + message.sensor() + "' is not a servo range sensor in robot '" + model.id + "'s spec");
  }
  if (!std::isfinite(message.stamp_s())) return field_error("servo_range.stamp_s", "must be finite");
  const double angle = message.servo_angle_rad();
  if (!std::isfinite(angle) || angle < servo->servo_min_rad - kServoAngleTolerance_rad ||
      angle > servo->servo_max_rad + kServoAngleTolerance_rad) {
    return field_error("servo_range.servo_angle_rad", "is " + std::to_string(angle) + "; sensor '" + servo->name +
                                                          "' turns within [" + std::to_string(servo->servo_min_rad) +
                                                          ", " + std::to_string(servo->servo_max_rad) + "] rad");
  }
  const float range = message.range_m();
  if (!std::isfinite(range) || range < 0.0F) {
    return field_error("servo_range.range_m",
                       "is " + std::to_string(range) + "; ranges must be finite and non-negative metres");
  }
  return std::nullopt;
}

std::optional<FieldError> check_wheel_encoders(const v1::WheelEncoders& message, const RobotModel& model) {
  if (!model.encoders) {
    return field_error("wheel_encoders",
                       "robot '" + model.id + "'s spec declares no encoders (set robot_spec.encoders to send ticks)");
  }
  if (!std::isfinite(message.stamp_s())) return field_error("wheel_encoders.stamp_s", "must be finite");
  return std::nullopt;
}

std::optional<FieldError> check_point_cloud(const v1::PointCloud& message, const RobotModel& model) {
  const PointCloudModel* cloud = model.find_point_cloud(message.sensor());
  if (cloud == nullptr) {
    return field_error("point_cloud.sensor",
                       "'" + message.sensor() + "' is not a point cloud sensor in robot '" + model.id + "'s spec");
  }
  if (!std::isfinite(message.stamp_s())) return field_error("point_cloud.stamp_s", "must be finite");
  const auto values = static_cast<std::size_t>(message.xyz_size());
  if (values % 3 != 0) {
    return field_error("point_cloud.xyz", "has " + std::to_string(values) + " values, not a multiple of 3");
  }
  if (values / 3 > cloud->max_points) {
    return field_error("point_cloud.xyz", "has " + std::to_string(values / 3) + " points; sensor '" + cloud->name +
                                              "' takes at most " + std::to_string(cloud->max_points));
  }
  const double range_max_squared = cloud->range_max_m * cloud->range_max_m;
  for (std::size_t i = 0; i < values; i += 3) {
    const Eigen::Vector3d point(message.xyz(static_cast<int>(i)), message.xyz(static_cast<int>(i + 1)),
                                message.xyz(static_cast<int>(i + 2)));
    for (std::size_t axis = 0; axis < 3; ++axis) {
      if (!std::isfinite(point[static_cast<Eigen::Index>(axis)])) {
        return field_error("point_cloud.xyz[" + std::to_string(i + axis) + "]",
                           "is " + std::to_string(point[static_cast<Eigen::Index>(axis)]) + "; must be finite metres");
      }
    }
    if (point.squaredNorm() > range_max_squared) {
      return field_error("point_cloud.xyz[" + std::to_string(i) + "]",
                         "point " + std::to_string(i / 3) + " is " + std::to_string(point.norm()) +
                             " m from the sensor, beyond its range_max_m " + std::to_string(cloud->range_max_m));
    }
  }
  return std::nullopt;
}

}  // namespace occgeo::service
