#pragma once

#include <string>

#include "occgeo/client/connection.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/presets.h"

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

// The Bearcat's RobotSpec exactly as the simulator sends it (its preset table is the one source).
inline v1::RobotSpec bearcat_spec() { return sim::make_robot_spec(*sim::find_robot_preset("bearcat")); }

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
