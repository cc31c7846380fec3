#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>

#include "fake_session.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/v1/robot.pb.h"

namespace occgeo::testing {

// A differential-drive probe (0.4 m wheel separation, 0.05 m wheels, 0.5 m/s) with a 0.6 x 0.4 m box
// footprint and one laser ("laser") 0.3 m up on base_link's origin; the defaults are a level laser of
// 181 beams over 180°, 0.05–8 m.
struct LaserProbe {
  std::string model = "laser-probe";
  double height_m = 0.5;   // footprint height
  double pitch_rad = 0.0;  // laser mount pitch
  int beam_count = 181;
  double angle_min_rad = -M_PI / 2;
  double angle_increment_rad = M_PI / 180;
  double range_min_m = 0.05;
  double range_max_m = 8.0;
};

inline v1::RobotSpec laser_probe_spec(const LaserProbe& probe = {}) {
  v1::RobotSpec spec;
  spec.set_model(probe.model);
  auto* drive = spec.mutable_kinematics()->mutable_differential();
  drive->set_wheel_separation_m(0.4);
  drive->set_wheel_radius_m(0.05);
  drive->set_max_wheel_speed_mps(0.5);
  auto* box = spec.mutable_footprint()->mutable_box();
  box->set_length_m(0.6);
  box->set_width_m(0.4);
  box->set_height_m(probe.height_m);
  spec.set_command_timeout_s(0.5);
  auto* sensor = spec.add_sensors();
  sensor->set_name("laser");
  sensor->mutable_mount()->mutable_position()->set_z(0.3);
  sensor->mutable_mount()->set_pitch(probe.pitch_rad);
  auto* laser = sensor->mutable_laser();
  laser->set_angle_min_rad(probe.angle_min_rad);
  laser->set_angle_increment_rad(probe.angle_increment_rad);
  laser->set_beam_count(probe.beam_count);
  laser->set_range_min_m(probe.range_min_m);
  laser->set_range_max_m(probe.range_max_m);
  laser->set_scan_period_s(0.1);
  return spec;
}

// Odometry at pose (x, y, theta), stamped `stamp`.
inline v1::Odometry odometry(double x, double y, double theta, double stamp) {
  v1::Odometry message;
  message.set_stamp_s(stamp);
  message.mutable_pose()->set_x(x);
  message.mutable_pose()->set_y(y);
  message.mutable_pose()->set_theta(theta);
  return message;
}

// A Hello of the protocol version this build speaks (proto::kProtocolVersion).
inline v1::Hello hello_message(v1::Role role, const std::string& robot_id = {}, const std::string& world = {}) {
  v1::Hello message;
  message.set_protocol_version(proto::kProtocolVersion);
  message.set_role(role);
  message.set_robot_id(robot_id);
  message.set_world(world);
  return message;
}

// A driver of `robot_id` in `world` (the default world when empty) that was welcomed and has sent `spec`.
inline std::shared_ptr<service::FakeSession> driver_session(service::ServerCore& core, const std::string& robot_id,
                                                            const v1::RobotSpec& spec, const std::string& world = {}) {
  auto session = std::make_shared<service::FakeSession>(core);
  service::handle_hello(session, hello_message(v1::ROLE_DRIVER, robot_id, world));
  EXPECT_TRUE(session->next_of(v1::ServerMessage::kWelcome));
  service::handle_robot_spec(session, spec);
  return session;
}

}  // namespace occgeo::testing
