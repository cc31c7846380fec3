#pragma once

#include <string>

#include "occgeo/client/connection.h"

namespace occgeo::testing {

// A query-role session to the server at `address`.
inline client::Connection open_query_session(const std::string& address) {
  auto connection = client::Connection::open(client::Endpoint::parse(address));
  v1::Hello hello;
  hello.set_protocol_version(1);
  hello.set_role(v1::ROLE_QUERY);
  hello.set_client_name("integration-test");
  connection.hello(hello);
  return connection;
}

// The Bearcat's RobotSpec as the simulator sends it: 1.0 x 0.8 m box, LMS200 at (0.45, 0, 0.6).
inline v1::RobotSpec bearcat_spec() {
  v1::RobotSpec spec;
  spec.set_model("bearcat");
  auto* drive = spec.mutable_kinematics()->mutable_differential();
  drive->set_wheel_separation_m(0.7);
  drive->set_wheel_radius_m(0.2);
  drive->set_max_wheel_speed_mps(1.2);
  auto* box = spec.mutable_footprint()->mutable_box();
  box->set_length_m(1.0);
  box->set_width_m(0.8);
  box->set_height_m(1.2);
  auto* sensor = spec.add_sensors();
  sensor->set_name("front_laser");
  sensor->mutable_mount()->mutable_position()->set_x(0.45);
  sensor->mutable_mount()->mutable_position()->set_z(0.6);
  auto* laser = sensor->mutable_laser();
  laser->set_angle_min_rad(-M_PI / 2);
  laser->set_angle_increment_rad(M_PI / 180);
  laser->set_beam_count(181);
  laser->set_range_max_m(8.0);
  laser->set_scan_period_s(0.1);
  spec.set_command_timeout_s(0.5);
  return spec;
}

// A driver session that has said hello and sent the Bearcat spec.
inline client::Connection open_driver_session(const std::string& address, const std::string& robot_id) {
  auto connection = client::Connection::open(client::Endpoint::parse(address));
  v1::Hello hello;
  hello.set_protocol_version(1);
  hello.set_role(v1::ROLE_DRIVER);
  hello.set_robot_id(robot_id);
  hello.set_client_name("integration-test-driver");
  connection.hello(hello);
  v1::ClientMessage spec;
  *spec.mutable_robot_spec() = bearcat_spec();
  connection.send(spec);
  return connection;
}

}  // namespace occgeo::testing
