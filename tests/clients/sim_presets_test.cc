// The scout, activitybot and ugv presets against their seeds, and the sensors, encoders, drive_goto, skid steer and
// drive scripts they brought.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "occgeo/geometry/dead_reckoning.h"
#include "occgeo/geometry/kinematics.h"
#include "occgeo/sim/args.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/range_sensors.h"
#include "occgeo/sim/robot.h"
#include "occgeo/sim/shape_world.h"
#include "occgeo/sim/sim_world.h"
#include "occgeo/sim/simulation.h"
#include "occgeo/sim/world.h"

namespace occgeo::sim {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDegree = kPi / 180.0;
const std::filesystem::path kWorlds = std::filesystem::path(OCCGEO_SOURCE_DIR) / "clients" / "sim" / "worlds";

const RobotPreset& preset_named(const std::string& name) {
  const RobotPreset* preset = find_robot_preset(name);
  if (preset == nullptr) throw std::runtime_error("no preset " + name);
  return *preset;
}

// A world with nothing in it but one far-away pixel, so robots can drive freely.
World empty_world() { return World::from_rows({"#"}, 0.1, {100.0, 100.0}); }

TEST(RobotPresets, ScoutHasARingOfSixteenSonars) {
  const RobotPreset& scout = preset_named("scout");
  const auto& drive = std::get<geometry::DifferentialDriveParams>(scout.kinematics);
  EXPECT_EQ(drive.wheel_separation_m, 0.34);
  EXPECT_EQ(drive.wheel_radius_m, 0.095);
  EXPECT_EQ(drive.max_wheel_speed_mps, 1.0);
  EXPECT_EQ(scout.footprint.length, 0.41);  // the box around the 0.41 m round body
  EXPECT_EQ(scout.footprint.width, 0.41);
  EXPECT_EQ(scout.laser(), nullptr);
  EXPECT_FALSE(scout.encoders);
  ASSERT_EQ(scout.sensors.size(), 1U);
  const auto& sonar = std::get<RangeArrayPreset>(scout.sensors[0]);
  ASSERT_EQ(sonar.elements.size(), 16U);
  for (std::size_t k = 0; k < 16; ++k) {
    const double yaw = k * 22.5 * kDegree;  // sonar 0 ahead, counter-clockwise (seed 001: front sonars 0-2, 13-15)
    EXPECT_NEAR(sonar.elements[k].theta, yaw, 1e-12);
    EXPECT_NEAR(sonar.elements[k].x, 0.2 * std::cos(yaw), 1e-12);
    EXPECT_NEAR(sonar.elements[k].y, 0.2 * std::sin(yaw), 1e-12);
  }
  EXPECT_NEAR(sonar.beam_width_rad, 25.0 * kDegree, 1e-12);
  EXPECT_EQ(sonar.range_min_m, 0.15);
  EXPECT_EQ(sonar.range_max_m, 6.5);
  EXPECT_EQ(sonar.period_s, 0.2);
  EXPECT_EQ(sonar.range_noise_fraction, 0.01);
  EXPECT_EQ(sonar.rays_per_beam % 2, 1U);
}

TEST(RobotPresets, ActivityBotMatchesSeed003) {
  const RobotPreset& bot = preset_named("activitybot");
  ASSERT_TRUE(bot.encoders);
  EXPECT_EQ(bot.encoders->ticks_per_revolution, 64.0);
  EXPECT_NEAR(geometry::metres_per_tick(*bot.encoders), 0.00325, 1e-9);
  EXPECT_NEAR(bot.encoders->wheel_separation_m, 0.1058, 1e-12);
  const auto& drive = std::get<geometry::DifferentialDriveParams>(bot.kinematics);
  EXPECT_NEAR(drive.max_wheel_speed_mps, 128 * 0.00325, 1e-9);  // drive_setMaxSpeed default, 128 ticks/s
  EXPECT_EQ(bot.drive_goto_speed_mps, drive.max_wheel_speed_mps);
  EXPECT_EQ(drive.wheel_separation_m, bot.encoders->wheel_separation_m);
  ASSERT_EQ(bot.sensors.size(), 1U);
  const auto& lidar = std::get<ServoRangePreset>(bot.sensors[0]);
  EXPECT_NEAR(lidar.servo_min_rad, -kPi / 2.0, 1e-12);  // servo_angle 0 of 0..1800 tenths, 900 ahead
  EXPECT_NEAR(lidar.servo_max_rad, kPi / 2.0, 1e-12);
  EXPECT_NEAR(lidar.servo_step_rad, kDegree, 1e-12);
  EXPECT_EQ(lidar.step_period_s, 0.02);  // the LIDAR-Lite's 50 Hz rep rate (the thesis paused 0.5 s)
  EXPECT_EQ(lidar.range_max_m, 40.0);
  EXPECT_EQ(lidar.noise_sigma_near_m, 0.025);
  EXPECT_EQ(lidar.noise_sigma_far_m, 0.10);
  EXPECT_EQ(lidar.noise_far_from_m, 5.0);
}

TEST(RobotPresets, UgvMatchesSeed004) {
  const RobotPreset& ugv = preset_named("ugv");
  const auto& skid = std::get<SkidSteerPreset>(ugv.kinematics);
  EXPECT_EQ(skid.params.track_separation_m, geometry::ugv_skid_steer_params().track_separation_m);
  // The tracks slip, unequally (the thesis gives no values; these are the preset's documented assumptions).
  EXPECT_EQ(skid.params.left_slip, 0.04);
  EXPECT_EQ(skid.params.right_slip, 0.06);
  EXPECT_EQ(skid.powertrain_time_constant_s, 0.1);
  EXPECT_NEAR(ugv.footprint.length, 27 * 0.0254, 1e-12);
  EXPECT_NEAR(ugv.footprint.width, 15 * 0.0254, 1e-12);
  ASSERT_NE(ugv.laser(), nullptr);
  const LaserPreset& urg = *ugv.laser();
  EXPECT_EQ(urg.beam_count, 682U);
  EXPECT_NEAR(urg.angle_min_rad, -120.0 * kDegree, 1e-12);
  EXPECT_NEAR(urg.angle_min_rad + 681 * urg.angle_increment_rad, 120.0 * kDegree, 1e-12);
  EXPECT_EQ(urg.range_min_m, 0.02);
  EXPECT_EQ(urg.range_max_m, 4.0);
  EXPECT_EQ(urg.range_noise_sigma_m, 0.020);
  EXPECT_EQ(urg.scan_period_s, 0.1);
  EXPECT_LT(urg.mount_height_m, 0.7) << "below the top of seed 004's cone";
}

// 45 x 41 pixels of 0.1 m from (-1, -2.05): a wall (column 40) from x = 3.0 to 3.1, y from -2.05 to 2.05, so the
// origin is in row 20.
PixelWorld sonar_wall_world() {
  std::vector<std::string> rows(41, std::string(45, '.'));
  for (std::string& row : rows) row[40] = '#';
  const std::vector<std::string_view> views(rows.begin(), rows.end());
  return PixelWorld(World::from_rows(views, 0.1, {-1.0, -2.05}));
}

// The scout's sonar reduced to one noise-free element at pose X_SE in the sensor frame.
RangeArrayPreset one_sonar(const geometry::Pose2& X_SE) {
  RangeArrayPreset sonar = std::get<RangeArrayPreset>(preset_named("scout").sensors[0]);
  sonar.elements = {X_SE};
  sonar.range_noise_fraction = 0.0;
  return sonar;
}

TEST(RangeArray, ScoutSonarIsSpecularWithinEightDegrees) {
  const auto& sonar = std::get<RangeArrayPreset>(preset_named("scout").sensors[0]);
  EXPECT_NEAR(sonar.specular_tolerance_rad, 8.0 * kDegree, 1e-12);
  // Over half the ray spacing, so the ray nearest a surface normal inside the cone always qualifies.
  EXPECT_GT(sonar.specular_tolerance_rad, 0.5 * sonar.beam_width_rad / (sonar.rays_per_beam - 1));
}

TEST(RangeArray, SonarFacingAWallSquarelyReadsItsDistanceAndMarksTheAxisPixel) {
  RangeArraySimulator simulator(one_sonar({0.0, 0.0, 0.0}), 1);
  const SimulatedScan scan = simulator.fire(sonar_wall_world(), {}, 0.0);
  ASSERT_EQ(scan.ranges_m.size(), 1U);
  EXPECT_NEAR(scan.ranges_m[0], 3.0, 1e-5);
  ASSERT_EQ(scan.hit_pixels.size(), 1U) << "only the acoustic axis marks pixels";
  EXPECT_EQ(scan.hit_pixels[0], (Pixel{40, 20}));
}

TEST(RangeArray, SonarAtFortyFiveDegreesToAWallHearsNoEcho) {
  // From (1.5, -1.5) at 45° every ray of the 25° cone meets the wall at 32.5° to 57.5° incidence: the pulse bounces
  // away. The rays do hit the wall, so it is the specular rule that silences them.
  const PixelWorld world = sonar_wall_world();
  const geometry::Pose2 X_SE{1.5, -1.5, 45.0 * kDegree};
  const auto axis_hit = world.cast(X_SE.position(), {std::cos(X_SE.theta), std::sin(X_SE.theta)}, 6.5, 0.0, 0.3);
  ASSERT_TRUE(axis_hit);
  EXPECT_NEAR(axis_hit->distance_m, 1.5 * std::sqrt(2.0), 1e-9);
  RangeArraySimulator simulator(one_sonar(X_SE), 1);
  const SimulatedScan scan = simulator.fire(world, {}, 0.0);
  ASSERT_EQ(scan.ranges_m.size(), 1U);
  EXPECT_EQ(scan.ranges_m[0], 6.5F) << "no echo reads exactly range_max";
  EXPECT_TRUE(scan.hit_pixels.empty()) << "an axis ray that hears nothing maps nothing";
}

TEST(RangeArray, WallTenDegreesOffTheAxisReadsThePerpendicularDistance) {
  // Facing -10°: the wall's normal is 10° off the axis, inside the 25° cone. The rays lie at -22.5°, -18.3°, ...,
  // -1.7°, +2.5°; those within 8° of the normal echo, and the nearest of them (-1.7°) reads 3 / cos 1.7°, the
  // perpendicular distance to 0.05%. The axis ray itself meets the wall at 10° incidence, so it marks no pixel.
  RangeArraySimulator simulator(one_sonar({0.0, 0.0, -10.0 * kDegree}), 1);
  const SimulatedScan scan = simulator.fire(sonar_wall_world(), {}, 0.0);
  ASSERT_EQ(scan.ranges_m.size(), 1U);
  EXPECT_NEAR(scan.ranges_m[0], 3.0 / std::cos(-10.0 * kDegree + 25.0 * kDegree / 3.0), 1e-5);
  EXPECT_NEAR(scan.ranges_m[0], 3.0, 0.0015);
  EXPECT_TRUE(scan.hit_pixels.empty()) << "the axis ray's own echo is not accepted";

  // Without the specular rule (a tolerance of 90° accepts every hit) the same reading results: the perpendicular foot
  // is also the nearest point of the wall. The axis ray's echo (3 / cos 10°, 4.6 cm farther) is then heard but masked
  // by the nearer one the element reports, so its pixel is still not what the reading saw.
  RangeArrayPreset every_echo = one_sonar({0.0, 0.0, -10.0 * kDegree});
  every_echo.specular_tolerance_rad = kPi / 2.0;
  RangeArraySimulator nearest(every_echo, 1);
  const SimulatedScan nearest_scan = nearest.fire(sonar_wall_world(), {}, 0.0);
  EXPECT_NEAR(nearest_scan.ranges_m[0], scan.ranges_m[0], 1e-6);
  EXPECT_TRUE(nearest_scan.hit_pixels.empty());
}

TEST(RangeArray, CircleOffTheAxisInsideTheConeEchoesFromItsNearestPoint) {
  // A pillar of radius 0.3 m centred 2 m away on the ray 25°/3 = 8.3° off the axis: that ray meets it head on at its
  // nearest point, 1.7 m away. The axis ray misses it and hears nothing (no other obstacle), so no pixel is marked.
  const double bearing = 25.0 * kDegree / 3.0;
  const ShapeWorld world({Shape::circle({2.0 * std::cos(bearing), 2.0 * std::sin(bearing)}, 0.3)}, {});
  RangeArraySimulator simulator(one_sonar({0.0, 0.0, 0.0}), 1);
  const SimulatedScan scan = simulator.fire(world, {}, 0.0);
  ASSERT_EQ(scan.ranges_m.size(), 1U);
  EXPECT_NEAR(scan.ranges_m[0], 1.7, 1e-5);
  EXPECT_TRUE(scan.hit_pixels.empty());

  // The same pillar 30° off the axis is outside the cone: no echo.
  const ShapeWorld outside({Shape::circle({2.0 * std::cos(30.0 * kDegree), 2.0 * std::sin(30.0 * kDegree)}, 0.3)}, {});
  EXPECT_EQ(simulator.fire(outside, {}, 0.0).ranges_m[0], 6.5F);
}

TEST(RangeArray, RefusesASpecularToleranceOutsideZeroToNinetyDegrees) {
  for (const double tolerance : {0.0, -0.1, kPi / 2.0 + 0.01, std::nan("")}) {
    RangeArrayPreset sonar = one_sonar({0.0, 0.0, 0.0});
    sonar.specular_tolerance_rad = tolerance;
    try {
      RangeArraySimulator simulator(sonar, 1);
      ADD_FAILURE() << "accepted specular_tolerance_rad " << tolerance;
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find("specular_tolerance_rad"), std::string::npos) << error.what();
      EXPECT_NE(std::string(error.what()).find("sonar_ring"), std::string::npos) << error.what();
    }
  }
}

