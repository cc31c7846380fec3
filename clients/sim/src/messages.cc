#include "occgeo/sim/messages.h"
#include "occgeo/proto/protocol.h"

#include <algorithm>
#include <cmath>
#include <variant>

namespace occgeo::sim {

v1::Hello make_driver_hello(const std::string& robot_id, const std::string& world_name) {
  v1::Hello hello;
  hello.set_protocol_version(occgeo::proto::kProtocolVersion);
  hello.set_role(v1::ROLE_DRIVER);
  hello.set_robot_id(robot_id);
  hello.set_world(world_name);
  hello.set_client_name("occgeo-sim");
  return hello;
}

namespace {

void set_mount(v1::SensorSpec& sensor, const geometry::Pose2& X_BS, double height_m) {
  v1::Pose3D& mount = *sensor.mutable_mount();
  mount.mutable_position()->set_x(X_BS.x);
  mount.mutable_position()->set_y(X_BS.y);
  mount.mutable_position()->set_z(height_m);
  mount.set_yaw(X_BS.theta);
}

void add_sensor(v1::RobotSpec& spec, const LaserPreset& laser) {
  v1::SensorSpec& sensor = *spec.add_sensors();
  sensor.set_name(laser.name);
  set_mount(sensor, laser.X_BS, laser.mount_height_m);
  v1::LaserSpec& laser_spec = *sensor.mutable_laser();
  laser_spec.set_angle_min_rad(laser.angle_min_rad);
  laser_spec.set_angle_increment_rad(laser.angle_increment_rad);
  laser_spec.set_beam_count(laser.beam_count);
  laser_spec.set_range_min_m(laser.range_min_m);
  laser_spec.set_range_max_m(laser.range_max_m);
  laser_spec.set_scan_period_s(laser.scan_period_s);
}

void add_sensor(v1::RobotSpec& spec, const RangeArrayPreset& array) {
  v1::SensorSpec& sensor = *spec.add_sensors();
  sensor.set_name(array.name);
  set_mount(sensor, array.X_BS, array.mount_height_m);
  v1::RangeArraySpec& array_spec = *sensor.mutable_range_array();
  for (const geometry::Pose2& X_SE : array.elements) {
    v1::Pose2D& element = *array_spec.add_elements();
    element.set_x(X_SE.x);
    element.set_y(X_SE.y);
    element.set_theta(X_SE.theta);
  }
  array_spec.set_beam_width_rad(array.beam_width_rad);
  array_spec.set_range_min_m(array.range_min_m);
  array_spec.set_range_max_m(array.range_max_m);
  array_spec.set_period_s(array.period_s);
}

void add_sensor(v1::RobotSpec& spec, const ServoRangePreset& servo) {
  v1::SensorSpec& sensor = *spec.add_sensors();
  sensor.set_name(servo.name);
  set_mount(sensor, servo.X_BS, servo.mount_height_m);
  v1::ServoRangeSpec& servo_spec = *sensor.mutable_servo_range();
  servo_spec.set_servo_min_rad(servo.servo_min_rad);
  servo_spec.set_servo_max_rad(servo.servo_max_rad);
  servo_spec.set_servo_step_rad(servo.servo_step_rad);
  servo_spec.set_step_period_s(servo.step_period_s);
  servo_spec.set_range_min_m(servo.range_min_m);
  servo_spec.set_range_max_m(servo.range_max_m);
}

void add_sensor(v1::RobotSpec& spec, const DepthSensorPreset& depth) {
  v1::SensorSpec& sensor = *spec.add_sensors();
  sensor.set_name(depth.name);
  // Roll, pitch and yaw of the mount in the order Pose3D composes them (yaw, then pitch, then roll).
  const Eigen::Matrix3d R = depth.X_BS.transform.linear();
  v1::Pose3D& mount = *sensor.mutable_mount();
  const Eigen::Vector3d t = depth.X_BS.translation();
  mount.mutable_position()->set_x(t.x());
  mount.mutable_position()->set_y(t.y());
  mount.mutable_position()->set_z(t.z());
  mount.set_yaw(std::atan2(R(1, 0), R(0, 0)));
  mount.set_pitch(std::asin(std::clamp(-R(2, 0), -1.0, 1.0)));
  mount.set_roll(std::atan2(R(2, 1), R(2, 2)));
  v1::PointCloudSpec& cloud = *sensor.mutable_point_cloud();
  cloud.set_range_max_m(depth.range_max_m);
  cloud.set_max_points(depth.rows * depth.columns);
}

void set_kinematics(v1::RobotSpec& spec, const geometry::DifferentialDriveParams& params) {
  v1::DifferentialDrive& drive = *spec.mutable_kinematics()->mutable_differential();
  drive.set_wheel_separation_m(params.wheel_separation_m);
  drive.set_wheel_radius_m(params.wheel_radius_m);
  drive.set_max_wheel_speed_mps(params.max_wheel_speed_mps);
}

void set_kinematics(v1::RobotSpec& spec, const SkidSteerPreset& skid) {
  v1::SkidSteer& steer = *spec.mutable_kinematics()->mutable_skid_steer();
  steer.set_track_separation_m(skid.params.track_separation_m);
  steer.set_left_sprocket_radius_m(skid.params.left_sprocket_radius_m);
  steer.set_right_sprocket_radius_m(skid.params.right_sprocket_radius_m);
  steer.set_left_slip(skid.params.left_slip);
  steer.set_right_slip(skid.params.right_slip);
  steer.set_max_track_speed_mps(skid.params.max_track_speed_mps);
  steer.set_powertrain_time_constant_s(skid.powertrain_time_constant_s);
}

}  // namespace

v1::RobotSpec make_robot_spec(const RobotPreset& preset, const geometry::Pose2& X_WB_start) {
  v1::RobotSpec spec;
  spec.set_model(preset.name);
  std::visit([&](const auto& kinematics) { set_kinematics(spec, kinematics); }, preset.kinematics);
  v1::BoxFootprint& box = *spec.mutable_footprint()->mutable_box();
  box.set_length_m(preset.footprint.length);
  box.set_width_m(preset.footprint.width);
  box.set_height_m(preset.footprint.height);
  box.set_center_x_m(preset.footprint.center_x);
  for (const SensorPreset& sensor : preset.sensors) {
    std::visit([&](const auto& sensor_preset) { add_sensor(spec, sensor_preset); }, sensor);
  }
  spec.set_command_timeout_s(preset.command_timeout_s);
  spec.set_default_behaviour(preset.default_behaviour);
  if (preset.activitybot_units) spec.set_command_units(v1::COMMAND_UNITS_ACTIVITYBOT_TICKS);
  if (preset.encoders) {
    v1::WheelEncoderSpec& encoders = *spec.mutable_encoders();
    encoders.set_ticks_per_revolution(preset.encoders->ticks_per_revolution);
    encoders.set_wheel_radius_m(preset.encoders->wheel_radius_m);
    encoders.set_wheel_separation_m(preset.encoders->wheel_separation_m);
    encoders.set_counter_bits(static_cast<std::uint32_t>(preset.encoders->counter_bits));
    v1::Pose2D& initial = *spec.mutable_initial_pose();
    initial.set_x(X_WB_start.x);
    initial.set_y(X_WB_start.y);
    initial.set_theta(X_WB_start.theta);
  }
  return spec;
}

v1::ClientMessage make_odometry_message(std::uint64_t seq, double stamp_s, const geometry::Pose2& X_WB,
                                        const geometry::BodyVelocity& velocity) {
  v1::ClientMessage message;
  v1::Odometry& odometry = *message.mutable_odometry();
  odometry.set_seq(seq);
  odometry.set_stamp_s(stamp_s);
  odometry.mutable_pose()->set_x(X_WB.x);
  odometry.mutable_pose()->set_y(X_WB.y);
  odometry.mutable_pose()->set_theta(X_WB.theta);
  odometry.set_linear_mps(velocity.linear_mps);
  odometry.set_angular_radps(velocity.angular_radps);
  return message;
}

v1::ClientMessage make_laser_scan_message(const std::string& sensor, std::uint64_t seq, double stamp_s,
                                          const std::vector<float>& ranges_m) {
  v1::ClientMessage message;
  v1::LaserScan& scan = *message.mutable_laser_scan();
  scan.set_sensor(sensor);
  scan.set_seq(seq);
  scan.set_stamp_s(stamp_s);
  scan.mutable_ranges()->Add(ranges_m.begin(), ranges_m.end());
  return message;
}

v1::ClientMessage make_range_array_message(const std::string& sensor, std::uint64_t seq, double stamp_s,
                                           const std::vector<float>& ranges_m) {
  v1::ClientMessage message;
  v1::RangeArray& array = *message.mutable_range_array();
  array.set_sensor(sensor);
  array.set_seq(seq);
  array.set_stamp_s(stamp_s);
  array.mutable_ranges()->Add(ranges_m.begin(), ranges_m.end());
  return message;
}

v1::ClientMessage make_servo_range_message(const std::string& sensor, std::uint64_t seq, double stamp_s,
                                           double servo_angle_rad, float range_m) {
  v1::ClientMessage message;
  v1::ServoRange& reading = *message.mutable_servo_range();
  reading.set_sensor(sensor);
  reading.set_seq(seq);
  reading.set_stamp_s(stamp_s);
  reading.set_servo_angle_rad(servo_angle_rad);
  reading.set_range_m(range_m);
  return message;
}

v1::ClientMessage make_point_cloud_message(const std::string& sensor, std::uint64_t seq, double stamp_s,
                                           const std::vector<float>& xyz_S) {
  v1::ClientMessage message;
  v1::PointCloud& cloud = *message.mutable_point_cloud();
  cloud.set_sensor(sensor);
  cloud.set_seq(seq);
  cloud.set_stamp_s(stamp_s);
  cloud.mutable_xyz()->Add(xyz_S.begin(), xyz_S.end());
  return message;
}

v1::ClientMessage make_wheel_encoders_message(std::uint64_t seq, double stamp_s, const EncoderTicks& ticks) {
  v1::ClientMessage message;
  v1::WheelEncoders& encoders = *message.mutable_wheel_encoders();
  encoders.set_seq(seq);
  encoders.set_stamp_s(stamp_s);
  encoders.set_left_ticks(ticks.left);
  encoders.set_right_ticks(ticks.right);
  return message;
}

WheelCommand to_wheel_command(const v1::MotionCommand& command) {
  return WheelCommand{.left_mps = command.left_wheel_mps(),
                      .right_mps = command.right_wheel_mps(),
                      .stop = command.stop(),
                      .expires_after_s = command.expires_after_s()};
}

}  // namespace occgeo::sim
