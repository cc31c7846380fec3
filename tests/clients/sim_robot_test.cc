#include <gtest/gtest.h>

#include "occgeo/sim/presets.h"
#include "occgeo/sim/robot.h"

namespace occgeo::sim {
namespace {

// Positions come from a few hundred exact-arc steps; 1e-9 m is far above their accumulated rounding.
constexpr double kTolerance_m = 1e-9;

const RobotPreset& bearcat() { return *find_robot_preset("bearcat"); }

// One free pixel: the whole plane is open ground.
World open_ground() { return World::from_rows({"."}, 1.0, {100.0, 100.0}); }

WheelCommand forward(double speed_mps) { return WheelCommand{.left_mps = speed_mps, .right_mps = speed_mps}; }

void step_times(SimulatedRobot& robot, int steps) {
  for (int i = 0; i < steps; ++i) robot.step();
}

TEST(SimulatedRobot, DrivesStraightAtTheCommandedSpeed) {
  const World world = open_ground();
  SimulatedRobot robot(world, bearcat(), {1.0, 2.0, 0.0});
  robot.command(forward(1.0));
  step_times(robot, 30);
  EXPECT_NEAR(robot.pose().x, 1.3, kTolerance_m);
  EXPECT_NEAR(robot.pose().y, 2.0, kTolerance_m);
  EXPECT_NEAR(robot.distance_m(), 0.3, kTolerance_m);
  EXPECT_EQ(robot.velocity().linear_mps, 1.0);
  EXPECT_NEAR(robot.time_s(), 0.3, 1e-15);
}

TEST(SimulatedRobot, WatchdogStopsTheWheelsHalfASecondAfterTheLastCommand) {
  const World world = open_ground();
  SimulatedRobot robot(world, bearcat(), {});
  robot.command(forward(1.0));
  step_times(robot, 49);
  EXPECT_EQ(robot.wheel_speeds().left_mps, 1.0) << "still within 0.5 s";
  robot.step();  // the 50th step ends 0.5 s after the command
  EXPECT_EQ(robot.wheel_speeds().left_mps, 0.0);
  EXPECT_EQ(robot.wheel_speeds().right_mps, 0.0);
  step_times(robot, 100);
  EXPECT_NEAR(robot.pose().x, 0.5, kTolerance_m) << "moved for exactly 0.5 s";
  EXPECT_EQ(robot.velocity().linear_mps, 0.0);
}

TEST(SimulatedRobot, ANewCommandRestartsTheWatchdog) {
  const World world = open_ground();
  SimulatedRobot robot(world, bearcat(), {});
  for (int i = 0; i < 10; ++i) {
    robot.command(forward(1.0));
    step_times(robot, 40);
  }
  EXPECT_NEAR(robot.pose().x, 4.0, kTolerance_m);
}

TEST(SimulatedRobot, StopAndExpiryEndACommandEarly) {
  const World world = open_ground();
  SimulatedRobot robot(world, bearcat(), {});
  robot.command(forward(1.0));
  step_times(robot, 10);
  robot.command(WheelCommand{.left_mps = 1.0, .right_mps = 1.0, .stop = true});
  step_times(robot, 10);
  EXPECT_NEAR(robot.pose().x, 0.1, kTolerance_m);

  robot.command(WheelCommand{.left_mps = 1.0, .right_mps = 1.0, .expires_after_s = 0.2});
  step_times(robot, 100);
  EXPECT_NEAR(robot.pose().x, 0.3, kTolerance_m);

  robot.command(forward(NAN));
  step_times(robot, 10);
  EXPECT_NEAR(robot.pose().x, 0.3, kTolerance_m) << "a non-finite command stops the robot";
}

TEST(SimulatedRobot, ScalesWheelSpeedsDownToTheMaximumKeepingTheCurvature) {
  const World world = open_ground();
  SimulatedRobot robot(world, bearcat(), {});
  robot.command(WheelCommand{.left_mps = 2.0, .right_mps = 4.0});
  EXPECT_DOUBLE_EQ(robot.wheel_speeds().left_mps, 0.6);
  EXPECT_DOUBLE_EQ(robot.wheel_speeds().right_mps, 1.2);
}

TEST(SimulatedRobot, TurnsOnTheExactArc) {
  const World world = open_ground();
  SimulatedRobot robot(world, bearcat(), {});
  // Wheels at -0.35 and +0.35 m/s on a 0.7 m axle turn in place at 1 rad/s.
  robot.command(WheelCommand{.left_mps = -0.35, .right_mps = 0.35});
  step_times(robot, 50);
  EXPECT_NEAR(robot.pose().theta, 0.5, 1e-12);
  EXPECT_NEAR(robot.pose().position().norm(), 0.0, 1e-12);
}

TEST(SimulatedRobot, IsBlockedByAnObstacleAndCountsOneCollision) {
  // 0.1 m pixels from (0, -1): a wall at x 2.0..2.1 across the whole height.
  std::vector<std::string> rows(20, std::string(30, '.'));
  for (std::string& row : rows) row[20] = '#';
  const World world = World::from_rows(std::vector<std::string_view>(rows.begin(), rows.end()), 0.1, {0.0, -1.0});
  SimulatedRobot robot(world, bearcat(), {0.5, 0.0, 0.0});
  for (int i = 0; i < 60; ++i) {  // 6 s at 1 m/s would carry the robot 6 m
    robot.command(forward(1.0));
    step_times(robot, 10);
  }
  // The front face (x + 0.5) stops within one 1 cm step of the wall at x = 2.0.
  EXPECT_LE(robot.pose().x + 0.5, 2.0);
  EXPECT_GT(robot.pose().x + 0.5, 1.99);
  EXPECT_EQ(robot.collisions(), 1U) << "one contact, however many blocked steps";
  EXPECT_EQ(robot.velocity().linear_mps, 0.0);
  EXPECT_NEAR(robot.distance_m(), robot.pose().x - 0.5, kTolerance_m);

  // Backing off and driving in again is a second collision.
  robot.command(forward(-1.0));
  step_times(robot, 20);
  robot.command(forward(1.0));
  step_times(robot, 40);
  EXPECT_EQ(robot.collisions(), 2U);
}

TEST(SimulatedRobot, RefusesAStartPoseInCollision) {
  const World world = World::from_rows({"#"}, 1.0, {0.0, 0.0});
  try {
    SimulatedRobot robot(world, bearcat(), {0.5, 0.5, 0.0});
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("collides with the obstacle pixel (col 0, row 0)"), std::string::npos)
        << error.what();
  }
}

TEST(RobotPresets, BearcatMatchesTheSeed) {
  const RobotPreset& preset = bearcat();
  EXPECT_NO_THROW(geometry::validate(std::get<geometry::DifferentialDriveParams>(preset.kinematics)));
  EXPECT_EQ(std::get<geometry::DifferentialDriveParams>(preset.kinematics).wheel_separation_m, 0.7);
  EXPECT_EQ(std::get<geometry::DifferentialDriveParams>(preset.kinematics).wheel_radius_m, 0.2);
  EXPECT_EQ(std::get<geometry::DifferentialDriveParams>(preset.kinematics).max_wheel_speed_mps, 1.2);
  EXPECT_EQ(preset.footprint.length, 1.0);
  EXPECT_EQ(preset.footprint.width, 0.8);
  EXPECT_EQ(preset.footprint.height, 1.2);
  EXPECT_EQ(preset.laser()->name, "front_laser");
  EXPECT_EQ(preset.laser()->beam_count, 181U);
  EXPECT_NEAR(preset.laser()->angle_min_rad + 180 * preset.laser()->angle_increment_rad, M_PI / 2.0, 1e-12);
  EXPECT_EQ(preset.laser()->range_max_m, 8.0);
  EXPECT_EQ(preset.laser()->X_BS.x, 0.45);
  EXPECT_EQ(preset.laser()->mount_height_m, 0.6);
  EXPECT_EQ(preset.command_timeout_s, 0.5);
  EXPECT_EQ(find_robot_preset("r2d2"), nullptr);
  EXPECT_EQ(robot_preset_names(), "bearcat, scout, activitybot, ugv, bearcat_3d");
}

}  // namespace
}  // namespace occgeo::sim