TEST(RangeArray, RefusesAnEvenRayCount) {
  RangeArrayPreset sonar = std::get<RangeArrayPreset>(preset_named("scout").sensors[0]);
  sonar.rays_per_beam = 6;
  EXPECT_THROW(RangeArraySimulator(sonar, 1), std::invalid_argument);
}

TEST(ServoRange, SweepsPingPongInOneDegreeSteps) {
  ServoRangeSimulator servo(std::get<ServoRangePreset>(preset_named("activitybot").sensors[0]), 1);
  EXPECT_EQ(servo.steps_per_sweep(), 180U);
  EXPECT_NEAR(servo.servo_angle_of(0), -kPi / 2.0, 1e-12);
  EXPECT_NEAR(servo.servo_angle_of(1), -89.0 * kDegree, 1e-12);
  EXPECT_NEAR(servo.servo_angle_of(90), 0.0, 1e-12);
  EXPECT_EQ(servo.servo_angle_of(180), kPi / 2.0);
  EXPECT_NEAR(servo.servo_angle_of(181), 89.0 * kDegree, 1e-12);
  EXPECT_NEAR(servo.servo_angle_of(360), -kPi / 2.0, 1e-12);
  EXPECT_NEAR(servo.servo_angle_of(361), -89.0 * kDegree, 1e-12);
}

