#include "occgeo/sim/messages.h"

namespace occgeo::sim {

v1::Hello make_driver_hello(const std::string& robot_id, const std::string& world_name) {
  v1::Hello hello;
  hello.set_protocol_version(1);
  hello.set_role(v1::ROLE_DRIVER);
  hello.set_robot_id(robot_id);
  hello.set_world(world_name);
  hello.set_client_name("occgeo-sim");
  return hello;
}

v1::RobotSpec make_robot_spec(const RobotPreset& preset) {
  v1::RobotSpec spec;
  spec.set_model(preset.name);
  v1::DifferentialDrive& drive = *spec.mutable_kinematics()->mutable_differential();
  drive.set_wheel_separation_m(preset.drive.wheel_separation_m);
  drive.set_wheel_radius_m(preset.drive.wheel_radius_m);
  drive.set_max_wheel_speed_mps(preset.drive.max_wheel_speed_mps);
  v1::BoxFootprint& box = *spec.mutable_footprint()->mutable_box();
  box.set_length_m(preset.footprint.length);
  box.set_width_m(preset.footprint.width);
  box.set_height_m(preset.footprint.height);
  box.set_center_x_m(preset.footprint.center_x);

  const LaserPreset& laser = preset.laser;
  v1::SensorSpec& sensor = *spec.add_sensors();
  sensor.set_name(laser.name);
  v1::Pose3D& mount = *sensor.mutable_mount();
  mount.mutable_position()->set_x(laser.X_BS.x);
  mount.mutable_position()->set_y(laser.X_BS.y);
  mount.mutable_position()->set_z(laser.mount_height_m);
  mount.set_yaw(laser.X_BS.theta);
  v1::LaserSpec& laser_spec = *sensor.mutable_laser();
  laser_spec.set_angle_min_rad(laser.angle_min_rad);
  laser_spec.set_angle_increment_rad(laser.angle_increment_rad);
  laser_spec.set_beam_count(laser.beam_count);
  laser_spec.set_range_min_m(laser.range_min_m);
  laser_spec.set_range_max_m(laser.range_max_m);
  laser_spec.set_scan_period_s(laser.scan_period_s);

  spec.set_command_timeout_s(preset.command_timeout_s);
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

WheelCommand to_wheel_command(const v1::MotionCommand& command) {
  return WheelCommand{.left_mps = command.left_wheel_mps(),
                      .right_mps = command.right_wheel_mps(),
                      .stop = command.stop(),
                      .expires_after_s = command.expires_after_s()};
}

}  // namespace occgeo::sim
