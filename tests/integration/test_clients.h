#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "occgeo/client/connection.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/presets.h"

namespace occgeo::testing {

// A query-role session to the server at `address`.
inline client::Connection open_query_session(const std::string& address) {
  auto connection = client::Connection::open(client::Endpoint::parse(address));
  v1::Hello hello;
  hello.set_protocol_version(proto::kProtocolVersion);
  hello.set_role(v1::ROLE_QUERY);
  hello.set_client_name("integration-test");
  connection.hello(hello);
  return connection;
}

// The Bearcat's RobotSpec exactly as the simulator sends it (its preset table is the one source).
inline v1::RobotSpec bearcat_spec() { return sim::make_robot_spec(*sim::find_robot_preset("bearcat")); }

// A driver session that has said hello and sent the Bearcat spec, which the server has registered: the status request
// after it is answered only once the session's earlier messages were handled, so another session's query that follows
// finds the robot (without the round trip it could reach the server first and be told ERROR_UNKNOWN_ROBOT).
inline client::Connection open_driver_session(const std::string& address, const std::string& robot_id) {
  auto connection = client::Connection::open(client::Endpoint::parse(address));
  v1::Hello hello;
  hello.set_protocol_version(proto::kProtocolVersion);
  hello.set_role(v1::ROLE_DRIVER);
  hello.set_robot_id(robot_id);
  hello.set_client_name("integration-test-driver");
  connection.hello(hello);
  v1::ClientMessage spec;
  *spec.mutable_robot_spec() = bearcat_spec();
  connection.send(spec);
  constexpr std::uint64_t kSpecHandled = 1;
  v1::ClientMessage status;
  status.mutable_status();
  status.set_request_id(kSpecHandled);
  connection.call(status, kSpecHandled);
  return connection;
}

// Ranges of the Bearcat's laser (181 beams over 180 degrees) at X_WB inside a 12 m square room centred on the origin;
// past 8 m (the laser's range) a beam has no return.
inline std::vector<float> room_ranges(double x, double y, double theta) {
  std::vector<float> ranges(181);
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    const double angle = theta - std::numbers::pi / 2.0 + static_cast<double>(i) * std::numbers::pi / 180.0;
    const double c = std::cos(angle);
    const double s = std::sin(angle);
    double range = 1e9;
    if (std::abs(c) > 1e-9) range = std::min(range, ((c > 0 ? 6.0 : -6.0) - x) / c);
    if (std::abs(s) > 1e-9) range = std::min(range, ((s > 0 ? 6.0 : -6.0) - y) / s);
    ranges[i] = static_cast<float>(std::min(range, 8.5));
  }
  return ranges;
}

}  // namespace occgeo::testing