TEST(ServoRange, ActivityBotSendsEncodersThenOneReadingPerStep) {
  Simulation simulation(load_world(kWorlds / "room.yaml"), preset_named("activitybot"), {}, 1);
  std::vector<double> angles;
  std::uint64_t seq = 0;
  for (int step = 0; step < 100; ++step) {
    if (simulation.batch_due()) {
      EXPECT_EQ(step % 2, 0) << "every 0.02 s";
      const SensorBatch batch = simulation.take_batch();
      ASSERT_EQ(batch.messages.size(), 2U);
      ASSERT_TRUE(batch.messages[0].has_wheel_encoders()) << "the pose message first; no odometry";
      ASSERT_TRUE(batch.messages[1].has_servo_range());
      const v1::ServoRange& reading = batch.messages[1].servo_range();
      EXPECT_EQ(reading.seq(), ++seq);
      EXPECT_EQ(batch.last_sensor_seq, seq);
      EXPECT_EQ(batch.steering_scan_seq, seq) << "no laser, no range array: the server answers each servo reading";
      EXPECT_NEAR(reading.stamp_s(), step * 0.01, 1e-12);
      EXPECT_EQ(batch.messages[0].wheel_encoders().stamp_s(), reading.stamp_s());
      EXPECT_GT(reading.range_m(), 0.5F);
      angles.push_back(reading.servo_angle_rad());
    }
    simulation.step();
  }
  ASSERT_EQ(angles.size(), 50U);
  for (std::size_t i = 0; i < angles.size(); ++i) EXPECT_NEAR(angles[i], (-90.0 + i) * kDegree, 1e-12);
  EXPECT_FALSE(simulation.visible_pixels().empty());
  EXPECT_EQ(simulation.message_counts().at("servo_range"), 50U);
  EXPECT_FALSE(simulation.message_counts().contains("odometry"));
}

