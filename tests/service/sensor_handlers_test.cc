// The range array, servo range, wheel encoder and point cloud handlers, and skid-steer commands,
// against a fake session and a real ServerCore (no sockets).
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>

#include "fake_session.h"
#include "occgeo/geometry/grid_ray.h"
#include "occgeo/geometry/kinematics.h"
#include "occgeo/proto/protocol.h"
#include "sensor_robot_spec.h"
#include "test_robots.h"

namespace occgeo::service {
namespace {

using R = testing::SensorRobot;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

v1::RangeArray sonar(std::uint64_t seq, double stamp, std::vector<float> ranges) {
  v1::RangeArray message;
  message.set_sensor("sonar");
  message.set_seq(seq);
  message.set_stamp_s(stamp);
  for (const float r : ranges) message.add_ranges(r);
  return message;
}

// One reading per sonar element: `range` for element k, and 0 (below range_min, so skipped) for
// the others, so that only one acoustic axis touches the map.
v1::RangeArray one_sonar_element(std::uint64_t seq, double stamp, int k, float range) {
  std::vector<float> ranges(R::kSonarElements, 0.0F);
  ranges[static_cast<std::size_t>(k)] = range;
  return sonar(seq, stamp, ranges);
}

v1::ServoRange servo(std::uint64_t seq, double stamp, double angle, float range) {
  v1::ServoRange message;
  message.set_sensor("lidar_lite");
  message.set_seq(seq);
  message.set_stamp_s(stamp);
  message.set_servo_angle_rad(angle);
  message.set_range_m(range);
  return message;
}

v1::PointCloud cloud(std::uint64_t seq, double stamp, const std::vector<float>& xyz) {
  v1::PointCloud message;
  message.set_sensor("depth");
  message.set_seq(seq);
  message.set_stamp_s(stamp);
  for (const float v : xyz) message.add_xyz(v);
  return message;
}

v1::WheelEncoders ticks(std::uint64_t seq, double stamp, std::int64_t left, std::int64_t right) {
  v1::WheelEncoders message;
  message.set_seq(seq);
  message.set_stamp_s(stamp);
  message.set_left_ticks(left);
  message.set_right_ticks(right);
  return message;
}

using testing::odometry;

// A tracked robot with slippage and a forward laser, for the skid-steer command conversion.
v1::RobotSpec skid_steer_spec(double max_track_speed_mps) {
  v1::RobotSpec spec;
  spec.set_model("tracked");
  auto* skid = spec.mutable_kinematics()->mutable_skid_steer();
  skid->set_track_separation_m(0.6);
  skid->set_left_sprocket_radius_m(0.1);
  skid->set_right_sprocket_radius_m(0.12);
  skid->set_left_slip(0.1);
  skid->set_right_slip(0.25);
  skid->set_max_track_speed_mps(max_track_speed_mps);
  skid->set_powertrain_time_constant_s(0.2);
  auto* box = spec.mutable_footprint()->mutable_box();
  box->set_length_m(0.7);
  box->set_width_m(0.4);
  box->set_height_m(0.4);
  auto* laser = spec.add_sensors();
  laser->set_name("front_laser");
  laser->mutable_mount()->mutable_position()->set_x(0.3);
  laser->mutable_laser()->set_angle_min_rad(-M_PI / 2);
  laser->mutable_laser()->set_angle_increment_rad(M_PI / 180);
  laser->mutable_laser()->set_beam_count(181);
  laser->mutable_laser()->set_range_min_m(0.05);
  laser->mutable_laser()->set_range_max_m(8.0);
  return spec;
}

class SensorHandlers : public ::testing::Test {
 protected:
  SensorHandlers() : core_(ServerConfig{}) {}

  std::shared_ptr<FakeSession> driver(const std::string& robot_id, const v1::RobotSpec& spec) {
    auto session = testing::driver_session(core_, robot_id, spec);
    EXPECT_NE(core_.find_robot(robot_id), nullptr) << "the spec was refused";
    return session;
  }

  // Waits for the ack of sensor message `seq`, failing on any error first.
  static void expect_ack(FakeSession& session, std::uint64_t seq) {
    const auto reply = session.next();
    ASSERT_TRUE(reply) << "no reply to seq " << seq;
    ASSERT_TRUE(reply->has_scan_ack()) << reply->DebugString();
    EXPECT_EQ(reply->scan_ack().seq(), seq);
  }

