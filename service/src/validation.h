#pragma once

#include <memory>
#include <optional>
#include <string>

#include "core.h"
#include "occgeo/v1/query.pb.h"
#include "occgeo/v1/sensors.pb.h"

namespace occgeo::service {

// A client's data is wrong: which field, and why.
struct FieldError {
  std::string field;
  std::string message;
};

// Checks a RobotSpec and converts it; the error names the first offending field. Each sensor's beam_limits are its
// SensorSpec.ranges, fields left unset taken from sensor_defaults (the config's `sensors:`), except a range array's
// no_return_clear_m, which defaults to 0 (a sonar's silence is mostly a specular miss).
std::shared_ptr<const RobotModel> robot_model_from_spec(
    const std::string& robot_id, const v1::RobotSpec& spec, const LimitsConfig& limits, FieldError& error,
    const mapping::BeamLimits& sensor_defaults = default_sensor_beam_limits());

// Why the robot cannot run the behaviour (a sensor it needs is missing), or nullopt when it can.
std::optional<std::string> missing_sensor_for(v1::Behaviour behaviour, const RobotModel& model);

// Checks a footprint message; prefix names the field path for errors.
std::optional<geometry::Footprint> footprint_from_proto(const v1::Footprint& footprint, const std::string& prefix,
                                                        FieldError& error);

// Checks values that need no robot state: finite pose within the coordinate limit.
std::optional<FieldError> check_odometry(const v1::Odometry& odometry, const LimitsConfig& limits);

// Checks a scan against its robot's spec: known sensor, beam count, finite non-negative ranges.
std::optional<FieldError> check_scan(const v1::LaserScan& scan, const RobotModel& model);

// The octree voxels a sensor message's rays would touch at most: per ray, the length it carves (cut by the sensor's
// beam_limits and the octree's max_range_m, as mapping::beam_use says) over the resolution, plus its end voxel. For
// an already checked scan or cloud of the robot's spec.
std::uint64_t scan_voxel_estimate(const v1::LaserScan& scan, const LaserModel& laser, double octree_max_range_m,
                                  double resolution_m);
std::uint64_t cloud_voxel_estimate(const v1::PointCloud& message, const PointCloudModel& cloud,
                                   double octree_max_range_m, double resolution_m);
// An error naming limits.max_scan_voxels when `voxels` exceeds it (field: the message's ranges or points).
std::optional<FieldError> check_voxel_budget(std::uint64_t voxels, std::uint64_t limit, const std::string& field);

// How far outside the spec's [servo_min_rad, servo_max_rad] a reported servo angle may be, radians:
// drivers compute angles as min + k * step in floating point and may round past the end.
inline constexpr double kServoAngleTolerance_rad = 1e-4;

// Checks a range array against its robot's spec: known sensor, one reading per element, finite
// non-negative ranges.
std::optional<FieldError> check_range_array(const v1::RangeArray& message, const RobotModel& model);

// Checks a servo range reading: known sensor, servo angle within the spec's limits, finite
// non-negative range.
std::optional<FieldError> check_servo_range(const v1::ServoRange& message, const RobotModel& model);

// Checks wheel encoder counts: the robot declares encoders and the stamp is finite.
std::optional<FieldError> check_wheel_encoders(const v1::WheelEncoders& message, const RobotModel& model);

// Checks a point cloud: known sensor, whole finite triples, no more points than the sensor's
// limit, none beyond its range.
std::optional<FieldError> check_point_cloud(const v1::PointCloud& message, const RobotModel& model);

// Checks a query pose: finite and within the coordinate limit.
std::optional<FieldError> check_pose(const v1::Pose2D& pose, const std::string& field, const LimitsConfig& limits);

// A robot or world id: 1..64 characters of [A-Za-z0-9_.-].
bool valid_name(const std::string& name);

}  // namespace occgeo::service
