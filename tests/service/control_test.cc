// Control ownership and watchdogs against fake sessions and a real ServerCore: leases, DriveRequest,
// the e-stop latch, teleop clamping, lease expiry, a holder's disconnect and stale sensors.
#include <gtest/gtest.h>

#include <thread>

#include "fake_session.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/presets.h"

namespace occgeo::service {
namespace {

v1::Hello hello(v1::Role role, const std::string& name, const std::string& robot_id = {},
                const std::string& token = {}) {
  v1::Hello message;
  message.set_protocol_version(proto::kProtocolVersion);
  message.set_role(role);
  message.set_robot_id(robot_id);
  message.set_client_name(name);
  message.set_auth_token(token);
  return message;
}

ServerConfig config_with_token() {
  ServerConfig config;
  config.auth.operator_token = "s3cret";
  config.control.sensor_timeout_s = 0.3;
  return config;
}

class Control : public ::testing::Test {
 protected:
  Control() : core_(config_with_token()) {}

  std::shared_ptr<FakeSession> session(v1::Role role, const std::string& name, const std::string& token = {}) {
    auto s = std::make_shared<FakeSession>(core_);
    s->info().id = core_.next_session_id++;
    handle_hello(s, hello(role, name, role == v1::ROLE_DRIVER ? "r1" : "", token));
    EXPECT_TRUE(s->next_of(v1::ServerMessage::kWelcome));
    return s;
  }

  std::shared_ptr<FakeSession> driver() {
    auto s = session(v1::ROLE_DRIVER, "sim");
    handle_robot_spec(s, sim::make_robot_spec(*sim::find_robot_preset("bearcat")));
    v1::Odometry odometry;
    odometry.mutable_pose();
    handle_odometry(s, odometry);
    return s;
  }

  // One scan with every beam at `range`; returns the command that answers it.
  v1::MotionCommand scan(const std::shared_ptr<FakeSession>& d, float range = 6.0F) {
    v1::LaserScan message;
    message.set_sensor("front_laser");
    message.set_seq(++seq_);
    message.set_stamp_s(0.1 * static_cast<double>(seq_));
    for (int i = 0; i < 181; ++i) message.add_ranges(range);
    v1::ClientMessage m;
    *m.mutable_laser_scan() = message;
    dispatch(d, std::move(m));
    for (int i = 0; i < 10; ++i) {
      auto command = d->next_of(v1::ServerMessage::kMotionCommand);
      if (!command) break;
      if (command->motion_command().answers_scan_seq() == seq_) return command->motion_command();
    }
    ADD_FAILURE() << "no command answered scan " << seq_;
    return {};
  }

  v1::ServerMessage send(const std::shared_ptr<FakeSession>& s, v1::ClientMessage message) {
    dispatch(s, std::move(message));
    auto reply = s->next();
    EXPECT_TRUE(reply);
    return reply ? *reply : v1::ServerMessage{};
  }

  v1::ServerMessage lease(const std::shared_ptr<FakeSession>& s, v1::LeaseRequest::Action action,
                          double timeout_s = 0.0) {
    v1::ClientMessage m;
    m.set_request_id(7);
    m.mutable_lease()->set_robot_id("r1");
    m.mutable_lease()->set_action(action);
    m.mutable_lease()->set_timeout_s(timeout_s);
    return send(s, m);
  }

  v1::ServerMessage drive(const std::shared_ptr<FakeSession>& s, v1::Behaviour behaviour, double v = 0.0,
                          double w = 0.0) {
    v1::ClientMessage m;
    m.set_request_id(8);
    m.mutable_drive()->set_robot_id("r1");
    m.mutable_drive()->set_behaviour(behaviour);
    m.mutable_drive()->set_linear_mps(v);
    m.mutable_drive()->set_angular_radps(w);
    return send(s, m);
  }

  v1::ServerMessage estop(const std::shared_ptr<FakeSession>& s, bool engage) {
    v1::ClientMessage m;
    m.set_request_id(9);
    m.mutable_estop()->set_robot_id("r1");
    m.mutable_estop()->set_engage(engage);
    return send(s, m);
  }