  static v1::Error expect_error(FakeSession& session) {
    const auto reply = session.next();
    if (!reply || !reply->has_error()) {
      ADD_FAILURE() << "expected an error, got " << (reply ? reply->DebugString() : "nothing");
      return {};
    }
    return reply->error();
  }

  [[nodiscard]] geometry::CellIndex cell(double x, double y) const {
    return geometry::GridGeometry(core_.config().himm.cell_size_m).cell_of({x, y});
  }
  [[nodiscard]] bool occupied(double x, double y) { return core_.world("default")->snapshot()->occupied(cell(x, y)); }
  [[nodiscard]] bool observed(double x, double y) { return core_.world("default")->snapshot()->observed(cell(x, y)); }

  ServerCore core_;
};

TEST_F(SensorHandlers, SonarElementAtTheRingEdgeMarksAlongItsOwnAxis) {
  auto session = driver("r1", testing::sensor_robot_spec());
  handle_odometry(session, odometry(0.05, 0.05, 0.0, 0.0));
  // Element 2 faces +y from the ring's edge: (0.05 + 0.1, 0.05 + 0.25) = (0.15, 0.30).
  handle_range_array(session, one_sonar_element(1, 0.1, 2, 1.02F));
  expect_ack(*session, 1);
  // The echo lies 1.02 m along the element's axis: (0.15, 1.32).
  EXPECT_TRUE(occupied(0.15, 1.32));
  EXPECT_TRUE(observed(0.15, 0.85)) << "the axis before the echo is cleared";
  // Seed 001 §3's mapping starts the ray at the robot centre and lands 0.25 m short (and 0.1 m to
  // the side): that cell must not be marked.
  EXPECT_FALSE(occupied(0.05, 1.07));
  EXPECT_FALSE(occupied(0.15, 1.07)) << "ray traced from the ring centre instead of the element";
  // HIMM touches only the acoustic axis: a cell 0.4 m beside it, inside the cone, is untouched.
  EXPECT_FALSE(observed(0.55, 0.85));
  // The other elements read 0, below range_min: they carry no information and change nothing.
  EXPECT_FALSE(observed(0.65, 0.05));
  EXPECT_EQ(core_.world("default")->snapshot()->version(), 1U) << "one ray for the one valid element";
}

TEST_F(SensorHandlers, SonarElementsFollowTheRobotsHeading) {
  auto session = driver("r1", testing::sensor_robot_spec());
  // Facing +y, element 0 (ahead) sits at (0.05, 0.05 + 0.1 + 0.25) and looks along +y.
  handle_odometry(session, odometry(0.05, 0.05, M_PI / 2, 0.0));
  handle_range_array(session, one_sonar_element(1, 0.1, 0, 1.52F));
  expect_ack(*session, 1);
  EXPECT_TRUE(occupied(0.05, 1.92));
  EXPECT_FALSE(occupied(0.05, 1.57)) << "mapped from the robot centre";
}

TEST_F(SensorHandlers, MaxRangeSonarReadingCarvesNothingByDefault) {
  auto session = driver("r1", testing::sensor_robot_spec());
  handle_odometry(session, odometry(0.05, 0.05, 0.0, 0.0));
  // Element 0 at (0.40, 0.05) facing +x; a reading beyond range_max (3 m) is "no echo", mostly a specular miss.
  handle_range_array(session, one_sonar_element(1, 0.1, 0, 10.0F));
  expect_ack(*session, 1);
  EXPECT_FALSE(observed(1.05, 0.05)) << "a sonar's silence carved free space";
  EXPECT_EQ(core_.world("default")->snapshot()->occupied_cell_count(), 0U);
}

TEST_F(SensorHandlers, MaxRangeSonarReadingClearsWithoutMarkingWhenTheSpecSaysSo) {
  v1::RobotSpec spec = testing::sensor_robot_spec();
  spec.mutable_sensors(0)->mutable_ranges()->set_no_return_clear_m(10.0);
  auto session = driver("r1", spec);
  handle_odometry(session, odometry(0.05, 0.05, 0.0, 0.0));
  // Element 0 at (0.40, 0.05) facing +x; a reading beyond range_max (3 m) is "no echo".
  handle_range_array(session, one_sonar_element(1, 0.1, 0, 10.0F));
  expect_ack(*session, 1);
  EXPECT_TRUE(observed(3.35, 0.05)) << "cleared up to range_max";
  EXPECT_FALSE(occupied(3.35, 0.05));
  EXPECT_FALSE(observed(3.55, 0.05)) << "nothing beyond range_max";
  EXPECT_EQ(core_.world("default")->snapshot()->occupied_cell_count(), 0U);
  // Exactly range_max is no echo too.
  handle_range_array(session, one_sonar_element(2, 0.2, 0, static_cast<float>(R::kSonarRangeMax_m)));
  expect_ack(*session, 2);
  EXPECT_EQ(core_.world("default")->snapshot()->occupied_cell_count(), 0U);
}

TEST_F(SensorHandlers, ServoAngleRotatesTheBeam) {
  auto session = driver("r1", testing::sensor_robot_spec());
  handle_odometry(session, odometry(0.05, 0.05, M_PI / 2, 0.0));
  // Robot facing +y, servo at +45°: the beam points at 135° in the world.
  handle_servo_range(session, servo(1, 0.1, M_PI / 4, 1.5F));
  expect_ack(*session, 1);
  const double c = 1.5 * std::cos(3 * M_PI / 4);
  const double s = 1.5 * std::sin(3 * M_PI / 4);
  EXPECT_TRUE(occupied(0.05 + c, 0.05 + s));
  EXPECT_FALSE(occupied(0.05, 1.55)) << "servo angle ignored";
  // At the servo's limit the beam is perpendicular to the heading: along -x... and +x.
  handle_servo_range(session, servo(2, 0.2, R::kServoMin_rad, 1.02F));
  expect_ack(*session, 2);
  EXPECT_TRUE(occupied(1.07, 0.05));
}

TEST_F(SensorHandlers, EncoderTicksMoveThePoseAndPlaceTheNextSensorMessage) {
  auto session = driver("r1", testing::sensor_robot_spec());
  auto robot = core_.find_robot("r1");
  // A sensor message before any pose cannot be placed.
  handle_servo_range(session, servo(1, 0.0, 0.0, 1.0F));
  auto error = expect_error(*session);
  EXPECT_EQ(error.code(), v1::ERROR_OUT_OF_ORDER);
  EXPECT_EQ(error.field(), "servo_range");

  handle_wheel_encoders(session, ticks(1, 0.0, 500, 500));  // the first reading only sets the reference
  handle_wheel_encoders(session, ticks(2, 1.0, 1500, 1500));
  // 1000 ticks on both wheels at 3.25 mm per tick: 3.25 m straight ahead of the initial pose.
  handle_servo_range(session, servo(2, 1.0, 0.0, 1.02F));
  expect_ack(*session, 2);
  auto pose = robot->state().X_WB;
  ASSERT_TRUE(pose);
  EXPECT_NEAR(pose->x, 0.05 + 3.25, 1e-9);
  EXPECT_NEAR(pose->y, 0.05, 1e-9);
  EXPECT_NEAR(pose->theta, 0.0, 1e-12);
  // The servo reading was taken there: its echo is 1.02 m ahead of (3.30, 0.05).
  EXPECT_TRUE(occupied(4.32, 0.05));
  EXPECT_FALSE(occupied(1.07, 0.05)) << "placed at the initial pose";

  // Wheels turning opposite ways by 10 ticks each spin the robot in place by 2 * 0.0325 m / b.
  handle_wheel_encoders(session, ticks(3, 2.0, 1490, 1510));
  handle_servo_range(session, servo(3, 2.0, 0.0, 1.0F));
  expect_ack(*session, 3);
  pose = robot->state().X_WB;
  EXPECT_NEAR(pose->x, 3.30, 1e-9);
  EXPECT_NEAR(pose->theta, 2 * 10 * R::kMetresPerTick / R::kWheelSeparation_m, 1e-9);

  // Timestamps must not go backwards; the pose stays.
  handle_wheel_encoders(session, ticks(4, 1.5, 2000, 2000));
  error = expect_error(*session);
  EXPECT_EQ(error.code(), v1::ERROR_OUT_OF_ORDER);
  EXPECT_EQ(error.field(), "wheel_encoders.stamp_s");

  // Odometry resets the dead-reckoned pose; the next counts only set a new reference, and later
  // ones move on from the odometry pose.
  handle_odometry(session, odometry(10.0, 20.0, 0.0, 3.0));
  handle_wheel_encoders(session, ticks(5, 3.0, 9000, 9000));
  handle_wheel_encoders(session, ticks(6, 4.0, 9100, 9100));
  handle_servo_range(session, servo(4, 4.0, 0.0, 1.0F));
  expect_ack(*session, 4);
  pose = robot->state().X_WB;
  EXPECT_NEAR(pose->x, 10.0 + 0.325, 1e-9);
  EXPECT_NEAR(pose->y, 20.0, 1e-9);
}

TEST_F(SensorHandlers, EncoderCountsWrapAtTheDeclaredWidth) {
  auto spec = testing::sensor_robot_spec();
  spec.mutable_encoders()->set_counter_bits(16);
  auto session = driver("r1", spec);
  handle_wheel_encoders(session, ticks(1, 0.0, 65500, 65500));
  handle_wheel_encoders(session, ticks(2, 1.0, 64, 64));  // 100 ticks on, through the wrap
  handle_servo_range(session, servo(1, 1.0, 0.0, 1.0F));
  expect_ack(*session, 1);
  EXPECT_NEAR(core_.find_robot("r1")->state().X_WB->x, 0.05 + 0.325, 1e-9);
}

TEST_F(SensorHandlers, WheelEncodersNeedDeclaredEncoders) {
  auto spec = testing::sensor_robot_spec();
  spec.clear_encoders();
  auto session = driver("r1", spec);
  handle_wheel_encoders(session, ticks(1, 0.0, 0, 0));
  const auto error = expect_error(*session);
  EXPECT_EQ(error.code(), v1::ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(error.field(), "wheel_encoders");
}

TEST_F(SensorHandlers, PointCloudMarksOnlyPointsBetweenGroundAndRobotHeight) {
  auto session = driver("r1", testing::sensor_robot_spec());
  handle_odometry(session, odometry(0.05, 0.05, 0.0, 0.0));
  // The camera sits at (0.25, 0.05, 0.3) in the world, looking along +x.
  handle_point_cloud(session, cloud(1, 0.1,
                                    {
                                        1.02F, 0.0F, 0.0F,     // z 0.3: in the band, an obstacle at (1.27, 0.05)
                                        1.02F, 1.0F, 0.5F,     // z 0.8: above the 0.5 m robot, ignored
                                        1.02F, -1.0F, -0.28F,  // z 0.02: the ground, ignored
                                    }));
  expect_ack(*session, 1);
  EXPECT_TRUE(occupied(1.27, 0.05));
  EXPECT_TRUE(observed(0.75, 0.05)) << "cleared from the sensor's ground position";
  EXPECT_FALSE(observed(1.27, 1.05)) << "an overhang above the robot must not block it";
  EXPECT_FALSE(observed(1.27, -0.95)) << "the floor is not an obstacle";
  EXPECT_EQ(core_.world("default")->snapshot()->version(), 1U) << "one ray, one snapshot";
  // A robot turned by 90° sees the same point at (0.05, 1.27).
  handle_odometry(session, odometry(0.05, 0.05, M_PI / 2, 0.2));
  handle_point_cloud(session, cloud(2, 0.2, {1.02F, 0.0F, 0.1F}));
  expect_ack(*session, 2);
  EXPECT_TRUE(occupied(0.05, 1.27));
}

TEST_F(SensorHandlers, OrderIsSharedAcrossSensorKindsAndALaserlessRobotGetsNoCommands) {
  auto session = driver("r1", testing::sensor_robot_spec());
  handle_odometry(session, odometry(0.05, 0.05, 0.0, 0.0));
  handle_range_array(session, one_sonar_element(5, 1.0, 0, 1.0F));
  expect_ack(*session, 5);
  handle_servo_range(session, servo(5, 1.1, 0.0, 1.0F));  // seq repeated by another kind
  auto error = expect_error(*session);
  EXPECT_EQ(error.code(), v1::ERROR_OUT_OF_ORDER);
  EXPECT_EQ(error.field(), "servo_range.seq");
  EXPECT_EQ(error.seq(), 5U);
  handle_point_cloud(session, cloud(6, 0.9, {1.0F, 0.0F, 0.0F}));  // stamp before the range array's
  error = expect_error(*session);
  EXPECT_EQ(error.code(), v1::ERROR_OUT_OF_ORDER);
  EXPECT_EQ(error.field(), "point_cloud.stamp_s");
  handle_range_array(session, one_sonar_element(4, 1.2, 0, 1.0F));
  error = expect_error(*session);
  EXPECT_EQ(error.field(), "range_array.seq");
  // An equal stamp is allowed (sensors firing together), a higher seq is required.
  handle_point_cloud(session, cloud(6, 1.0, {1.0F, 0.0F, 0.0F}));
  expect_ack(*session, 6);
  handle_servo_range(session, servo(9, 1.0, 0.0, 1.0F));
  expect_ack(*session, 9);

  core_.drain();
  for (const auto& message : session->take_all()) {
    EXPECT_FALSE(message.has_motion_command()) << "a robot without a laser has no behaviour steering it";
  }
  const RobotState state = core_.find_robot("r1")->state();
  EXPECT_EQ(state.scans_ingested, 3U);
  EXPECT_EQ(state.scans_rejected, 3U);
  EXPECT_EQ(state.commands_sent, 0U);
}

TEST_F(SensorHandlers, BadSensorMessagesNameTheFieldAndLeaveTheMapAlone) {
  auto session = driver("r1", testing::sensor_robot_spec());
  handle_odometry(session, odometry(0.05, 0.05, 0.0, 0.0));
  std::vector<float> nan_at_3(R::kSonarElements, 1.0F);
  nan_at_3[3] = kNaNf;
  std::vector<float> negative_at_7(R::kSonarElements, 1.0F);
  negative_at_7[7] = -0.5F;
  std::vector<float> too_many_points(3 * (R::kDepthMaxPoints + 1), 1.0F);
  struct Case {
    std::function<void()> send;
    std::string field;
    std::string message_part;
  };
  const auto send_sonar = [&](v1::RangeArray m) { return [&, m] { handle_range_array(session, m); }; };
  const auto send_servo = [&](v1::ServoRange m) { return [&, m] { handle_servo_range(session, m); }; };
  const auto send_cloud = [&](v1::PointCloud m) { return [&, m] { handle_point_cloud(session, m); }; };
  auto wrong_sensor = sonar(1, 0.1, std::vector<float>(R::kSonarElements, 1.0F));
  wrong_sensor.set_sensor("depth");
  auto infinite_stamp = one_sonar_element(1, 0.1, 0, 1.0F);
  infinite_stamp.set_stamp_s(std::numeric_limits<double>::infinity());
  const std::vector<Case> cases = {
      {send_sonar(sonar(1, 0.1, std::vector<float>(7, 1.0F))), "range_array.ranges", "has 7 readings"},
      {send_sonar(sonar(1, 0.1, nan_at_3)), "range_array.ranges[3]", "finite"},
      {send_sonar(sonar(1, 0.1, negative_at_7)), "range_array.ranges[7]", "non-negative"},
      {send_sonar(wrong_sensor), "range_array.sensor", "not a range array"},
      {send_sonar(infinite_stamp), "range_array.stamp_s", "finite"},
      {send_servo(servo(1, 0.1, 2.0, 1.0F)), "servo_range.servo_angle_rad", "turns within"},
      {send_servo(servo(1, 0.1, kNaN, 1.0F)), "servo_range.servo_angle_rad", "nan"},
      {send_servo(servo(1, 0.1, 0.0, kNaNf)), "servo_range.range_m", "finite"},
      {send_servo(servo(1, 0.1, 0.0, -1.0F)), "servo_range.range_m", "non-negative"},
      {send_cloud(cloud(1, 0.1, {1, 2, 3, 4, 5, 6, 7})), "point_cloud.xyz", "has 7 values, not a multiple of 3"},
      {send_cloud(cloud(1, 0.1, {1, 2, 3, 4, kNaNf, 6})), "point_cloud.xyz[4]", "finite"},
      {send_cloud(cloud(1, 0.1, {7, 0, 0})), "point_cloud.xyz[0]", "beyond its range_max_m"},
      {send_cloud(cloud(1, 0.1, too_many_points)), "point_cloud.xyz", "at most 1000"},
  };
  for (const auto& c : cases) {
    c.send();
    const auto error = expect_error(*session);
    EXPECT_EQ(error.code(), v1::ERROR_INVALID_ARGUMENT) << c.field;
    EXPECT_EQ(error.field(), c.field);
    EXPECT_NE(error.message().find(c.message_part), std::string::npos) << error.message();
  }
  handle_wheel_encoders(session, ticks(1, kNaN, 0, 0));
  EXPECT_EQ(expect_error(*session).field(), "wheel_encoders.stamp_s");

  // Nothing reached the map, and a good message with the very seq the bad ones used is accepted.
  EXPECT_EQ(core_.world("default")->snapshot()->version(), 0U);
  handle_servo_range(session, servo(1, 0.1, 0.0, 1.0F));
  expect_ack(*session, 1);
  core_.drain();
  EXPECT_EQ(core_.find_robot("r1")->state().scans_rejected, cases.size());
}

TEST_F(SensorHandlers, DispatchRoutesTheNewKindsOnlyFromADriverWithASpec) {
  auto query = std::make_shared<FakeSession>(core_);
  v1::Hello hello;
  hello.set_protocol_version(proto::kProtocolVersion);
  hello.set_role(v1::ROLE_QUERY);
  handle_hello(query, hello);
  ASSERT_TRUE(query->next_of(v1::ServerMessage::kWelcome));
  auto driver_without_spec = std::make_shared<FakeSession>(core_);
  hello.set_role(v1::ROLE_DRIVER);
  hello.set_robot_id("r1");
  handle_hello(driver_without_spec, hello);
  ASSERT_TRUE(driver_without_spec->next_of(v1::ServerMessage::kWelcome));

  std::vector<std::pair<v1::ClientMessage, std::string>> messages(4);
  *messages[0].first.mutable_range_array() = one_sonar_element(1, 0.0, 0, 1.0F);
  *messages[1].first.mutable_servo_range() = servo(1, 0.0, 0.0, 1.0F);
  *messages[2].first.mutable_wheel_encoders() = ticks(1, 0.0, 0, 0);
  *messages[3].first.mutable_point_cloud() = cloud(1, 0.0, {1.0F, 0.0F, 0.0F});
  messages[0].second = "range_array";
  messages[1].second = "servo_range";
  messages[2].second = "wheel_encoders";
  messages[3].second = "point_cloud";
  for (const auto& [message, field] : messages) {
    dispatch(query, message);
    auto error = expect_error(*query);
    EXPECT_EQ(error.code(), v1::ERROR_NOT_ALLOWED);
    EXPECT_EQ(error.field(), field);
    dispatch(driver_without_spec, message);
    error = expect_error(*driver_without_spec);
    EXPECT_EQ(error.code(), v1::ERROR_OUT_OF_ORDER);
    EXPECT_EQ(error.field(), field);
  }
}

TEST_F(SensorHandlers, RobotSpecErrorsForTheNewKindsNameTheField) {
  auto session = std::make_shared<FakeSession>(core_);
  v1::Hello hello;
  hello.set_protocol_version(proto::kProtocolVersion);
  hello.set_role(v1::ROLE_DRIVER);
  hello.set_robot_id("r1");
  handle_hello(session, hello);
  ASSERT_TRUE(session->next_of(v1::ServerMessage::kWelcome));
  struct Case {
    std::function<void(v1::RobotSpec&)> damage;
    std::string field;
  };
  const auto skid = [](v1::RobotSpec& s) { return s.mutable_kinematics()->mutable_skid_steer(); };
  const std::vector<Case> robot_cases = {
      {[&](v1::RobotSpec& s) { skid(s)->set_left_slip(1.0); }, "robot_spec.kinematics.skid_steer.left_slip"},
      {[&](v1::RobotSpec& s) { skid(s)->set_right_slip(-0.1); }, "robot_spec.kinematics.skid_steer.right_slip"},
      {[&](v1::RobotSpec& s) { skid(s)->set_track_separation_m(0.0); },
       "robot_spec.kinematics.skid_steer.track_separation_m"},
      {[&](v1::RobotSpec& s) { skid(s)->set_left_sprocket_radius_m(kNaN); },
       "robot_spec.kinematics.skid_steer.left_sprocket_radius_m"},
      {[&](v1::RobotSpec& s) { skid(s)->set_max_track_speed_mps(-1.0); },
       "robot_spec.kinematics.skid_steer.max_track_speed_mps"},
      {[&](v1::RobotSpec& s) { skid(s)->set_powertrain_time_constant_s(-1.0); },
       "robot_spec.kinematics.skid_steer.powertrain_time_constant_s"},
      {[](v1::RobotSpec& s) {
         auto* drive = s.mutable_kinematics()->mutable_differential();
         drive->set_wheel_separation_m(0.5);
         drive->set_max_wheel_speed_mps(1.0);
       },
       "robot_spec.kinematics.differential.wheel_radius_m"},
      {[](v1::RobotSpec& s) { s.mutable_kinematics()->Clear(); }, "robot_spec.kinematics"},
      // ActivityBot ticks need encoders and a differential drive.
      {[](v1::RobotSpec& s) { s.set_command_units(v1::COMMAND_UNITS_ACTIVITYBOT_TICKS); }, "robot_spec.command_units"},
  };
  for (const auto& c : robot_cases) {
    auto spec = skid_steer_spec(1.0);
    c.damage(spec);
    handle_robot_spec(session, spec);
    const auto reply = session->next();
    ASSERT_TRUE(reply && reply->has_error()) << c.field;
    EXPECT_EQ(reply->error().field(), c.field);
  }
  const auto sensor = [](v1::RobotSpec& s, int i) { return s.mutable_sensors(i); };
  const std::vector<Case> sensor_cases = {
      {[](v1::RobotSpec& s) { s.mutable_encoders()->set_counter_bits(0); }, "robot_spec.encoders.counter_bits"},
      {[](v1::RobotSpec& s) { s.mutable_encoders()->set_counter_bits(65); }, "robot_spec.encoders.counter_bits"},
      {[](v1::RobotSpec& s) { s.mutable_encoders()->set_ticks_per_revolution(0); },
       "robot_spec.encoders.ticks_per_revolution"},
      {[](v1::RobotSpec& s) { s.mutable_encoders()->set_wheel_separation_m(kNaN); },
       "robot_spec.encoders.wheel_separation_m"},
      {[](v1::RobotSpec& s) { s.mutable_initial_pose()->set_x(kNaN); }, "robot_spec.initial_pose.x"},
      {[&](v1::RobotSpec& s) { sensor(s, 0)->mutable_range_array()->clear_elements(); },
       "robot_spec.sensors[0].range_array.elements"},
      {[&](v1::RobotSpec& s) { sensor(s, 0)->mutable_range_array()->mutable_elements(2)->set_theta(kNaN); },
       "robot_spec.sensors[0].range_array.elements[2].theta"},
      {[&](v1::RobotSpec& s) { sensor(s, 0)->mutable_range_array()->set_range_min_m(5.0); },
       "robot_spec.sensors[0].range_array.range_min_m"},
      {[&](v1::RobotSpec& s) { sensor(s, 0)->mutable_range_array()->set_range_max_m(1000.0); },
       "robot_spec.sensors[0].range_array.range_max_m"},
      {[&](v1::RobotSpec& s) { sensor(s, 0)->mutable_range_array()->set_beam_width_rad(0.0); },
       "robot_spec.sensors[0].range_array.beam_width_rad"},
      {[&](v1::RobotSpec& s) { sensor(s, 0)->mutable_range_array()->set_period_s(-1.0); },
       "robot_spec.sensors[0].range_array.period_s"},
      {[&](v1::RobotSpec& s) { sensor(s, 1)->mutable_servo_range()->set_servo_max_rad(R::kServoMin_rad); },
       "robot_spec.sensors[1].servo_range.servo_max_rad"},
      {[&](v1::RobotSpec& s) { sensor(s, 1)->mutable_servo_range()->set_servo_min_rad(kNaN); },
       "robot_spec.sensors[1].servo_range.servo_min_rad"},
      {[&](v1::RobotSpec& s) { sensor(s, 1)->mutable_servo_range()->set_servo_step_rad(0.0); },
       "robot_spec.sensors[1].servo_range.servo_step_rad"},
      {[&](v1::RobotSpec& s) { sensor(s, 1)->mutable_servo_range()->set_range_min_m(-0.1); },
       "robot_spec.sensors[1].servo_range.range_min_m"},
      {[&](v1::RobotSpec& s) { sensor(s, 2)->mutable_point_cloud()->set_range_max_m(0.0); },
       "robot_spec.sensors[2].point_cloud.range_max_m"},
      {[&](v1::RobotSpec& s) { sensor(s, 2)->mutable_point_cloud()->set_max_points(200001); },
       "robot_spec.sensors[2].point_cloud.max_points"},
      {[&](v1::RobotSpec& s) { sensor(s, 2)->set_name("sonar"); }, "robot_spec.sensors[2].name"},
      {[&](v1::RobotSpec& s) { sensor(s, 1)->clear_servo_range(); }, "robot_spec.sensors[1]"},
      {[](v1::RobotSpec& s) { s.set_command_units(static_cast<v1::CommandUnits>(7)); }, "robot_spec.command_units"},
  };
  for (const auto& c : sensor_cases) {
    auto spec = testing::sensor_robot_spec();
    c.damage(spec);
    handle_robot_spec(session, spec);
    const auto reply = session->next();
    ASSERT_TRUE(reply && reply->has_error()) << c.field;
    EXPECT_EQ(reply->error().field(), c.field);
  }
  EXPECT_EQ(core_.find_robot("r1"), nullptr) << "a rejected spec registers nothing";
}

// The decided body velocity is what the tracks produce after slipping: the rim speeds sent are
// larger than the ground speeds by 1 / (1 - slip).
TEST_F(SensorHandlers, SkidSteerCommandsCompensateSlippage) {
  v1::LaserScan scan;
  scan.set_sensor("front_laser");
  // Obstacles 1.2 m away on the right half, open on the left: the behaviour turns left.
  for (int i = 0; i < 181; ++i) scan.add_ranges(i < 80 ? 1.2F : 6.0F);
  const control::ScanView view{-M_PI / 2, M_PI / 180,
                               std::span<const float>(scan.ranges().data(), scan.ranges().size()), 8.0};
  // The robot's Bearcat turns wheel speeds into motion with the robot's own track separation (0.6 m below).
  control::BearcatParams bearcat = core_.config().bearcat;
  bearcat.wheel_separation_m = 0.6;
  const control::BearcatDecision decision = control::BearcatBehaviour(bearcat).decide(view);
  ASSERT_FALSE(decision.stop);

  for (const double max_track_speed_mps : {10.0, 0.2}) {
    SCOPED_TRACE(max_track_speed_mps);
    const std::string id = "tracked" + std::to_string(static_cast<int>(max_track_speed_mps * 10));
    const auto spec = skid_steer_spec(max_track_speed_mps);
    const geometry::SkidSteerParams params{0.6, 0.1, 0.12, 0.1, 0.25, max_track_speed_mps};
    auto session = driver(id, spec);
    handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
    scan.set_seq(1);
    handle_laser_scan(session, scan);
    const auto reply = session->next_of(v1::ServerMessage::kMotionCommand);
    ASSERT_TRUE(reply);
    const v1::MotionCommand& command = reply->motion_command();
    const geometry::WheelSpeeds rims{command.left_wheel_mps(), command.right_wheel_mps()};
    const geometry::BodyVelocity produced = geometry::to_body(rims, params);
    // linear/angular describe what the sent rim speeds do, slippage included.
    EXPECT_NEAR(produced.linear_mps, command.linear_mps(), 1e-12);
    EXPECT_NEAR(produced.angular_radps, command.angular_radps(), 1e-12);
    // Ground speeds are (1 - s) times the rim speeds.
    EXPECT_NEAR((1 - 0.1) * rims.left_mps, command.linear_mps() - command.angular_radps() * 0.3, 1e-12);
    EXPECT_NEAR((1 - 0.25) * rims.right_mps, command.linear_mps() + command.angular_radps() * 0.3, 1e-12);
    if (max_track_speed_mps > 1.0) {
      // Within the limit: exactly the decided body velocity.
      EXPECT_NEAR(command.linear_mps(), decision.linear_mps, 1e-12);
      EXPECT_NEAR(command.angular_radps(), decision.angular_radps, 1e-12);
    } else {
      // Clamped: the faster track at the limit, the path's curvature kept.
      EXPECT_NEAR(std::max(std::abs(rims.left_mps), std::abs(rims.right_mps)), max_track_speed_mps, 1e-12);
      ASSERT_NE(decision.linear_mps, 0.0);
      EXPECT_NEAR(command.angular_radps() / command.linear_mps(), decision.angular_radps / decision.linear_mps, 1e-9);
    }
  }
  EXPECT_NE(decision.angular_radps, 0.0) << "the scan should make the robot turn";
}

}  // namespace
}  // namespace occgeo::service