TEST(RangeArray, ScoutSendsOdometryThenTheRingEveryPeriod) {
  Simulation simulation(load_world(kWorlds / "room.yaml"), preset_named("scout"), {}, 1);
  int batches = 0;
  for (int step = 0; step < 100; ++step) {
    if (simulation.batch_due()) {
      EXPECT_EQ(step % 20, 0) << "every 0.2 s";
      const SensorBatch batch = simulation.take_batch();
      ASSERT_EQ(batch.messages.size(), 2U);
      EXPECT_TRUE(batch.messages[0].has_odometry());
      ASSERT_TRUE(batch.messages[1].has_range_array());
      EXPECT_EQ(batch.messages[1].range_array().ranges_size(), 16);
      EXPECT_EQ(batch.messages[1].range_array().seq(), static_cast<std::uint64_t>(++batches));
      const auto& ranges = batch.messages[1].range_array().ranges();
      for (int k = 0; k < 16; k += 4)
        EXPECT_LT(ranges[k], 6.5F) << "sonar " << k << " faces a wall within 5 m squarely";
      // The walls are axis-aligned, so the sonars at 45° to the axes (cones 32.5° to 57.5° off) hear no wall; the one
      // at 135° hears the pillar of radius 0.3 m at (-3, 2.2), 3.72 m from the centre, across its round face (the
      // surface the pixels draw, not their axis-aligned faces), from the ring 0.2 m out.
      for (const int k : {2, 10, 14}) EXPECT_EQ(ranges[k], 6.5F) << "sonar " << k;
      EXPECT_NEAR(ranges[6], std::hypot(3.0, 2.2) - 0.3 - 0.2, 0.15) << "sonar 6 (1 % noise, 0.1 m pixels)";
    }
    simulation.step();
  }
  EXPECT_EQ(batches, 5);
  EXPECT_FALSE(simulation.visible_pixels().empty());
}

