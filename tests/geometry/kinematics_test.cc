#include "occgeo/geometry/kinematics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace occgeo::geometry {
namespace {

// Closed-form results evaluated in double precision: a few ulps of error at most.
constexpr double kTolerance = 1e-12;

const DifferentialDriveParams kParams{0.5, 0.1, 1.0};

void expect_pose_near(const Pose2& actual, const Pose2& expected) {
  EXPECT_NEAR(actual.x, expected.x, kTolerance);
  EXPECT_NEAR(actual.y, expected.y, kTolerance);
  EXPECT_NEAR(wrap_angle(actual.theta - expected.theta), 0.0, kTolerance);
}

TEST(DifferentialDrive, EqualWheelSpeedsDriveStraight) {
  const BodyVelocity body = to_body({0.4, 0.4}, kParams);
  EXPECT_DOUBLE_EQ(body.linear_mps, 0.4);
  EXPECT_DOUBLE_EQ(body.angular_radps, 0.0);
}

TEST(DifferentialDrive, OppositeWheelSpeedsTurnOnTheSpot) {
  // Right wheel forward at 0.25 m/s on a 0.5 m track: 0.5 m/s difference over 0.5 m is 1 rad/s counter-clockwise.
  const BodyVelocity body = to_body({-0.25, 0.25}, kParams);
  EXPECT_DOUBLE_EQ(body.linear_mps, 0.0);
  EXPECT_DOUBLE_EQ(body.angular_radps, 1.0);
}

TEST(DifferentialDrive, WheelsAndBodyConvertBothWays) {
  const BodyVelocity body{0.3, -0.8};
  const WheelSpeeds wheels = to_wheels(body, kParams);
  EXPECT_DOUBLE_EQ(wheels.left_mps, 0.3 + 0.8 * 0.25);
  EXPECT_DOUBLE_EQ(wheels.right_mps, 0.3 - 0.8 * 0.25);
  const BodyVelocity back = to_body(wheels, kParams);
  EXPECT_NEAR(back.linear_mps, body.linear_mps, kTolerance);
  EXPECT_NEAR(back.angular_radps, body.angular_radps, kTolerance);
}

TEST(DifferentialDrive, ClampingKeepsTheTurnRatio) {
  const WheelSpeeds clamped = clamp_to_max_speed({-1.0, 3.0}, kParams);
  EXPECT_DOUBLE_EQ(clamped.right_mps, 1.0);
  EXPECT_DOUBLE_EQ(clamped.left_mps, -1.0 / 3.0);
  // Same curvature (yaw rate per unit forward speed) before and after.
  const BodyVelocity before = to_body({-1.0, 3.0}, kParams);
  const BodyVelocity after = to_body(clamped, kParams);
  EXPECT_NEAR(after.angular_radps / after.linear_mps, before.angular_radps / before.linear_mps, kTolerance);

  const WheelSpeeds within{0.5, -0.9};
  const WheelSpeeds unchanged = clamp_to_max_speed(within, kParams);
  EXPECT_EQ(unchanged.left_mps, within.left_mps);
  EXPECT_EQ(unchanged.right_mps, within.right_mps);
}

TEST(DifferentialDrive, ValidateNamesTheBadField) {
  EXPECT_NO_THROW(validate(kParams));
  try {
    validate({0.5, 0.0, 1.0});
    FAIL() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_EQ(std::string(error.what()),
              "DifferentialDriveParams.wheel_radius_m must be positive and finite, got 0.000000");
  }
  EXPECT_THROW(validate(DifferentialDriveParams{}), std::invalid_argument);
}

TEST(Integrate, StraightLineAlongTheHeading) {
  const Pose2 start{1.0, 2.0, M_PI / 6};
  expect_pose_near(integrate(start, {2.0, 0.0}, 1.5),
                   {1.0 + 3.0 * std::cos(M_PI / 6), 2.0 + 3.0 * std::sin(M_PI / 6), M_PI / 6});
}

TEST(Integrate, PureRotationStaysInPlaceAndWraps) {
  expect_pose_near(integrate({1.0, -1.0, 3.0}, {0.0, 1.0}, 0.5), {1.0, -1.0, 3.5 - 2 * M_PI});
  EXPECT_LT(integrate({1.0, -1.0, 3.0}, {0.0, 1.0}, 0.5).theta, M_PI);
}

TEST(Integrate, QuarterCircleEndsExactlyOnTheArc) {
  // 1 m/s at pi/2 rad/s for 1 s: a quarter circle of radius 2/pi to the left, ending at (r, r) facing +y.
  const double r = 2.0 / M_PI;
  expect_pose_near(integrate({0.0, 0.0, 0.0}, {1.0, M_PI / 2}, 1.0), {r, r, M_PI / 2});
  // The same arc clockwise from a rotated, offset start.
  expect_pose_near(integrate({1.0, 1.0, M_PI / 2}, {1.0, -M_PI / 2}, 1.0), {1.0 + r, 1.0 + r, 0.0});
}

TEST(Integrate, ManySmallStepsMatchOneBigStep) {
  const BodyVelocity v{0.7, -0.9};
  Pose2 stepped{0.3, -0.2, 2.0};
  for (int i = 0; i < 1000; ++i) stepped = integrate(stepped, v, 0.003);
  expect_pose_near(stepped, integrate({0.3, -0.2, 2.0}, v, 3.0));
}

TEST(Integrate, TinyYawRatesJoinTheStraightLineSmoothly) {
  // Around the switch to the Taylor series the arc must not jump: compare with the straight line plus the sagitta.
  for (const double angular : {1e-3, 2.0001e-4, 1.9999e-4, 1e-6, 1e-12}) {
    const Pose2 end = integrate({0.0, 0.0, 0.0}, {1.0, angular}, 1.0);
    EXPECT_NEAR(end.x, std::sin(angular) / angular, 1e-15);
    EXPECT_NEAR(end.y, 2.0 * std::pow(std::sin(angular / 2.0), 2) / angular, 1e-15);  // (1 - cos a) / a
  }
}

}  // namespace
}  // namespace occgeo::geometry
