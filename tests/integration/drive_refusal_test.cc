// A drive request the robot cannot carry out: the lease holder gets an error naming the reason, and the robot is left
// stopped (behaviour "stop", a stop command to its driver) rather than carrying on with what it did before.
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "../support/process.h"
#include "occgeo/client/connection.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/presets.h"

namespace occgeo::testing {
namespace {

using namespace std::chrono_literals;

class DriveRefusal : public ::testing::Test {
 protected:
  void SetUp() override { server_.emplace(dir_.path()); }

  // A driver session for a robot of the simulator's preset, registered when this returns.
  client::Connection driver(const std::string& robot, const std::string& preset) {
    auto connection = client::Connection::open(client::Endpoint::parse(server_->address()));
    connection.hello(sim::make_driver_hello(robot, "default"));
    v1::ClientMessage spec;
    *spec.mutable_robot_spec() = sim::make_robot_spec(*sim::find_robot_preset(preset), {});
    connection.send(spec);
    v1::ClientMessage status;
    status.mutable_status();
    status.set_request_id(1);
    static_cast<void>(connection.call(status, 1));
    return connection;
  }

  client::Connection controller(const std::string& robot) {
    auto connection = client::Connection::open(client::Endpoint::parse(server_->address()));
    v1::Hello hello;
    hello.set_protocol_version(proto::kProtocolVersion);
    hello.set_role(v1::ROLE_CONTROLLER);
    hello.set_client_name("refusal-test");
    connection.hello(hello);
    v1::ClientMessage lease;
    lease.set_request_id(++id_);
    lease.mutable_lease()->set_robot_id(robot);
    lease.mutable_lease()->set_action(v1::LeaseRequest::ACQUIRE);
    EXPECT_TRUE(connection.call(lease, id_).lease().granted());
    return connection;
  }

  // The error the drive request gets, as "field: message"; empty when it was accepted.
  std::string drive(client::Connection& connection, const v1::DriveRequest& request) {
    v1::ClientMessage message;
    *message.mutable_drive() = request;
    message.set_request_id(++id_);
    try {
      static_cast<void>(connection.call(message, id_));
      return {};
    } catch (const client::ClientError& error) {
      return error.what();
    }
  }

  v1::Behaviour behaviour_of(client::Connection& connection, const std::string& robot) {
    v1::ClientMessage request;
    request.mutable_status();
    request.set_request_id(++id_);
    const v1::ServerMessage reply = connection.call(request, id_);
    for (const auto& r : reply.status().robots()) {
      if (r.id() == robot) return r.behaviour();
    }
    return v1::BEHAVIOUR_UNSPECIFIED;  // no such robot
  }

  // The next motion command the driver receives within 5 s.
  static std::optional<v1::MotionCommand> next_command(client::Connection& connection) {
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    while (std::chrono::steady_clock::now() < deadline) {
      const auto message = connection.receive(200ms);
      if (message && message->has_motion_command()) return message->motion_command();
    }
    return std::nullopt;
  }

  TempDir dir_;
  std::optional<ServerProcess> server_;
  std::uint64_t id_ = 100;
};

TEST_F(DriveRefusal, WanderWithoutARangeSensorToWanderByIsRefusedAndTheRobotStops) {
  auto bot = driver("bot", "activitybot");  // a servo-swept single beam: no laser, no range array
  auto control = controller("bot");
  v1::DriveRequest request;
  request.set_robot_id("bot");
  request.set_behaviour(v1::BEHAVIOUR_WANDER);
  const std::string error = drive(control, request);
  EXPECT_NE(error.find("drive.behaviour"), std::string::npos) << error;
  EXPECT_NE(error.find("no range sensor to wander by"), std::string::npos) << error;
  EXPECT_EQ(behaviour_of(control, "bot"), v1::BEHAVIOUR_STOP);
  const auto command = next_command(bot);
  ASSERT_TRUE(command);
  EXPECT_TRUE(command->stop());
  EXPECT_EQ(command->state(), v1::BEHAVIOUR_STATE_DRIVE_REFUSED);
}

TEST_F(DriveRefusal, PointBugGoalOutsideTheWorldIsRefusedAndTheMovingRobotStops) {
  auto bearcat = driver("cat", "bearcat");
  auto control = controller("cat");
  v1::DriveRequest teleop;
  teleop.set_robot_id("cat");
  teleop.set_behaviour(v1::BEHAVIOUR_TELEOP);
  teleop.set_linear_mps(0.3);
  ASSERT_EQ(drive(control, teleop), "");
  ASSERT_EQ(behaviour_of(control, "cat"), v1::BEHAVIOUR_TELEOP);

  v1::DriveRequest far;
  far.set_robot_id("cat");
  far.set_behaviour(v1::BEHAVIOUR_GOTO);
  far.mutable_goal()->set_x_m(5.0e7);
  far.mutable_goal()->set_y_m(0.0);
  const std::string error = drive(control, far);
  EXPECT_NE(error.find("drive.goal.x_m"), std::string::npos) << error;
  EXPECT_NE(error.find("outside the world"), std::string::npos) << error;
  EXPECT_EQ(behaviour_of(control, "cat"), v1::BEHAVIOUR_STOP);
  const auto command = next_command(bearcat);
  ASSERT_TRUE(command);
  EXPECT_TRUE(command->stop());
  EXPECT_EQ(command->state(), v1::BEHAVIOUR_STATE_DRIVE_REFUSED);
}

}  // namespace
}  // namespace occgeo::testing
