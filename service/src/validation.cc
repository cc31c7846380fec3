#include "validation.h"

#include <cmath>

namespace occgeo::service {

namespace {

bool finite_positive(double v) { return std::isfinite(v) && v > 0.0; }

FieldError field_error(std::string field, std::string message) { return {std::move(field), std::move(message)}; }

}  // namespace

bool valid_name(const std::string& name) {
  if (name.empty() || name.size() > 64) return false;
  for (const char c : name) {
    const bool ok =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-' || c == '.';
    if (!ok) return false;
  }
  return true;
}

std::optional<geometry::Footprint> footprint_from_proto(const v1::Footprint& footprint, const std::string& prefix,
                                                        FieldError& error) {
  if (footprint.has_box()) {
    const auto& box = footprint.box();
    const std::pair<const char*, double> lengths[] = {
        {".box.length_m", box.length_m()}, {".box.width_m", box.width_m()}, {".box.height_m", box.height_m()}};
    for (const auto& [name, value] : lengths) {
      if (!finite_positive(value)) {
        error = field_error(prefix + name, "must be a positive length");
        return std::nullopt;
      }
    }
    if (!std::isfinite(box.center_x_m())) {
      error = field_error(prefix + ".box.center_x_m", "must be finite");
      return std::nullopt;
    }
    return geometry::BoxFootprint{box.length_m(), box.width_m(), box.height_m(), box.center_x_m()};
  }
  if (footprint.has_cylinder()) {
    const auto& cylinder = footprint.cylinder();
    if (!finite_positive(cylinder.radius_m())) {
      error = field_error(prefix + ".cylinder.radius_m", "must be a positive length");
    } else if (!finite_positive(cylinder.height_m())) {
      error = field_error(prefix + ".cylinder.height_m", "must be a positive length");
    } else {
      return geometry::CylinderFootprint{cylinder.radius_m(), cylinder.height_m()};
    }
    return std::nullopt;
  }
  error = field_error(prefix, "must be a box or a cylinder");
  return std::nullopt;
}

std::shared_ptr<const RobotModel> robot_model_from_spec(const std::string& robot_id, const v1::RobotSpec& spec,
                                                        const LimitsConfig& limits, FieldError& error) {
  auto model = std::make_shared<RobotModel>();
  model->id = robot_id;
  model->model = spec.model();
  model->spec = spec;

  if (!spec.kinematics().has_differential()) {
    error = field_error("robot_spec.kinematics", "must be differential (the only model this server version knows)");
    return nullptr;
  }
  const auto& drive = spec.kinematics().differential();
  if (!finite_positive(drive.wheel_separation_m())) {
    error = field_error("robot_spec.kinematics.differential.wheel_separation_m", "must be a positive length");
    return nullptr;
  }
  if (!finite_positive(drive.wheel_radius_m())) {
    error = field_error("robot_spec.kinematics.differential.wheel_radius_m", "must be a positive length");
    return nullptr;
  }
  if (!finite_positive(drive.max_wheel_speed_mps())) {
    error = field_error("robot_spec.kinematics.differential.max_wheel_speed_mps", "must be a positive speed");
    return nullptr;
  }
  model->drive = {drive.wheel_separation_m(), drive.wheel_radius_m(), drive.max_wheel_speed_mps()};

  auto footprint = footprint_from_proto(spec.footprint(), "robot_spec.footprint", error);
  if (!footprint) return nullptr;
  model->footprint = *footprint;

  if (spec.sensors_size() == 0) {
    error = field_error("robot_spec.sensors", "must declare at least one sensor");
    return nullptr;
  }
  for (int i = 0; i < spec.sensors_size(); ++i) {
    const auto& sensor = spec.sensors(i);
    const std::string prefix = "robot_spec.sensors[" + std::to_string(i) + "]";
    if (sensor.name().empty()) {
      error = field_error(prefix + ".name", "must not be empty");
      return nullptr;
    }
    if (model->find_laser(sensor.name()) != nullptr) {
      error = field_error(prefix + ".name", "'" + sensor.name() + "' is used by an earlier sensor");
      return nullptr;
    }
    if (!sensor.has_laser()) {
      error = field_error(prefix, "must be a laser (the only sensor model this server version knows)");
      return nullptr;
    }
    const auto& mount = sensor.mount();
    for (const double v :
         {mount.position().x(), mount.position().y(), mount.position().z(), mount.roll(), mount.pitch(), mount.yaw()}) {
      if (!std::isfinite(v)) {
        error = field_error(prefix + ".mount", "must be finite");
        return nullptr;
      }
    }
    const auto& laser = sensor.laser();
    if (laser.beam_count() == 0 || laser.beam_count() > limits.max_beams) {
      error = field_error(prefix + ".laser.beam_count", "must be between 1 and " + std::to_string(limits.max_beams));
      return nullptr;
    }
    if (!std::isfinite(laser.angle_min_rad()) || std::abs(laser.angle_min_rad()) > 2 * M_PI) {
      error = field_error(prefix + ".laser.angle_min_rad", "must be a finite angle within ±2π");
      return nullptr;
    }
    if (!std::isfinite(laser.angle_increment_rad()) || laser.angle_increment_rad() == 0.0 ||
        std::abs(laser.angle_increment_rad() * (laser.beam_count() - 1)) > 2 * M_PI + 1e-9) {
      error = field_error(prefix + ".laser.angle_increment_rad", "must be non-zero and span at most 2π");
      return nullptr;
    }
    if (!finite_positive(laser.range_max_m()) || laser.range_max_m() > limits.max_sensor_range_m) {
      error = field_error(prefix + ".laser.range_max_m",
                          "must be a positive length up to " + std::to_string(limits.max_sensor_range_m) + " m");
      return nullptr;
    }
    if (!std::isfinite(laser.range_min_m()) || laser.range_min_m() < 0 || laser.range_min_m() >= laser.range_max_m()) {
      error = field_error(prefix + ".laser.range_min_m", "must be in [0, range_max_m)");
      return nullptr;
    }
    LaserModel laser_model;
    laser_model.name = sensor.name();
    laser_model.X_BS = geometry::Pose3::from_xyz_rpy(mount.position().x(), mount.position().y(), mount.position().z(),
                                                     mount.roll(), mount.pitch(), mount.yaw());
    laser_model.angle_min_rad = laser.angle_min_rad();
    laser_model.angle_increment_rad = laser.angle_increment_rad();
    laser_model.beam_count = laser.beam_count();
    laser_model.range_min_m = laser.range_min_m();
    laser_model.range_max_m = laser.range_max_m();
    model->lasers.push_back(std::move(laser_model));
  }
  return model;
}

std::optional<FieldError> check_pose(const v1::Pose2D& pose, const std::string& field, const LimitsConfig& limits) {
  if (!std::isfinite(pose.x()) || std::abs(pose.x()) > limits.max_abs_coordinate_m) {
    return field_error(field + ".x",
                       "must be finite and within ±" + std::to_string(limits.max_abs_coordinate_m) + " m");
  }
  if (!std::isfinite(pose.y()) || std::abs(pose.y()) > limits.max_abs_coordinate_m) {
    return field_error(field + ".y",
                       "must be finite and within ±" + std::to_string(limits.max_abs_coordinate_m) + " m");
  }
  if (!std::isfinite(pose.theta())) return field_error(field + ".theta", "must be finite");
  return std::nullopt;
}

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

}  // namespace occgeo::service
