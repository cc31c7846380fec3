// Checks a RobotSpec and converts it into a RobotModel: kinematics, footprint, encoders, sensors and the behaviour and
// command units they allow.
#include "validation.h"

#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <variant>

#include "occgeo/proto/labels.h"
#include "validation_helpers.h"

namespace occgeo::service {

namespace {

// geometry's validate() names the bad member as "<Params>.<member> ..."; the RobotSpec's fields
// carry the same member names, so the error can name the client's field.
FieldError error_from_geometry(const std::invalid_argument& e, const std::string& prefix) {
  const std::string what = e.what();
  const auto dot = what.find('.');
  const auto space = what.find(' ');
  if (dot == std::string::npos || space == std::string::npos || space < dot) return field_error(prefix, what);
  return field_error(prefix + "." + what.substr(dot + 1, space - dot - 1), what);
}

bool parse_drive(const v1::Kinematics& kinematics, RobotModel& model, FieldError& error) {
  if (kinematics.has_differential()) {
    const auto& drive = kinematics.differential();
    const geometry::DifferentialDriveParams params{drive.wheel_separation_m(), drive.wheel_radius_m(),
                                                   drive.max_wheel_speed_mps()};
    try {
      geometry::validate(params);
    } catch (const std::invalid_argument& e) {
      error = error_from_geometry(e, "robot_spec.kinematics.differential");
      return false;
    }
    model.drive = params;
    return true;
  }
  if (kinematics.has_skid_steer()) {
    const auto& skid = kinematics.skid_steer();
    const geometry::SkidSteerParams params{
        skid.track_separation_m(), skid.left_sprocket_radius_m(), skid.right_sprocket_radius_m(), skid.left_slip(),
        skid.right_slip(),         skid.max_track_speed_mps()};
    try {
      geometry::validate(params);
    } catch (const std::invalid_argument& e) {
      error = error_from_geometry(e, "robot_spec.kinematics.skid_steer");
      return false;
    }
    if (!std::isfinite(skid.powertrain_time_constant_s()) || skid.powertrain_time_constant_s() < 0.0) {
      error = field_error("robot_spec.kinematics.skid_steer.powertrain_time_constant_s",
                          "must be a finite, non-negative time in seconds");
      return false;
    }
    model.drive = params;
    return true;
  }
  error = field_error("robot_spec.kinematics", "must be differential or skid_steer");
  return false;
}

bool parse_encoders(const v1::RobotSpec& spec, const LimitsConfig& limits, RobotModel& model, FieldError& error) {
  if (spec.has_initial_pose()) {
    if (auto pose_error = check_pose(spec.initial_pose(), "robot_spec.initial_pose", limits)) {
      error = *pose_error;
      return false;
    }
    model.initial_pose = {spec.initial_pose().x(), spec.initial_pose().y(),
                          geometry::wrap_angle(spec.initial_pose().theta())};
  }
  if (!spec.has_encoders()) return true;
  const auto& encoders = spec.encoders();
  // Checked before the cast to int so that a huge unsigned value cannot wrap into range.
  if (encoders.counter_bits() < 1 || encoders.counter_bits() > 64) {
    error = field_error("robot_spec.encoders.counter_bits",
                        "is " + std::to_string(encoders.counter_bits()) + "; must be between 1 and 64");
    return false;
  }
  const geometry::EncoderParams params{encoders.ticks_per_revolution(), encoders.wheel_radius_m(),
                                       encoders.wheel_separation_m(), static_cast<int>(encoders.counter_bits())};
  try {
    geometry::validate(params);
  } catch (const std::invalid_argument& e) {
    error = error_from_geometry(e, "robot_spec.encoders");
    return false;
  }
  model.encoders = params;
  return true;
}

// Minimum and maximum range of a single-beam sensor: 0 <= min < max <= the server's limit.
bool check_range_limits(double range_min_m, double range_max_m, const std::string& prefix, const LimitsConfig& limits,
                        FieldError& error) {
  if (!finite_positive(range_max_m) || range_max_m > limits.max_sensor_range_m) {
    error = field_error(prefix + ".range_max_m",
                        "must be a positive length up to " + std::to_string(limits.max_sensor_range_m) + " m");
    return false;
  }
  if (!std::isfinite(range_min_m) || range_min_m < 0 || range_min_m >= range_max_m) {
    error = field_error(prefix + ".range_min_m", "must be in [0, range_max_m)");
    return false;
  }
  return true;
}

bool finite_non_negative(double v) { return std::isfinite(v) && v >= 0.0; }

bool parse_laser(const v1::LaserSpec& laser, const std::string& prefix, const LimitsConfig& limits, LaserModel& model,
                 FieldError& error) {
  if (laser.beam_count() == 0 || laser.beam_count() > limits.max_beams) {
    error = field_error(prefix + ".beam_count", "must be between 1 and " + std::to_string(limits.max_beams));
    return false;
  }
  if (!std::isfinite(laser.angle_min_rad()) || std::abs(laser.angle_min_rad()) > 2 * M_PI) {
    error = field_error(prefix + ".angle_min_rad", "must be a finite angle within ±2π");
    return false;
  }
  if (!std::isfinite(laser.angle_increment_rad()) || laser.angle_increment_rad() == 0.0 ||
      std::abs(laser.angle_increment_rad() * (laser.beam_count() - 1)) > 2 * M_PI + 1e-9) {
    error = field_error(prefix + ".angle_increment_rad", "must be non-zero and span at most 2π");
    return false;
  }
  if (!check_range_limits(laser.range_min_m(), laser.range_max_m(), prefix, limits, error)) return false;
  model.angle_min_rad = laser.angle_min_rad();
  model.angle_increment_rad = laser.angle_increment_rad();
  model.beam_count = laser.beam_count();
  model.range_min_m = laser.range_min_m();
  model.range_max_m = laser.range_max_m();
  return true;
}

bool parse_range_array(const v1::RangeArraySpec& array, const std::string& prefix, const LimitsConfig& limits,
                       RangeArrayModel& model, FieldError& error) {
  // Every element is one beam per firing, so the laser's beam limit bounds the work per message.
  if (array.elements_size() == 0 || static_cast<std::uint32_t>(array.elements_size()) > limits.max_beams) {
    error = field_error(prefix + ".elements", "must have between 1 and " + std::to_string(limits.max_beams) +
                                                  " elements, has " + std::to_string(array.elements_size()));
    return false;
  }
  for (int k = 0; k < array.elements_size(); ++k) {
    const auto& element = array.elements(k);
    const std::string field = prefix + ".elements[" + std::to_string(k) + "]";
    // An element is part of the sensor: it cannot sit farther from it than any sensor can see.
    for (const auto& [name, value] : {std::pair{".x", element.x()}, std::pair{".y", element.y()}}) {
      if (!std::isfinite(value) || std::abs(value) > limits.max_sensor_range_m) {
        error = field_error(field + name, "must be finite and within ±" + std::to_string(limits.max_sensor_range_m) +
                                              " m of the sensor frame");
        return false;
      }
    }
    if (!std::isfinite(element.theta())) {
      error = field_error(field + ".theta", "must be finite");
      return false;
    }
    model.X_SE.push_back({element.x(), element.y(), geometry::wrap_angle(element.theta())});
  }
  if (!std::isfinite(array.beam_width_rad()) || array.beam_width_rad() <= 0.0 || array.beam_width_rad() > M_PI) {
    error = field_error(prefix + ".beam_width_rad", "must be an angle in (0, π]");
    return false;
  }
  if (!check_range_limits(array.range_min_m(), array.range_max_m(), prefix, limits, error)) return false;
  if (!finite_non_negative(array.period_s())) {
    error = field_error(prefix + ".period_s", "must be a finite, non-negative time in seconds");
    return false;
  }
  model.beam_width_rad = array.beam_width_rad();
  model.range_min_m = array.range_min_m();
  model.range_max_m = array.range_max_m();
  model.period_s = array.period_s();
  return true;
}

bool parse_servo_range(const v1::ServoRangeSpec& servo, const std::string& prefix, const LimitsConfig& limits,
                       ServoRangeModel& model, FieldError& error) {
  if (!std::isfinite(servo.servo_min_rad()) || std::abs(servo.servo_min_rad()) > 2 * M_PI) {
    error = field_error(prefix + ".servo_min_rad", "must be a finite angle within ±2π");
    return false;
  }
  if (!std::isfinite(servo.servo_max_rad()) || std::abs(servo.servo_max_rad()) > 2 * M_PI ||
      servo.servo_max_rad() <= servo.servo_min_rad()) {
    error = field_error(prefix + ".servo_max_rad", "must be a finite angle within ±2π, above servo_min_rad");
    return false;
  }
  if (!finite_positive(servo.servo_step_rad()) || servo.servo_step_rad() > 2 * M_PI) {
    error = field_error(prefix + ".servo_step_rad", "must be a positive angle up to 2π");
    return false;
  }
  if (!finite_non_negative(servo.step_period_s())) {
    error = field_error(prefix + ".step_period_s", "must be a finite, non-negative time in seconds");
    return false;
  }
  if (!check_range_limits(servo.range_min_m(), servo.range_max_m(), prefix, limits, error)) return false;
  model.servo_min_rad = servo.servo_min_rad();
  model.servo_max_rad = servo.servo_max_rad();
  model.servo_step_rad = servo.servo_step_rad();
  model.step_period_s = servo.step_period_s();
  model.range_min_m = servo.range_min_m();
  model.range_max_m = servo.range_max_m();
  return true;
}

bool parse_point_cloud(const v1::PointCloudSpec& cloud, const std::string& prefix, const LimitsConfig& limits,
                       PointCloudModel& model, FieldError& error) {
  if (!finite_positive(cloud.range_max_m()) || cloud.range_max_m() > limits.max_sensor_range_m) {
    error = field_error(prefix + ".range_max_m",
                        "must be a positive length up to " + std::to_string(limits.max_sensor_range_m) + " m");
    return false;
  }
  if (cloud.max_points() > limits.max_point_cloud_points) {
    error = field_error(prefix + ".max_points", "is " + std::to_string(cloud.max_points()) +
                                                    "; this server takes at most " +
                                                    std::to_string(limits.max_point_cloud_points) + " points");
    return false;
  }
  model.range_max_m = cloud.range_max_m();
  model.max_points = cloud.max_points() == 0 ? limits.max_point_cloud_points : cloud.max_points();
  return true;
}

// SensorSpec.ranges.no_return_clear_m of a range array (sonar ring) that leaves it unset, whatever the config's
// `sensors:` says.
constexpr double kRangeArrayNoReturnClear_m = 0.0;

// A sensor's SensorSpec.ranges over the server's defaults; each given length finite and >= 0 (the insert range > 0).
bool parse_sensor_ranges(const v1::SensorSpec& sensor, const std::string& prefix,
                         const mapping::BeamLimits& sensor_defaults, mapping::BeamLimits& limits, FieldError& error) {
  limits = sensor_defaults;
  if (!sensor.has_ranges()) return true;
  const v1::SensorRanges& ranges = sensor.ranges();
  const auto take = [&](bool given, double value, const char* name, bool zero_allowed, double& out) {
    if (!given) return true;
    if (!std::isfinite(value) || value < 0.0 || (!zero_allowed && value == 0.0)) {
      error = field_error(prefix + ".ranges." + name, "is " + std::to_string(value) + "; must be a finite length " +
                                                          (zero_allowed ? ">= 0" : "> 0") + " in metres");
      return false;
    }
    out = value;
    return true;
  };
  return take(ranges.has_max_insert_range_m(), ranges.max_insert_range_m(), "max_insert_range_m", false,
              limits.max_insert_range_m) &&
         take(ranges.has_max_free_range_m(), ranges.max_free_range_m(), "max_free_range_m", true,
              limits.max_free_range_m) &&
         take(ranges.has_no_return_clear_m(), ranges.no_return_clear_m(), "no_return_clear_m", true,
              limits.no_return_clear_m);
}

}  // namespace

std::shared_ptr<const RobotModel> robot_model_from_spec(const std::string& robot_id, const v1::RobotSpec& spec,
                                                        const LimitsConfig& limits, FieldError& error,
                                                        const mapping::BeamLimits& sensor_defaults) {
  auto model = std::make_shared<RobotModel>();
  model->id = robot_id;
  model->model = spec.model();
  model->spec = spec;

  if (!parse_drive(spec.kinematics(), *model, error)) return nullptr;

  auto footprint = footprint_from_proto(spec.footprint(), "robot_spec.footprint", error);
  if (!footprint) return nullptr;
  model->footprint = *footprint;

  if (!parse_encoders(spec, limits, *model, error)) return nullptr;

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
    if (model->has_sensor(sensor.name())) {
      error = field_error(prefix + ".name", "'" + sensor.name() + "' is used by an earlier sensor");
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
    const geometry::Pose3 X_BS = geometry::Pose3::from_xyz_rpy(
        mount.position().x(), mount.position().y(), mount.position().z(), mount.roll(), mount.pitch(), mount.yaw());
    mapping::BeamLimits beam_limits;
    mapping::BeamLimits defaults = sensor_defaults;
    // A sonar element that hears nothing has mostly met a wall obliquely (its echo is specular), not open space: by
    // default its silence carves nothing (ROS's range_sensor_layer leaves clear_on_max_reading off for the same
    // reason), or the walls a ring drives along are erased by the elements that graze them.
    if (sensor.model_case() == v1::SensorSpec::kRangeArray) defaults.no_return_clear_m = kRangeArrayNoReturnClear_m;
    if (!parse_sensor_ranges(sensor, prefix, defaults, beam_limits, error)) return nullptr;
    switch (sensor.model_case()) {
      case v1::SensorSpec::kLaser: {
        LaserModel laser;
        laser.name = sensor.name();
        laser.X_BS = X_BS;
        laser.beam_limits = beam_limits;
        if (!parse_laser(sensor.laser(), prefix + ".laser", limits, laser, error)) return nullptr;
        model->lasers.push_back(std::move(laser));
        break;
      }
      case v1::SensorSpec::kRangeArray: {
        RangeArrayModel array;
        array.name = sensor.name();
        array.X_BS = X_BS;
        array.beam_limits = beam_limits;
        if (!parse_range_array(sensor.range_array(), prefix + ".range_array", limits, array, error)) return nullptr;
        model->range_arrays.push_back(std::move(array));
        break;
      }
      case v1::SensorSpec::kServoRange: {
        ServoRangeModel servo;
        servo.name = sensor.name();
        servo.X_BS = X_BS;
        servo.beam_limits = beam_limits;
        if (!parse_servo_range(sensor.servo_range(), prefix + ".servo_range", limits, servo, error)) return nullptr;
        model->servo_ranges.push_back(std::move(servo));
        break;
      }
      case v1::SensorSpec::kPointCloud: {
        PointCloudModel cloud;
        cloud.name = sensor.name();
        cloud.X_BS = X_BS;
        cloud.beam_limits = beam_limits;
        if (!parse_point_cloud(sensor.point_cloud(), prefix + ".point_cloud", limits, cloud, error)) return nullptr;
        model->point_clouds.push_back(std::move(cloud));
        break;
      }
      default:
        error = field_error(prefix, "must be a laser, range_array, servo_range or point_cloud");
        return nullptr;
    }
  }
  const v1::Behaviour default_behaviour = spec.default_behaviour();
  if (default_behaviour != v1::BEHAVIOUR_UNSPECIFIED) {
    if (default_behaviour != v1::BEHAVIOUR_BEARCAT && default_behaviour != v1::BEHAVIOUR_WANDER &&
        default_behaviour != v1::BEHAVIOUR_STOP) {
      error = field_error("robot_spec.default_behaviour",
                          "must be BEHAVIOUR_BEARCAT, BEHAVIOUR_WANDER or BEHAVIOUR_STOP, not " +
                              (v1::Behaviour_IsValid(default_behaviour) ? v1::Behaviour_Name(default_behaviour)
                                                                        : std::to_string(default_behaviour)));
      return nullptr;
    }
    if (const std::optional<std::string> missing = missing_sensor_for(default_behaviour, *model)) {
      error = field_error("robot_spec.default_behaviour", *missing);
      return nullptr;
    }
  }
  if (spec.command_units() == v1::COMMAND_UNITS_ACTIVITYBOT_TICKS) {
    if (!model->encoders || !std::holds_alternative<geometry::DifferentialDriveParams>(model->drive)) {
      error = field_error("robot_spec.command_units",
                          "ActivityBot ticks need a differential drive and the spec's encoders (robot_spec.encoders)");
      return nullptr;
    }
  } else if (spec.command_units() != v1::COMMAND_UNITS_SI) {
    error =
        field_error("robot_spec.command_units", "is " + std::to_string(spec.command_units()) +
                                                    "; must be COMMAND_UNITS_SI or COMMAND_UNITS_ACTIVITYBOT_TICKS");
    return nullptr;
  }
  return model;
}

std::optional<std::string> missing_sensor_for(v1::Behaviour behaviour, const RobotModel& model) {
  const bool laser = !model.lasers.empty();
  if (behaviour == v1::BEHAVIOUR_BEARCAT || behaviour == v1::BEHAVIOUR_BEARCAT_SEED) {
    if (!laser) {
      return "'" + proto::behaviour_label(behaviour) + "' steers by a laser scan and robot '" + model.id +
             "' has no laser";
    }
  } else if (behaviour == v1::BEHAVIOUR_WANDER) {
    if (!laser && model.range_arrays.empty()) {
      return "'wander' avoids what a laser or a range array sees and robot '" + model.id +
             "' has neither (no range sensor to wander by)";
    }
  } else if (behaviour == v1::BEHAVIOUR_GOTO) {
    if (!laser && model.servo_ranges.empty()) {
      return "'goto' (PointBug) reads a laser scan or a servo-swept beam and robot '" + model.id + "' has neither";
    }
  }
  return std::nullopt;
}

}  // namespace occgeo::service
