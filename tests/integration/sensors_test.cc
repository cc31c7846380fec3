// The range array, servo range, wheel encoder and point cloud messages over the wire against the
// real occgeod: each accepted sensor message is acknowledged, the map holds its echoes where the
// dead-reckoned pose puts them, and bad input is answered with an error naming the field while
// the connection stays usable.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "../service/sensor_robot_spec.h"
#include "../support/process.h"
#include "occgeo/client/connection.h"
#include "occgeo/proto/protocol.h"

namespace occgeo::testing {
namespace {

using R = SensorRobot;

client::Connection open_session(const std::string& address, v1::Role role, const std::string& robot_id = {}) {
  auto connection = client::Connection::open(client::Endpoint::parse(address));
  v1::Hello hello;
  hello.set_protocol_version(proto::kProtocolVersion);
  hello.set_role(role);
  hello.set_robot_id(robot_id);
  hello.set_client_name("sensors-test");
  connection.hello(hello);
  return connection;
}

class Sensors : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<ServerProcess>(dir_.path());
    driver_ = std::make_unique<client::Connection>(open_session(server_->address(), v1::ROLE_DRIVER, "rover"));
    v1::ClientMessage spec;
    *spec.mutable_robot_spec() = sensor_robot_spec();
    driver_->send(spec);
  }

  // The reply to the last sensor message: its ack or an error, whichever comes first.
  v1::ServerMessage reply() {
    for (int i = 0; i < 10; ++i) {
      auto message = driver_->receive(std::chrono::seconds(5));
      if (!message) break;
      if (message->has_scan_ack() || message->has_error()) return *message;
    }
    ADD_FAILURE() << "no ack or error arrived\n" << server_->log();
    return {};
  }

  void expect_ack(const v1::ClientMessage& message, std::uint64_t seq) {
    driver_->send(message);
    const v1::ServerMessage answer = reply();
    ASSERT_TRUE(answer.has_scan_ack()) << answer.DebugString();
    EXPECT_EQ(answer.scan_ack().seq(), seq);
  }

  void expect_error(const v1::ClientMessage& message, const std::string& field) {
    driver_->send(message);
    const v1::ServerMessage answer = reply();
    ASSERT_TRUE(answer.has_error()) << field << ": " << answer.DebugString();
    EXPECT_EQ(answer.error().field(), field) << answer.error().message();
  }

  v1::GridReply grid() {
    auto query = open_session(server_->address(), v1::ROLE_QUERY);
    v1::ClientMessage request;
    request.set_request_id(7);
    request.mutable_grid()->set_world("default");
    return query.call(request, 7).grid();
  }

  // Certainty of the cell holding (x, y), or -1 when the reply does not cover it or it is unobserved.
  static int certainty(const v1::GridReply& reply, double x, double y) {
    const auto ix = static_cast<std::int64_t>(std::floor(x / reply.cell_size_m())) - reply.min_cell().ix();
    const auto iy = static_cast<std::int64_t>(std::floor(y / reply.cell_size_m())) - reply.min_cell().iy();
    if (ix < 0 || iy < 0 || ix >= reply.width() || iy >= reply.height()) return -1;
    const auto value = static_cast<unsigned char>(reply.cells()[static_cast<std::size_t>(iy * reply.width() + ix)]);
    return value == 255 ? -1 : value;
  }
  static bool occupied(const v1::GridReply& reply, double x, double y) {
    return certainty(reply, x, y) >= static_cast<int>(reply.occupied_threshold());
  }

  static v1::ClientMessage range_array(std::uint64_t seq, double stamp, std::vector<float> ranges) {
    v1::ClientMessage message;
    auto* body = message.mutable_range_array();
    body->set_sensor("sonar");
    body->set_seq(seq);
    body->set_stamp_s(stamp);
    for (const float r : ranges) body->add_ranges(r);
    return message;
  }
  static v1::ClientMessage servo_range(std::uint64_t seq, double stamp, double angle, float range) {
    v1::ClientMessage message;
    auto* body = message.mutable_servo_range();
    body->set_sensor("lidar_lite");
    body->set_seq(seq);
    body->set_stamp_s(stamp);
    body->set_servo_angle_rad(angle);
    body->set_range_m(range);
    return message;
  }
  static v1::ClientMessage wheel_encoders(std::uint64_t seq, double stamp, std::int64_t left, std::int64_t right) {
    v1::ClientMessage message;
    auto* body = message.mutable_wheel_encoders();
    body->set_seq(seq);
    body->set_stamp_s(stamp);
    body->set_left_ticks(left);
    body->set_right_ticks(right);
    return message;
  }
  static v1::ClientMessage point_cloud(std::uint64_t seq, double stamp, const std::vector<float>& xyz) {
    v1::ClientMessage message;
    auto* body = message.mutable_point_cloud();
    body->set_sensor("depth");
    body->set_seq(seq);
    body->set_stamp_s(stamp);
    for (const float v : xyz) body->add_xyz(v);
    return message;
  }