TEST(Encoders, TicksAreWholeTicksOfTheTrueTravel) {
  SimulatedRobot robot(empty_world(), preset_named("activitybot"), {});
  for (int step = 0; step < 37; ++step) {
    robot.command({.left_mps = 0.1, .right_mps = -0.05});
    robot.step();
  }
  EXPECT_NEAR(robot.left_travel_m(), 0.037, 1e-12);
  EXPECT_NEAR(robot.right_travel_m(), -0.0185, 1e-12);
  EXPECT_EQ(robot.encoder_ticks().left, 11);   // 11.38 ticks
  EXPECT_EQ(robot.encoder_ticks().right, -5);  // -5.69 ticks, toward zero
}

TEST(DriveGoto, DrivesOneMetreToTheTick) {
  SimulatedRobot robot(empty_world(), preset_named("activitybot"), {});
  const auto [left, right] = geometry::drive_goto_ticks_for_distance(1.0);
  robot.drive_goto(left, right);
  for (int step = 0; step < 1000 && robot.drive_goto_active(); ++step) robot.step();
  EXPECT_FALSE(robot.drive_goto_active());
  EXPECT_NEAR(robot.pose().x, 1.0, 0.00325);
  EXPECT_NEAR(robot.pose().x, left * 0.00325, 1e-6);
  EXPECT_NEAR(robot.pose().y, 0.0, 1e-9);
  EXPECT_EQ(robot.encoder_ticks().left, left);
  EXPECT_EQ(robot.encoder_ticks().right, right);
  // At 128 ticks/s, 308 ticks take 2.41 s.
  EXPECT_NEAR(robot.time_s(), left / 128.0, 0.02);
}

TEST(DriveGoto, TurnsNinetyDegreesInPlace) {
  SimulatedRobot robot(empty_world(), preset_named("activitybot"), {});
  const auto [left, right] = geometry::drive_goto_ticks_for_turn(kPi / 2.0);
  robot.drive_goto(left, right);
  for (int step = 0; step < 1000 && robot.drive_goto_active(); ++step) robot.step();
  const double one_tick_of_turn_rad = 2.0 * 0.00325 / 0.1058;  // both wheels off by half a tick
  EXPECT_NEAR(robot.pose().theta, kPi / 2.0, one_tick_of_turn_rad);
  EXPECT_NEAR(robot.pose().theta, (right - left) * 0.00325 / 0.1058, 1e-6);
  EXPECT_NEAR(robot.pose().position().norm(), 0.0, 1e-9) << "in place";
}

TEST(DriveGoto, PivotsAboutTheHeldWheel) {
  SimulatedRobot robot(empty_world(), preset_named("activitybot"), {});
  const auto [left, right] = geometry::drive_goto_ticks_for_pivot_turn(kPi / 2.0);
  EXPECT_EQ(left, 0);
  robot.drive_goto(left, right);
  for (int step = 0; step < 1000 && robot.drive_goto_active(); ++step) robot.step();
  EXPECT_NEAR(robot.pose().theta, kPi / 2.0, 0.00325 / 0.1058);
  // The held (left) wheel's contact point stays where it was.
  const Eigen::Vector2d left_wheel =
      robot.pose().position() + 0.0529 * Eigen::Vector2d(-std::sin(robot.pose().theta), std::cos(robot.pose().theta));
  EXPECT_NEAR((left_wheel - Eigen::Vector2d(0.0, 0.0529)).norm(), 0.0, 1e-9);
  EXPECT_EQ(robot.encoder_ticks().left, 0);
  EXPECT_EQ(robot.encoder_ticks().right, right);
}

// A UGV whose tracks slip (10% left, 5% right); the simulated tracks slip exactly as declared.
RobotPreset slipping_ugv() {
  RobotPreset preset = preset_named("ugv");
  auto& skid = std::get<SkidSteerPreset>(preset.kinematics);
  skid.params.left_slip = 0.10;
  skid.params.right_slip = 0.05;
  return preset;
}

TEST(SkidSteer, LagReaches63PercentAtTheTimeConstant) {
  SimulatedRobot robot(empty_world(), slipping_ugv(), {});
  for (int step = 0; step < 10; ++step) {  // τ = 0.1 s
    robot.command({.left_mps = 0.5, .right_mps = 0.5});
    robot.step();
  }
  EXPECT_NEAR(robot.rim_speeds().left_mps, 0.5 * (1.0 - std::exp(-1.0)), 1e-12);
  EXPECT_NEAR(robot.rim_speeds().right_mps, 0.5 * (1.0 - std::exp(-1.0)), 1e-12);
}