  std::shared_ptr<FakeSession> keep(std::shared_ptr<FakeSession> s) {
    sessions_.push_back(s);
    return s;
  }

  ServerCore core_;
  std::vector<std::shared_ptr<FakeSession>> sessions_;
  std::uint64_t seq_ = 0;
};

TEST_F(Control, ASecondControllerIsRefusedAndToldTheHolder) {
  keep(driver());
  auto first = session(v1::ROLE_CONTROLLER, "alice");
  auto second = session(v1::ROLE_CONTROLLER, "bob");
  auto reply = lease(first, v1::LeaseRequest::ACQUIRE);
  ASSERT_TRUE(reply.has_lease());
  EXPECT_TRUE(reply.lease().granted());
  EXPECT_EQ(reply.request_id(), 7U);
  EXPECT_NEAR(reply.lease().expires_in_s(), 2.0, 0.1) << "control.lease_timeout_s by default";

  reply = lease(second, v1::LeaseRequest::ACQUIRE);
  ASSERT_TRUE(reply.has_lease());
  EXPECT_FALSE(reply.lease().granted());
  EXPECT_EQ(reply.lease().holder().session_id(), first->info().id);
  EXPECT_EQ(reply.lease().holder().client_name(), "alice");
  // Neither may the second one retain, return or drive.
  EXPECT_FALSE(lease(second, v1::LeaseRequest::RETAIN).lease().granted());
  EXPECT_FALSE(lease(second, v1::LeaseRequest::RETURN).lease().granted());
  reply = drive(second, v1::BEHAVIOUR_TELEOP, 0.3);
  ASSERT_TRUE(reply.has_error());
  EXPECT_EQ(reply.error().code(), v1::ERROR_NOT_ALLOWED);
  EXPECT_EQ(reply.error().field(), "drive.robot_id");
  EXPECT_NE(reply.error().message().find("alice"), std::string::npos) << reply.error().message();

  // Once returned, the second controller gets it.
  EXPECT_TRUE(lease(first, v1::LeaseRequest::RETURN).lease().granted());
  EXPECT_TRUE(lease(second, v1::LeaseRequest::ACQUIRE).lease().granted());
  EXPECT_TRUE(lease(second, v1::LeaseRequest::RETURN).lease().granted());
}

TEST_F(Control, ObserversQueriesAndDriversCanNeverDrive) {
  keep(driver());
  for (const v1::Role role : {v1::ROLE_OBSERVER, v1::ROLE_QUERY}) {
    auto s = session(role, "watcher");
    auto reply = drive(s, v1::BEHAVIOUR_BEARCAT);
    ASSERT_TRUE(reply.has_error());
    EXPECT_EQ(reply.error().code(), v1::ERROR_NOT_ALLOWED);
    EXPECT_EQ(reply.error().field(), "drive");
    reply = lease(s, v1::LeaseRequest::ACQUIRE);
    ASSERT_TRUE(reply.has_error());
    EXPECT_EQ(reply.error().code(), v1::ERROR_NOT_ALLOWED);
    EXPECT_EQ(reply.error().field(), "lease");
  }
  auto query = session(v1::ROLE_QUERY, "q");
  auto reply = estop(query, true);
  ASSERT_TRUE(reply.has_error());
  EXPECT_EQ(reply.error().field(), "estop");
}

TEST_F(Control, TakeNeedsTheOperatorToken) {
  keep(driver());
  auto holder = session(v1::ROLE_CONTROLLER, "alice");
  ASSERT_TRUE(lease(holder, v1::LeaseRequest::ACQUIRE).lease().granted());
  auto plain = session(v1::ROLE_CONTROLLER, "bob", "wrong");
  auto reply = lease(plain, v1::LeaseRequest::TAKE);
  ASSERT_TRUE(reply.has_error());
  EXPECT_EQ(reply.error().code(), v1::ERROR_UNAUTHENTICATED);
  EXPECT_EQ(reply.error().field(), "lease.action");

  auto operator_session = session(v1::ROLE_CONTROLLER, "operator", "s3cret");
  reply = lease(operator_session, v1::LeaseRequest::TAKE);
  ASSERT_TRUE(reply.has_lease());
  EXPECT_TRUE(reply.lease().granted());
  EXPECT_EQ(reply.lease().holder().client_name(), "operator");
  // The old holder has lost it.
  EXPECT_FALSE(lease(holder, v1::LeaseRequest::RETAIN).lease().granted());
  EXPECT_TRUE(drive(holder, v1::BEHAVIOUR_BEARCAT).has_error());
  EXPECT_TRUE(lease(operator_session, v1::LeaseRequest::RETURN).lease().granted());
}

TEST_F(Control, ALeaseNotRetainedLapsesAndStopsTheRobot) {
  auto d = keep(driver());
  auto holder = session(v1::ROLE_CONTROLLER, "alice");
  ASSERT_TRUE(lease(holder, v1::LeaseRequest::ACQUIRE, 0.2).lease().granted());
  ASSERT_TRUE(drive(holder, v1::BEHAVIOUR_TELEOP, 0.4).has_drive());
  EXPECT_FALSE(scan(d).stop());
  // The lease (0.2 s) runs out before the sensor watchdog (0.3 s here) fires.
  std::optional<v1::MotionCommand> stop;
  for (int i = 0; i < 40 && !stop; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    for (const auto& message : d->take_all()) {
      if (message.has_motion_command() && message.motion_command().state() == v1::BEHAVIOUR_STATE_LEASE_EXPIRED) {
        stop = message.motion_command();
      }
    }
  }
  ASSERT_TRUE(stop) << "no stop within 0.8 s of a 0.2 s lease";
  EXPECT_TRUE(stop->stop());
  EXPECT_EQ(stop->left_wheel_mps(), 0.0);
  const ControlState control = core_.find_robot("r1")->control().state();
  EXPECT_FALSE(control.lease);
  EXPECT_EQ(control.behaviour, v1::BEHAVIOUR_STOP);
  EXPECT_TRUE(scan(d).stop()) << "scans are answered by stops after the lapse";
  EXPECT_FALSE(lease(holder, v1::LeaseRequest::RETAIN).lease().granted()) << "too late to retain";
}

TEST_F(Control, TheHoldersDisconnectStopsTheRobotAtOnce) {
  auto d = keep(driver());
  auto holder = session(v1::ROLE_CONTROLLER, "alice");
  ASSERT_TRUE(lease(holder, v1::LeaseRequest::ACQUIRE).lease().granted());
  ASSERT_TRUE(drive(holder, v1::BEHAVIOUR_TELEOP, 0.4).has_drive());
  EXPECT_FALSE(scan(d).stop());
  handle_disconnect(core_, holder->info());
  auto command = d->next_of(v1::ServerMessage::kMotionCommand);
  ASSERT_TRUE(command);
  EXPECT_TRUE(command->motion_command().stop());
  EXPECT_EQ(command->motion_command().state(), v1::BEHAVIOUR_STATE_CONTROLLER_DISCONNECTED);
  EXPECT_TRUE(scan(d).stop());
  EXPECT_FALSE(core_.find_robot("r1")->control().state().lease);
}

TEST_F(Control, EStopLatchesAcrossBehaviourChangesAndOnlyTheHolderReleasesIt) {
  auto d = keep(driver());
  auto holder = session(v1::ROLE_CONTROLLER, "alice");
  auto observer = session(v1::ROLE_OBSERVER, "watcher");
  ASSERT_TRUE(lease(holder, v1::LeaseRequest::ACQUIRE, 10.0).lease().granted());
  ASSERT_TRUE(drive(holder, v1::BEHAVIOUR_TELEOP, 0.3).has_drive());
  EXPECT_FALSE(scan(d).stop());

  auto reply = estop(observer, true);
  ASSERT_TRUE(reply.has_estop());
  EXPECT_TRUE(reply.estop().engaged());
  EXPECT_EQ(reply.estop().holder().client_name(), "alice");
  auto command = scan(d);
  EXPECT_TRUE(command.stop());
  EXPECT_EQ(command.state(), v1::BEHAVIOUR_STATE_ESTOP);
  for (const v1::Behaviour behaviour : {v1::BEHAVIOUR_BEARCAT, v1::BEHAVIOUR_TELEOP, v1::BEHAVIOUR_STOP}) {
    reply = drive(holder, behaviour, 0.3);
    ASSERT_TRUE(reply.has_drive());
    EXPECT_TRUE(reply.drive().estop());
    command = scan(d);
    EXPECT_TRUE(command.stop()) << behaviour;
    EXPECT_EQ(command.state(), v1::BEHAVIOUR_STATE_ESTOP) << behaviour;
  }
  reply = estop(observer, false);
  ASSERT_TRUE(reply.has_error());
  EXPECT_EQ(reply.error().code(), v1::ERROR_NOT_ALLOWED);
  EXPECT_EQ(reply.error().field(), "estop.engage");
  EXPECT_NE(reply.error().message().find("alice"), std::string::npos) << reply.error().message();

  // The status shows the latch and the holder.
  v1::ClientMessage status;
  status.mutable_status();
  status.set_request_id(3);
  const auto robots = send(observer, status).status().robots();
  ASSERT_EQ(robots.size(), 1);
  EXPECT_TRUE(robots[0].estop());
  EXPECT_EQ(robots[0].lease_holder().client_name(), "alice");

  ASSERT_TRUE(drive(holder, v1::BEHAVIOUR_BEARCAT).has_drive());
  reply = estop(holder, false);
  ASSERT_TRUE(reply.has_estop());
  EXPECT_FALSE(reply.estop().engaged());
  command = scan(d);
  EXPECT_FALSE(command.stop());
  EXPECT_EQ(command.behaviour(), v1::BEHAVIOUR_BEARCAT);
  EXPECT_TRUE(lease(holder, v1::LeaseRequest::RETURN).lease().granted());
}

TEST_F(Control, TheActiveBehavioursPlannedPathIsInTheRobotsStateUntilItStops) {
  auto d = keep(driver());
  auto holder = session(v1::ROLE_CONTROLLER, "alice");
  ASSERT_TRUE(lease(holder, v1::LeaseRequest::ACQUIRE, 10.0).lease().granted());
  v1::ClientMessage go;
  go.set_request_id(8);
  go.mutable_drive()->set_robot_id("r1");
  go.mutable_drive()->set_behaviour(v1::BEHAVIOUR_GOTO);
  go.mutable_drive()->mutable_goal()->set_x_m(3.0);
  go.mutable_drive()->mutable_goal()->set_y_m(1.0);
  ASSERT_TRUE(send(holder, go).has_drive());
  static_cast<void>(scan(d));
  std::vector<Eigen::Vector2d> path = core_.find_robot("r1")->state().path();
  ASSERT_EQ(path.size(), 2U) << "from the robot straight to the goal";
  EXPECT_TRUE(path.front().isApprox(Eigen::Vector2d(0.0, 0.0)));
  EXPECT_TRUE(path.back().isApprox(Eigen::Vector2d(3.0, 1.0)));
  // A plain status stays cheap: no path and no scan; the detailed one carries both, world frame.
  v1::ClientMessage status;
  status.mutable_status();
  status.set_request_id(9);
  const v1::RobotStatus plain = send(holder, status).status().robots(0);
  EXPECT_EQ(plain.path_size(), 0);
  EXPECT_EQ(plain.scan_size(), 0);
  status.mutable_status()->set_detailed(true);
  const v1::RobotStatus detailed = send(holder, status).status().robots(0);
  ASSERT_EQ(detailed.path_size(), 2);
  EXPECT_NEAR(detailed.path(1).x(), 3.0, 1e-9);
  EXPECT_NEAR(detailed.path(1).y(), 1.0, 1e-9);
  EXPECT_GT(detailed.scan_size(), 0) << "the driver's latest laser returns";
  // Teleop plans nothing; stopping clears the path.
  ASSERT_TRUE(drive(holder, v1::BEHAVIOUR_TELEOP, 0.2).has_drive());
  static_cast<void>(scan(d));
  EXPECT_TRUE(core_.find_robot("r1")->state().path().empty());
  ASSERT_TRUE(send(holder, go).has_drive());
  static_cast<void>(scan(d));
  EXPECT_FALSE(core_.find_robot("r1")->state().path().empty());
  ASSERT_TRUE(drive(holder, v1::BEHAVIOUR_STOP).has_drive());
  static_cast<void>(scan(d));
  EXPECT_TRUE(core_.find_robot("r1")->state().path().empty());
  EXPECT_TRUE(lease(holder, v1::LeaseRequest::RETURN).lease().granted());
}

TEST_F(Control, TeleopVelocitiesAreClampedToTheRobotsLimits) {
  auto d = keep(driver());
  auto holder = session(v1::ROLE_CONTROLLER, "alice");
  ASSERT_TRUE(lease(holder, v1::LeaseRequest::ACQUIRE, 10.0).lease().granted());
  const auto& drive_params = std::get<geometry::DifferentialDriveParams>(core_.find_robot("r1")->model().drive);
  auto reply = drive(holder, v1::BEHAVIOUR_TELEOP, 50.0, 1.0);
  ASSERT_TRUE(reply.has_drive());
  EXPECT_LT(reply.drive().linear_mps(), drive_params.max_wheel_speed_mps + 1e-9);
  EXPECT_GT(reply.drive().linear_mps(), 0.0);
  // One factor for both wheels: the curvature w/v is kept.
  EXPECT_NEAR(reply.drive().angular_radps() / reply.drive().linear_mps(), 1.0 / 50.0, 1e-9);
  const auto command = scan(d);
  EXPECT_EQ(command.behaviour(), v1::BEHAVIOUR_TELEOP);
  EXPECT_LE(std::abs(command.left_wheel_mps()), drive_params.max_wheel_speed_mps + 1e-9);
  EXPECT_LE(std::abs(command.right_wheel_mps()), drive_params.max_wheel_speed_mps + 1e-9);
  EXPECT_NEAR(command.linear_mps(), reply.drive().linear_mps(), 1e-9);
  EXPECT_NEAR(command.expires_after_s(), 0.6, 1e-12) << "teleop commands expire like all others";
  reply = drive(holder, v1::BEHAVIOUR_TELEOP, std::nan(""));
  ASSERT_TRUE(reply.has_error());
  EXPECT_EQ(reply.error().field(), "drive.linear_mps");
  reply = drive(holder, v1::BEHAVIOUR_UNSPECIFIED);
  ASSERT_TRUE(reply.has_error());
  EXPECT_EQ(reply.error().field(), "drive.behaviour");
  EXPECT_NE(reply.error().message().find("not BEHAVIOUR_UNSPECIFIED"), std::string::npos) << reply.error().message();
  // A value from a newer schema this server does not know is refused by its number.
  reply = drive(holder, static_cast<v1::Behaviour>(99));
  ASSERT_TRUE(reply.has_error());
  EXPECT_EQ(reply.error().field(), "drive.behaviour");
  EXPECT_NE(reply.error().message().find("not 99"), std::string::npos) << reply.error().message();
  EXPECT_TRUE(lease(holder, v1::LeaseRequest::RETURN).lease().granted());
}

TEST_F(Control, StaleSensorsStopTheRobotOnce) {
  auto d = keep(driver());
  EXPECT_EQ(scan(d).behaviour(), v1::BEHAVIOUR_BEARCAT) << "without a controller robots keep the Bearcat behaviour";
  std::this_thread::sleep_for(std::chrono::milliseconds(600));  // sensor_timeout_s is 0.3 s here
  std::vector<v1::MotionCommand> stops;
  for (const auto& message : d->take_all()) {
    if (message.has_motion_command()) stops.push_back(message.motion_command());
  }
  ASSERT_EQ(stops.size(), 1U) << "one stop, not one per tick";
  EXPECT_TRUE(stops[0].stop());
  EXPECT_EQ(stops[0].state(), v1::BEHAVIOUR_STATE_SENSOR_STALE);
  EXPECT_TRUE(core_.find_robot("r1")->control().state().sensor_stale);
  EXPECT_EQ(core_.find_robot("r1")->state().behaviour_state, v1::BEHAVIOUR_STATE_SENSOR_STALE);
  scan(d);
  EXPECT_FALSE(core_.find_robot("r1")->control().state().sensor_stale) << "a new sensor message clears it";
  handle_disconnect(core_, d->info());
}

}  // namespace
}  // namespace occgeo::service