  TempDir dir_;
  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<client::Connection> driver_;
};

TEST_F(Sensors, EachKindIsAcknowledgedAndMappedAtTheDeadReckonedPose) {
  // The first counts put the robot at its initial pose, (0.05, 0.05) facing +x.
  driver_->send(wheel_encoders(1, 0.0, 0, 0));
  // Sonar element 2 sits at the ring's edge, (0.15, 0.30), facing +y: its echo at 1.02 m is (0.15, 1.32).
  std::vector<float> sonar(R::kSonarElements, 0.0F);
  sonar[2] = 1.02F;
  expect_ack(range_array(1, 0.1, sonar), 1);
  // The servo rangefinder on base_link turned to -45°: an echo 1.5 m away at (1.11, -1.01).
  expect_ack(servo_range(2, 0.2, -M_PI / 4, 1.5F), 2);
  // 1000 ticks on both wheels drive 3.25 m ahead, to (3.30, 0.05); the depth camera then sits at
  // (3.50, 0.05, 0.3) and sees a point 1.02 m ahead at mid height: (4.52, 0.05).
  driver_->send(wheel_encoders(2, 1.0, 1000, 1000));
  expect_ack(point_cloud(3, 1.0, {1.02F, 0.0F, 0.0F, 1.02F, 0.5F, 0.9F}), 3);

  const v1::GridReply map = grid();
  EXPECT_TRUE(occupied(map, 0.15, 1.32));
  EXPECT_FALSE(occupied(map, 0.05, 1.07)) << "sonar mapped from the robot centre (seed 001 §3)";
  EXPECT_TRUE(occupied(map, 0.05 + 1.5 * std::cos(M_PI / 4), 0.05 - 1.5 * std::sin(M_PI / 4)));
  EXPECT_TRUE(occupied(map, 4.52, 0.05));
  EXPECT_FALSE(occupied(map, 1.27, 0.05)) << "the point cloud was placed at the initial pose";
  EXPECT_EQ(certainty(map, 4.52, 0.55), -1) << "a point above the robot's height is not an obstacle";

  // Status counts every sensor kind.
  auto query = open_session(server_->address(), v1::ROLE_QUERY);
  v1::ClientMessage request;
  request.mutable_status();
  request.set_request_id(3);
  const auto status = query.call(request, 3).status();
  ASSERT_EQ(status.robots_size(), 1);
  EXPECT_EQ(status.robots(0).scans_ingested(), 3U);
  EXPECT_NEAR(status.robots(0).pose().x(), 3.30, 1e-9);
}

TEST_F(Sensors, BadInputNamesTheFieldAndTheConnectionStaysUsable) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  driver_->send(wheel_encoders(1, 0.0, 0, 0));
  expect_ack(servo_range(1, 0.1, 0.0, 1.02F), 1);
  const v1::GridReply before = grid();

  std::vector<float> sonar(R::kSonarElements, 1.0F);
  sonar[5] = nan;
  expect_error(range_array(2, 0.2, sonar), "range_array.ranges[5]");
  expect_error(range_array(2, 0.2, std::vector<float>(3, 1.0F)), "range_array.ranges");
  expect_error(servo_range(2, 0.2, std::numeric_limits<double>::quiet_NaN(), 1.0F), "servo_range.servo_angle_rad");
  expect_error(servo_range(2, 0.2, 0.0, nan), "servo_range.range_m");
  expect_error(servo_range(2, 0.2, R::kServoMax_rad + 0.1, 1.0F), "servo_range.servo_angle_rad");
  expect_error(point_cloud(2, 0.2, {1.0F, nan, 0.0F}), "point_cloud.xyz[1]");
  expect_error(point_cloud(2, 0.2, {1.0F, 0.0F, 0.0F, 1.0F}), "point_cloud.xyz");
  expect_error(wheel_encoders(2, std::numeric_limits<double>::infinity(), 0, 0), "wheel_encoders.stamp_s");
  // Out of order across kinds: seq 1 was the servo's.
  expect_error(point_cloud(1, 0.2, {1.0F, 0.0F, 0.0F}), "point_cloud.seq");
  expect_error(range_array(2, 0.05, std::vector<float>(R::kSonarElements, 1.0F)), "range_array.stamp_s");

  const v1::GridReply after = grid();
  EXPECT_EQ(after.version(), before.version());
  EXPECT_EQ(after.cells(), before.cells());

  // The same connection goes on: a good message with the next seq is accepted.
  expect_ack(range_array(2, 0.3, std::vector<float>(R::kSonarElements, 2.0F)), 2);
  ASSERT_TRUE(server_->running()) << server_->log();
}

}  // namespace
}  // namespace occgeo::testing