// After the lag settles (2 s = 20 τ), one more second of driving matches geometry::to_body with slip plus integrate.
void expect_closed_form_after_settling(const geometry::WheelSpeeds& rim) {
  const RobotPreset preset = slipping_ugv();
  SimulatedRobot robot(empty_world(), preset, {});
  const auto drive = [&](int steps) {
    for (int step = 0; step < steps; ++step) {
      robot.command({.left_mps = rim.left_mps, .right_mps = rim.right_mps});
      robot.step();
    }
  };
  drive(200);
  const geometry::Pose2 settled = robot.pose();
  drive(100);
  const geometry::BodyVelocity body = geometry::to_body(rim, std::get<SkidSteerPreset>(preset.kinematics).params);
  const geometry::Pose2 expected = geometry::integrate(settled, body, 1.0);
  EXPECT_NEAR(robot.pose().x, expected.x, 1e-6);
  EXPECT_NEAR(robot.pose().y, expected.y, 1e-6);
  EXPECT_NEAR(robot.pose().theta, expected.theta, 1e-6);
  EXPECT_NEAR(robot.velocity().linear_mps, body.linear_mps, 1e-6);
}

TEST(SkidSteer, StraightCommandVeersByTheDeclaredSlip) {
  expect_closed_form_after_settling({0.5, 0.5});
  const geometry::BodyVelocity body =
      geometry::to_body(geometry::WheelSpeeds{0.5, 0.5}, std::get<SkidSteerPreset>(slipping_ugv().kinematics).params);
  EXPECT_GT(body.angular_radps, 0.0) << "the left track slips more, so the UGV turns left";
}

TEST(SkidSteer, ArcMatchesTheClosedForm) { expect_closed_form_after_settling({0.3, 0.6}); }

TEST(SkidSteer, StopRunsTheTracksDownThroughTheLag) {
  SimulatedRobot robot(empty_world(), preset_named("ugv"), {});
  for (int step = 0; step < 100; ++step) {
    robot.command({.left_mps = 0.5, .right_mps = 0.5});
    robot.step();
  }
  robot.command({.stop = true});
  robot.step();
  EXPECT_NEAR(robot.rim_speeds().left_mps, 0.5 * std::exp(-0.1), 1e-4);
  for (int step = 0; step < 1000; ++step) robot.step();
  EXPECT_EQ(robot.rim_speeds().left_mps, 0.0);
  EXPECT_EQ(robot.velocity().linear_mps, 0.0);
}

TEST(DriveScript, ScoutFollowsItAndIgnoresServerCommands) {
  Simulation simulation(load_world(kWorlds / "room.yaml"), preset_named("scout"), {}, 1);
  simulation.set_drive_script({{0.0, 0.5, 1.0}, {0.2, 0.0, 1.0}});
  v1::MotionCommand command;
  command.set_left_wheel_mps(-1.0);
  command.set_right_wheel_mps(-1.0);
  simulation.apply_command(command);
  for (int step = 0; step < 100; ++step) simulation.step();
  EXPECT_NEAR(simulation.robot().pose().theta, 0.5, 1e-9);
  EXPECT_NEAR(simulation.robot().pose().position().norm(), 0.0, 1e-9);
  for (int step = 0; step < 100; ++step) simulation.step();
  EXPECT_NEAR(simulation.robot().pose().x, 0.2 * std::cos(0.5), 1e-9);
  EXPECT_NEAR(simulation.robot().pose().y, 0.2 * std::sin(0.5), 1e-9);
  for (int step = 0; step < 100; ++step) simulation.step();  // round again: turning
  EXPECT_NEAR(simulation.robot().pose().theta, 1.0, 1e-9);
  EXPECT_EQ(simulation.command_count(), 0U);
  EXPECT_EQ(simulation.ignored_command_count(), 1U);
}

TEST(DriveScript, SegmentBoundariesDoNotDriftOverManyLoops) {
  Simulation simulation(load_world(kWorlds / "room.yaml"), preset_named("activitybot"), {}, 1);
  simulation.set_drive_script(parse_drive_script("0,0,7.2;0,0.8,2"));
  for (int step = 0; step < 3000; ++step) simulation.step();  // 30 s: three whole loops of 9.2 s, then standing
  EXPECT_NEAR(simulation.robot().pose().theta, 3 * 1.6 - 2.0 * kPi, 1e-9);
  EXPECT_THROW(simulation.set_drive_script({{0.0, 0.0, 0.001}}), std::invalid_argument) << "under one physics step";
}

