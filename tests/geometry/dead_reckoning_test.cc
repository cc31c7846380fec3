#include "occgeo/geometry/dead_reckoning.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

namespace occgeo::geometry {
namespace {

// Closed-form results evaluated in double precision over at most a few hundred arc steps: well below 1e-12.
constexpr double kTolerance = 1e-12;

// Test robot: a 1 m wheel circumference over 100 ticks is 1 cm per tick; wheels 0.5 m apart.
EncoderParams test_params() {
  EncoderParams params;
  params.ticks_per_revolution = 100.0;
  params.wheel_radius_m = 0.5 / M_PI;
  params.wheel_separation_m = 0.5;
  return params;
}

void expect_pose_near(const Pose2& actual, const Pose2& expected, double tolerance = kTolerance) {
  EXPECT_NEAR(actual.x, expected.x, tolerance);
  EXPECT_NEAR(actual.y, expected.y, tolerance);
  EXPECT_NEAR(wrap_angle(actual.theta - expected.theta), 0.0, tolerance);
}

std::string validation_message(const EncoderParams& params) {
  try {
    validate(params);
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "no exception";
}

TEST(EncoderParams, RobotsFromTheSources) {
  const EncoderParams bot = activitybot_encoder_params();
  EXPECT_NO_THROW(validate(bot));
  EXPECT_EQ(bot.ticks_per_revolution, 64.0);                        // Seed 003 §3.2.3.
  EXPECT_NEAR(metres_per_tick(bot), 3.25e-3, 1e-15);                // Seed 003 §3.2.3: 3.25 mm per tick.
  EXPECT_EQ(bot.wheel_separation_m, 0.1058);                        // Seed 003 §3.4.2: R = 105.8 mm.
  EXPECT_NEAR(2.0 * M_PI * bot.wheel_separation_m, 0.66476, 5e-6);  // ... whose 2 pi R is the thesis's 664.76 mm.
  EXPECT_EQ(bot.counter_bits, 32);

  const EncoderParams rover = minesrover_encoder_params();
  EXPECT_NO_THROW(validate(rover));
  EXPECT_EQ(rover.ticks_per_revolution, 2000.0);
  EXPECT_EQ(rover.wheel_radius_m, 0.077);
  EXPECT_EQ(rover.wheel_separation_m, 0.33);
  EXPECT_NEAR(metres_per_tick(rover), 2.0 * M_PI * 0.077 / 2000.0, 1e-18);
}

TEST(EncoderParams, ValidateNamesTheBadField) {
  EXPECT_NO_THROW(validate(test_params()));
  EncoderParams bad = test_params();
  bad.ticks_per_revolution = 0.0;
  EXPECT_EQ(validation_message(bad), "EncoderParams.ticks_per_revolution must be positive and finite, got 0.000000");
  bad = test_params();
  bad.wheel_radius_m = -0.1;
  EXPECT_EQ(validation_message(bad), "EncoderParams.wheel_radius_m must be positive and finite, got -0.100000");
  bad = test_params();
  bad.wheel_separation_m = std::numeric_limits<double>::infinity();
  EXPECT_EQ(validation_message(bad), "EncoderParams.wheel_separation_m must be positive and finite, got inf");
  bad = test_params();
  bad.counter_bits = 65;
  EXPECT_EQ(validation_message(bad), "EncoderParams.counter_bits must be in [1, 64], got 65");
  bad.counter_bits = 0;
  EXPECT_EQ(validation_message(bad), "EncoderParams.counter_bits must be in [1, 64], got 0");
  EXPECT_THROW(EncoderOdometry{bad}, std::invalid_argument);
}

TEST(EncoderOdometry, FirstReadingOnlySetsTheReference) {
  EncoderOdometry odometry(test_params(), {1.0, 2.0, 0.5});
  EXPECT_FALSE(odometry.has_reference());
  expect_pose_near(odometry.update({123456, -789, 10.0}), {1.0, 2.0, 0.5});
  EXPECT_TRUE(odometry.has_reference());
  EXPECT_EQ(odometry.velocity().linear_mps, 0.0);
  EXPECT_EQ(odometry.velocity().angular_radps, 0.0);
  // The next reading moves by the increment only: 100 ticks = 1 m along heading 0.5 rad.
  expect_pose_near(odometry.update({123556, -689, 11.0}), {1.0 + std::cos(0.5), 2.0 + std::sin(0.5), 0.5});
}

TEST(EncoderOdometry, StraightLine) {
  EncoderOdometry odometry(test_params());
  odometry.update({0, 0, 0.0});
  odometry.update({250, 250, 2.0});
  expect_pose_near(odometry.pose(), {2.5, 0.0, 0.0});
  EXPECT_NEAR(odometry.velocity().linear_mps, 1.25, kTolerance);
  EXPECT_NEAR(odometry.velocity().angular_radps, 0.0, kTolerance);
  odometry.update({150, 150, 3.0});  // One metre backwards.
  expect_pose_near(odometry.pose(), {1.5, 0.0, 0.0});
  EXPECT_NEAR(odometry.velocity().linear_mps, -1.0, kTolerance);
}

TEST(EncoderOdometry, InPlaceRotation) {
  // Wheels 25 ticks = 0.25 m in opposite directions on a 0.5 m axle: 0.5 / 0.5 = 1 rad counter-clockwise per step.
  EncoderOdometry odometry(test_params(), {3.0, -2.0, 0.0});
  odometry.update({0, 0, 0.0});
  odometry.update({-25, 25, 0.5});
  expect_pose_near(odometry.pose(), {3.0, -2.0, 1.0});
  EXPECT_NEAR(odometry.velocity().linear_mps, 0.0, kTolerance);
  EXPECT_NEAR(odometry.velocity().angular_radps, 2.0, kTolerance);
  for (int i = 2; i <= 4; ++i) odometry.update({-25 * i, 25 * i, 0.5 * i});
  expect_pose_near(odometry.pose(), {3.0, -2.0, 4.0 - 2.0 * M_PI});
}

TEST(EncoderOdometry, ConstantCurvatureArcIsTheClosedForm) {
  // Left 150 ticks (1.5 m), right 250 ticks (2.5 m) on 0.5 m: phi = 1 m / 0.5 m = 2 rad over a 2 m arc, R = 1 m.
  const Pose2 expected{std::sin(2.0), 1.0 - std::cos(2.0), 2.0};
  EncoderOdometry even(test_params());
  for (int i = 0; i <= 10; ++i) even.update({15 * i, 25 * i, 0.1 * i});
  expect_pose_near(even.pose(), expected);
  EXPECT_NEAR(even.velocity().linear_mps, 2.0, kTolerance);  // 0.2 m per 0.1 s.
  EXPECT_NEAR(even.velocity().angular_radps, 2.0, kTolerance);

  // Uneven increments in the same 3:5 ratio end at the same place: each increment is an exact arc.
  EncoderOdometry uneven(test_params());
  double t = 0.0;
  for (const auto& [left, right] : {std::pair{0, 0}, {3, 5}, {15, 25}, {18, 30}, {90, 150}, {150, 250}}) {
    uneven.update({left, right, t += 0.3});
  }
  expect_pose_near(uneven.pose(), expected);

  // From a rotated, offset start the same arc is composed onto the start pose.
  const Pose2 start{-1.0, 4.0, -2.5};
  EncoderOdometry moved(test_params(), start);
  moved.update({0, 0, 0.0});
  moved.update({150, 250, 1.0});
  expect_pose_near(moved.pose(), start.compose(expected));
}

TEST(EncoderOdometry, TickDeltaUndoesOneWrap) {
  constexpr std::int64_t k2To31 = std::int64_t{1} << 31;
  constexpr std::int64_t k2To32 = std::int64_t{1} << 32;
  EXPECT_EQ(EncoderOdometry::tick_delta(k2To32 - 10, 6, 32), 16);           // Unsigned counter wrapping forwards.
  EXPECT_EQ(EncoderOdometry::tick_delta(6, k2To32 - 10, 32), -16);          // ... and backwards.
  EXPECT_EQ(EncoderOdometry::tick_delta(k2To31 - 8, -k2To31 + 8, 32), 16);  // Signed int32 counter wrapping.
  EXPECT_EQ(EncoderOdometry::tick_delta(0, k2To31 - 1, 32), k2To31 - 1);    // Just under half the range: no wrap.
  EXPECT_EQ(EncoderOdometry::tick_delta(0, k2To31, 32), -k2To31);           // Exactly half: read as backwards.
  EXPECT_EQ(EncoderOdometry::tick_delta(65530, 4, 16), 10);
  EXPECT_EQ(EncoderOdometry::tick_delta(0, 1, 1), -1);
  EXPECT_EQ(EncoderOdometry::tick_delta(std::numeric_limits<std::int64_t>::max(),
                                        std::numeric_limits<std::int64_t>::min(), 64),
            1);
  EXPECT_EQ(EncoderOdometry::tick_delta(-5, 7, 64), 12);
}

TEST(EncoderOdometry, CounterWrapAroundKeepsThePoseContinuous) {
  constexpr std::int64_t k2To32 = std::int64_t{1} << 32;
  EncoderOdometry odometry(test_params());
  // Left counts unsigned 0 .. 2^32 - 1, right counts as a signed int32: both move 16 ticks through their wrap.
  odometry.update({k2To32 - 10, (std::int64_t{1} << 31) - 8, 0.0});
  odometry.update({6, -(std::int64_t{1} << 31) + 8, 1.0});
  expect_pose_near(odometry.pose(), {0.16, 0.0, 0.0});
  EXPECT_NEAR(odometry.velocity().linear_mps, 0.16, kTolerance);
  // And back through the wrap.
  odometry.update({k2To32 - 4, (std::int64_t{1} << 31) - 2, 2.0});
  expect_pose_near(odometry.pose(), {0.06, 0.0, 0.0});
}

TEST(EncoderOdometry, RepeatedAndBackwardTimestampsKeepTheVelocity) {
  EncoderOdometry odometry(test_params());
  odometry.update({0, 0, 5.0});
  odometry.update({100, 100, 6.0});
  EXPECT_NEAR(odometry.velocity().linear_mps, 1.0, kTolerance);
  // Same timestamp: the pose still moves by the ticks, the velocity is left alone (no division by zero).
  odometry.update({150, 150, 6.0});
  expect_pose_near(odometry.pose(), {1.5, 0.0, 0.0});
  EXPECT_NEAR(odometry.velocity().linear_mps, 1.0, kTolerance);
  // Time advances again: the 1 m travelled since the last velocity update at t = 6 s took 0.5 s.
  odometry.update({200, 200, 6.5});
  EXPECT_NEAR(odometry.velocity().linear_mps, 2.0, kTolerance);
  // A clock going backwards moves the pose, keeps the velocity and restarts the interval from that reading.
  odometry.update({250, 250, 6.2});
  expect_pose_near(odometry.pose(), {2.5, 0.0, 0.0});
  EXPECT_NEAR(odometry.velocity().linear_mps, 2.0, kTolerance);
  odometry.update({300, 300, 6.7});
  EXPECT_NEAR(odometry.velocity().linear_mps, 1.0, kTolerance);
  EXPECT_TRUE(std::isfinite(odometry.velocity().angular_radps));

  try {
    odometry.update({400, 400, std::nan("")});
    FAIL() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()), "EncoderReading.time_s must be finite, got nan");
  }
  expect_pose_near(odometry.pose(), {3.0, 0.0, 0.0});  // The rejected reading changed nothing.
}

TEST(EncoderOdometry, ResetForgetsTheReference) {
  EncoderOdometry odometry(test_params());
  odometry.update({0, 0, 0.0});
  odometry.update({100, 100, 1.0});
  odometry.reset({5.0, 5.0, M_PI / 2});
  EXPECT_FALSE(odometry.has_reference());
  EXPECT_EQ(odometry.velocity().linear_mps, 0.0);
  odometry.update({9000, 9000, 2.0});  // New reference only.
  odometry.update({9100, 9100, 3.0});
  expect_pose_near(odometry.pose(), {5.0, 6.0, M_PI / 2});
}

// Drives the ActivityBot's encoders through one drive_goto command and returns where dead reckoning puts it.
Pose2 dead_reckon_drive_goto(const std::pair<std::int64_t, std::int64_t>& command) {
  EncoderOdometry odometry(activitybot_encoder_params());
  odometry.update({1000, -1000, 0.0});  // Arbitrary counter values before the command.
  return odometry.update({1000 + command.first, -1000 + command.second, 1.0});
}

TEST(ActivityBotDriveGoto, StraightDistanceIsTicksTimes3Point25Millimetres) {
  // Seed 003 §3.4: 100 ticks = 325 mm exactly.
  EXPECT_EQ(drive_goto_ticks_for_distance(0.325), (std::pair<std::int64_t, std::int64_t>{100, 100}));
  expect_pose_near(dead_reckon_drive_goto(drive_goto_ticks_for_distance(0.325)), {0.325, 0.0, 0.0});
  // 1 m = 307.69 ticks, rounded to 308: the robot stops within half a tick (1.625 mm) of the goal.
  EXPECT_EQ(drive_goto_ticks_for_distance(1.0), (std::pair<std::int64_t, std::int64_t>{308, 308}));
  const Pose2 metre = dead_reckon_drive_goto(drive_goto_ticks_for_distance(1.0));
  EXPECT_NEAR(metre.x, 1.0, 1.625e-3);
  EXPECT_NEAR(metre.x, 308 * 3.25e-3, kTolerance);
  EXPECT_NEAR(metre.y, 0.0, kTolerance);
  // Backwards (§3.4.1: both counts negative).
  EXPECT_EQ(drive_goto_ticks_for_distance(-0.1), (std::pair<std::int64_t, std::int64_t>{-31, -31}));
  expect_pose_near(dead_reckon_drive_goto(drive_goto_ticks_for_distance(-0.1)), {-31 * 3.25e-3, 0.0, 0.0});
}

TEST(ActivityBotDriveGoto, InPlaceTurnFollowsTheThesisFormula) {
  // Seed 003 §3.4.2: a full turn is t = 664.76 / 3.25 = 204.5 ticks, drive_goto(-t/2, t/2) = (-102, 102) rounded.
  EXPECT_EQ(drive_goto_ticks_for_turn(2.0 * M_PI), (std::pair<std::int64_t, std::int64_t>{-102, 102}));
  EXPECT_EQ(drive_goto_ticks_for_turn(M_PI / 2), (std::pair<std::int64_t, std::int64_t>{-26, 26}));  // 25.57.
  EXPECT_EQ(drive_goto_ticks_for_turn(-M_PI / 2), (std::pair<std::int64_t, std::int64_t>{26, -26}));
  // Rounding each wheel to half a tick bounds the heading error by 2 * 0.5 * 3.25 mm / 105.8 mm = 0.0307 rad.
  const double bound = 3.25e-3 / 0.1058;
  for (const double angle : {M_PI / 2, -M_PI / 2, M_PI / 6, 1.0}) {
    const auto command = drive_goto_ticks_for_turn(angle);
    const Pose2 end = dead_reckon_drive_goto(command);
    EXPECT_NEAR(end.x, 0.0, kTolerance);
    EXPECT_NEAR(end.y, 0.0, kTolerance);
    EXPECT_NEAR(end.theta, 2.0 * static_cast<double>(command.second) * 3.25e-3 / 0.1058, kTolerance);
    EXPECT_LE(std::abs(end.theta - angle), bound) << angle;
  }
}

TEST(ActivityBotDriveGoto, PivotTurnRollsAboutTheHeldWheel) {
  // Seed 003 §3.4.2, fig. 3.13: a quarter turn is 664.76 * 0.25 / 3.25 = 51.1 ticks on one wheel.
  EXPECT_EQ(drive_goto_ticks_for_pivot_turn(M_PI / 2), (std::pair<std::int64_t, std::int64_t>{0, 51}));
  EXPECT_EQ(drive_goto_ticks_for_pivot_turn(-M_PI / 2), (std::pair<std::int64_t, std::int64_t>{51, 0}));
  // Counter-clockwise about the held left wheel at (0, S/2): base_link moves on a circle of radius S/2.
  const double half_axle = 0.1058 / 2.0;
  const double phi = 51 * 3.25e-3 / 0.1058;
  EXPECT_LE(std::abs(phi - M_PI / 2), 0.5 * 3.25e-3 / 0.1058);  // Half a tick of one wheel.
  expect_pose_near(dead_reckon_drive_goto(drive_goto_ticks_for_pivot_turn(M_PI / 2)),
                   {half_axle * std::sin(phi), half_axle * (1.0 - std::cos(phi)), phi});
  // Clockwise about the held right wheel at (0, -S/2).
  expect_pose_near(dead_reckon_drive_goto(drive_goto_ticks_for_pivot_turn(-M_PI / 2)),
                   {half_axle * std::sin(phi), -half_axle * (1.0 - std::cos(phi)), -phi});
}

TEST(ActivityBotDriveGoto, RejectsInputsDriveGotoCannotTake) {
  try {
    drive_goto_ticks_for_distance(std::nan(""));
    FAIL() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()), "distance must be finite, got nan");
  }
  EXPECT_THROW(drive_goto_ticks_for_distance(1e7), std::invalid_argument);  // 3e9 ticks exceed a 32-bit int.
  EXPECT_THROW(drive_goto_ticks_for_turn(std::numeric_limits<double>::infinity()), std::invalid_argument);
  EXPECT_THROW(drive_goto_ticks_for_pivot_turn(-1e9), std::invalid_argument);
}

}  // namespace
}  // namespace occgeo::geometry
