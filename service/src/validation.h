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

// Checks a RobotSpec and converts it; the error names the first offending field.
std::shared_ptr<const RobotModel> robot_model_from_spec(const std::string& robot_id, const v1::RobotSpec& spec,
                                                        const LimitsConfig& limits, FieldError& error);

// Checks a footprint message; prefix names the field path for errors.
std::optional<geometry::Footprint> footprint_from_proto(const v1::Footprint& footprint, const std::string& prefix,
                                                        FieldError& error);

// Checks values that need no robot state: finite pose within the coordinate limit.
std::optional<FieldError> check_odometry(const v1::Odometry& odometry, const LimitsConfig& limits);

// Checks a scan against its robot's spec: known sensor, beam count, finite non-negative ranges.
std::optional<FieldError> check_scan(const v1::LaserScan& scan, const RobotModel& model);

// Checks a query pose: finite and within the coordinate limit.
std::optional<FieldError> check_pose(const v1::Pose2D& pose, const std::string& field, const LimitsConfig& limits);

// A robot or world id: 1..64 characters of [A-Za-z0-9_.-].
bool valid_name(const std::string& name);

}  // namespace occgeo::service