TEST(DriveScript, ParsesSegmentsAndNamesTheFlagInErrors) {
  const DriveScript script = parse_drive_script("0,0.5,12.6;0.3,0,3");
  ASSERT_EQ(script.size(), 2U);
  EXPECT_EQ(script[0].angular_radps, 0.5);
  EXPECT_EQ(script[0].duration_s, 12.6);
  EXPECT_EQ(script[1].linear_mps, 0.3);
  const SimOptions options = parse_args({"--world", "w.yaml", "--drive", "0.1,0,1"});
  ASSERT_TRUE(options.drive);
  EXPECT_EQ(options.drive->size(), 1U);
  for (const std::string_view bad : {"", "1,2", "1,2,3,4", "0,0,0", "0,0,-1", "a,0,1", "0,0,1;", "0,0,1;;0,0,1"}) {
    SCOPED_TRACE(std::string(bad));
    try {
      parse_args({"--world", "w.yaml", "--drive", bad});
      ADD_FAILURE() << "accepted";
    } catch (const ArgsError& error) {
      EXPECT_EQ(std::string(error.what()).rfind("option '--drive' ", 0), 0U) << error.what();
    }
  }
}

TEST(ConfiguredPreset, LaserRangeNeedsALaserAndNoiseReachesEverySensor) {
  SimOptions options = parse_args({"--world", "w.yaml", "--robot", "scout", "--laser-range", "5"});
  try {
    configured_preset(options);
    ADD_FAILURE() << "accepted";
  } catch (const ArgsError& error) {
    EXPECT_EQ(std::string(error.what()), "option '--laser-range' needs a robot with a laser; 'scout' has none");
  }
  options = parse_args({"--world", "w.yaml", "--robot", "activitybot", "--noise", "0"});
  const auto& lidar = std::get<ServoRangePreset>(configured_preset(options).sensors[0]);
  EXPECT_EQ(lidar.noise_sigma_near_m, 0.0);
  EXPECT_EQ(lidar.noise_sigma_far_m, 0.0);
}

TEST(Messages, RobotSpecDescribesEveryPreset) {
  const v1::RobotSpec scout = make_robot_spec(preset_named("scout"));
  ASSERT_EQ(scout.sensors_size(), 1);
  ASSERT_TRUE(scout.sensors(0).has_range_array());
  EXPECT_EQ(scout.sensors(0).range_array().elements_size(), 16);
  EXPECT_NEAR(scout.sensors(0).range_array().elements(4).theta(), kPi / 2.0, 1e-12);
  EXPECT_NEAR(scout.sensors(0).range_array().elements(4).y(), 0.2, 1e-12);
  EXPECT_NEAR(scout.sensors(0).range_array().beam_width_rad(), 25.0 * kDegree, 1e-12);
  EXPECT_EQ(scout.sensors(0).range_array().range_min_m(), 0.15);
  EXPECT_EQ(scout.sensors(0).range_array().range_max_m(), 6.5);
  EXPECT_EQ(scout.sensors(0).range_array().period_s(), 0.2);
  EXPECT_EQ(scout.sensors(0).mount().position().z(), 0.3);
  EXPECT_EQ(scout.kinematics().differential().wheel_separation_m(), 0.34);
  EXPECT_FALSE(scout.has_encoders());

  const v1::RobotSpec bot = make_robot_spec(preset_named("activitybot"), {0.5, -0.25, 1.0});
  ASSERT_TRUE(bot.sensors(0).has_servo_range());
  EXPECT_NEAR(bot.sensors(0).servo_range().servo_min_rad(), -kPi / 2.0, 1e-12);
  EXPECT_NEAR(bot.sensors(0).servo_range().servo_step_rad(), kDegree, 1e-12);
  EXPECT_EQ(bot.sensors(0).servo_range().step_period_s(), 0.02);
  EXPECT_EQ(bot.sensors(0).servo_range().range_max_m(), 40.0);
  ASSERT_TRUE(bot.has_encoders());
  EXPECT_EQ(bot.encoders().ticks_per_revolution(), 64.0);
  EXPECT_NEAR(bot.encoders().wheel_separation_m(), 0.1058, 1e-12);
  EXPECT_EQ(bot.encoders().counter_bits(), 32U);
  EXPECT_EQ(bot.initial_pose().x(), 0.5);
  EXPECT_EQ(bot.initial_pose().y(), -0.25);
  EXPECT_EQ(bot.initial_pose().theta(), 1.0);

  const v1::RobotSpec ugv = make_robot_spec(preset_named("ugv"));
  ASSERT_TRUE(ugv.kinematics().has_skid_steer());
  EXPECT_EQ(ugv.kinematics().skid_steer().powertrain_time_constant_s(), 0.1);
  EXPECT_EQ(ugv.kinematics().skid_steer().track_separation_m(), geometry::ugv_skid_steer_params().track_separation_m);
  EXPECT_EQ(ugv.kinematics().skid_steer().max_track_speed_mps(), 1.0);
  ASSERT_TRUE(ugv.sensors(0).has_laser());
  EXPECT_EQ(ugv.sensors(0).laser().beam_count(), 682U);
  EXPECT_EQ(ugv.sensors(0).laser().range_max_m(), 4.0);
  EXPECT_FALSE(ugv.has_encoders());
}

TEST(Messages, SensorMessagesCarryTheirFields) {
  const v1::ClientMessage array = make_range_array_message("sonar_ring", 7, 1.5, {1.0F, 2.0F});
  ASSERT_TRUE(array.has_range_array());
  EXPECT_EQ(array.range_array().sensor(), "sonar_ring");
  EXPECT_EQ(array.range_array().seq(), 7U);
  EXPECT_EQ(array.range_array().stamp_s(), 1.5);
  EXPECT_EQ(array.range_array().ranges_size(), 2);
  const v1::ClientMessage servo = make_servo_range_message("lidar_lite", 8, 1.52, -0.5, 3.25F);
  ASSERT_TRUE(servo.has_servo_range());
  EXPECT_EQ(servo.servo_range().sensor(), "lidar_lite");
  EXPECT_EQ(servo.servo_range().seq(), 8U);
  EXPECT_EQ(servo.servo_range().servo_angle_rad(), -0.5);
  EXPECT_EQ(servo.servo_range().range_m(), 3.25F);
  const v1::ClientMessage ticks = make_wheel_encoders_message(3, 0.04, {.left = 12, .right = -4});
  ASSERT_TRUE(ticks.has_wheel_encoders());
  EXPECT_EQ(ticks.wheel_encoders().seq(), 3U);
  EXPECT_EQ(ticks.wheel_encoders().left_ticks(), 12);
  EXPECT_EQ(ticks.wheel_encoders().right_ticks(), -4);
}

// Seed 003 §3.4: the ActivityBot takes its commands in encoder ticks. drive_goto turns each wheel by its ticks once
// per manoeuvre id (its repeats while it runs change nothing); drive_speed runs the wheels at ticks per second.
TEST(ActivityBotUnits, DriveGotoOncePerIdAndDriveSpeedInTicksPerSecond) {
  const RobotPreset& activitybot = preset_named("activitybot");
  const v1::RobotSpec spec = make_robot_spec(activitybot, {});
  EXPECT_EQ(spec.command_units(), v1::COMMAND_UNITS_ACTIVITYBOT_TICKS);
  EXPECT_EQ(spec.default_behaviour(), v1::BEHAVIOUR_STOP)
      << "server-steered: stands until a controller gives it a goal";
  Simulation simulation(load_world(kWorlds / "room.yaml"), activitybot, {}, 1);
  v1::MotionCommand go;
  go.set_expires_after_s(0.5);
  go.mutable_drive_goto()->set_left_ticks(100);
  go.mutable_drive_goto()->set_right_ticks(100);
  go.mutable_drive_goto()->set_id(1);
  go.mutable_drive_goto()->set_max_ticks_per_s(64);
  simulation.apply_command(go);
  for (int step = 0; step < 100; ++step) {
    simulation.step();
    if (step % 10 == 0) simulation.apply_command(go);  // the same manoeuvre repeated while it runs
  }
  // 100 ticks at 64 ticks/s take 1.56 s: still going after 1 s, however long the watchdog.
  EXPECT_TRUE(simulation.robot().drive_goto_active());
  for (int step = 0; step < 100; ++step) simulation.step();
  EXPECT_FALSE(simulation.robot().drive_goto_active());
  EXPECT_EQ(simulation.robot().encoder_ticks().left, 100);
  EXPECT_EQ(simulation.robot().encoder_ticks().right, 100);
  EXPECT_NEAR(simulation.robot().pose().x, 100 * 3.25e-3, 1e-3);

  v1::MotionCommand turn;
  turn.set_expires_after_s(0.5);
  turn.mutable_drive_speed()->set_left_ticks_per_s(-32);
  turn.mutable_drive_speed()->set_right_ticks_per_s(32);
  simulation.apply_command(turn);
  for (int step = 0; step < 25; ++step) simulation.step();  // 0.25 s: 8 ticks each way
  EXPECT_EQ(simulation.robot().encoder_ticks().left, 92);
  EXPECT_EQ(simulation.robot().encoder_ticks().right, 108);
  for (int step = 0; step < 100; ++step) simulation.step();  // the command expired after 0.5 s
  EXPECT_EQ(simulation.robot().encoder_ticks().right, 116);
}

}  // namespace
}  // namespace occgeo::sim
