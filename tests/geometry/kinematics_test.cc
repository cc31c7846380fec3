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
    validate(DifferentialDriveParams{0.5, 0.0, 1.0});
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

// Seed 004 eq. 3.2–3.4 with unequal sprocket radii and slippage, chosen so the track ground speeds are round numbers.
SkidSteerParams skid_params() {
  SkidSteerParams params;
  params.track_separation_m = 0.8;
  params.left_sprocket_radius_m = 0.1;
  params.right_sprocket_radius_m = 0.12;
  params.left_slip = 0.1;
  params.right_slip = 0.25;
  params.max_track_speed_mps = 2.0;
  return params;
}

// Classic fourth-order Runge-Kutta on the thesis's pose rate, as its Simulink integrator would do.
Pose2 rk4_integrate(Pose2 X_WB, const SprocketRates& rates, const SkidSteerParams& params, double duration_s,
                    int steps) {
  const double h = duration_s / steps;
  const auto f = [&](const Pose2& p) { return pose_rate(p, rates, params); };
  const auto advance = [](const Pose2& p, const PoseRate& r, double dt) {
    return Pose2{p.x + r.x_mps * dt, p.y + r.y_mps * dt, p.theta + r.theta_radps * dt};
  };
  for (int i = 0; i < steps; ++i) {
    const PoseRate k1 = f(X_WB);
    const PoseRate k2 = f(advance(X_WB, k1, h / 2));
    const PoseRate k3 = f(advance(X_WB, k2, h / 2));
    const PoseRate k4 = f(advance(X_WB, k3, h));
    X_WB.x += h / 6 * (k1.x_mps + 2 * k2.x_mps + 2 * k3.x_mps + k4.x_mps);
    X_WB.y += h / 6 * (k1.y_mps + 2 * k2.y_mps + 2 * k3.y_mps + k4.y_mps);
    X_WB.theta += h / 6 * (k1.theta_radps + 2 * k2.theta_radps + 2 * k3.theta_radps + k4.theta_radps);
  }
  return X_WB;
}

TEST(SkidSteer, PoseRateIsTheThesisEquations) {
  // Left ground speed (1 - 0.1) * 0.1 m * 10 rad/s = 0.9 m/s; right (1 - 0.25) * 0.12 m * 5 rad/s = 0.45 m/s.
  const PoseRate rate = pose_rate({3.0, -1.0, M_PI / 3}, {10.0, 5.0}, skid_params());
  EXPECT_NEAR(rate.x_mps, (0.45 + 0.9) * std::cos(M_PI / 3) / 2, kTolerance);  // Eq. 3.2.
  EXPECT_NEAR(rate.y_mps, (0.45 + 0.9) * std::sin(M_PI / 3) / 2, kTolerance);  // Eq. 3.3.
  EXPECT_NEAR(rate.theta_radps, (0.45 - 0.9) / 0.8, kTolerance);               // Eq. 3.4.

  const BodyVelocity body = to_body(SprocketRates{10.0, 5.0}, skid_params());
  EXPECT_NEAR(body.linear_mps, 0.675, kTolerance);
  EXPECT_NEAR(body.angular_radps, -0.5625, kTolerance);
}

TEST(SkidSteer, WithoutSlipItIsADifferentialDrive) {
  SkidSteerParams params = skid_params();
  params.left_slip = params.right_slip = 0.0;
  params.right_sprocket_radius_m = params.left_sprocket_radius_m;
  const DifferentialDriveParams diff{params.track_separation_m, params.left_sprocket_radius_m, 2.0};
  const BodyVelocity skid = to_body(SprocketRates{4.0, 7.0}, params);
  const BodyVelocity expected = to_body(WheelSpeeds{0.4, 0.7}, diff);
  EXPECT_NEAR(skid.linear_mps, expected.linear_mps, kTolerance);
  EXPECT_NEAR(skid.angular_radps, expected.angular_radps, kTolerance);
}

TEST(SkidSteer, ConversionsInvertEachOther) {
  const SkidSteerParams params = skid_params();
  const BodyVelocity body{0.4, -0.7};
  const SprocketRates rates = to_sprocket_rates(body, params);
  // Ground speeds 0.4 +- 0.7 * 0.4: left 0.68 m/s, right 0.12 m/s, each divided by (1 - s) r.
  EXPECT_NEAR(rates.left_radps, 0.68 / (0.9 * 0.1), kTolerance);
  EXPECT_NEAR(rates.right_radps, 0.12 / (0.75 * 0.12), kTolerance);
  const BodyVelocity back = to_body(rates, params);
  EXPECT_NEAR(back.linear_mps, body.linear_mps, kTolerance);
  EXPECT_NEAR(back.angular_radps, body.angular_radps, kTolerance);

  const WheelSpeeds rims = to_wheels(body, params);
  EXPECT_NEAR(rims.left_mps, 0.68 / 0.9, kTolerance);
  EXPECT_NEAR(rims.right_mps, 0.12 / 0.75, kTolerance);
  const BodyVelocity from_rims = to_body(rims, params);
  EXPECT_NEAR(from_rims.linear_mps, body.linear_mps, kTolerance);
  EXPECT_NEAR(from_rims.angular_radps, body.angular_radps, kTolerance);
}

TEST(SkidSteer, ArcWithoutSlipIsTheClosedForm) {
  // Tracks at 0.75 and 1.25 m/s on b = 0.5 m: v = 1 m/s, yaw rate 1 rad/s, so a circle of R = 1 m; after 2 s the
  // heading is phi = 2 rad at (R sin phi, R (1 - cos phi)).
  SkidSteerParams params = skid_params();
  params.track_separation_m = 0.5;
  params.left_slip = params.right_slip = 0.0;
  params.left_sprocket_radius_m = params.right_sprocket_radius_m = 0.05;
  const SprocketRates rates{0.75 / 0.05, 1.25 / 0.05};
  const Pose2 expected{std::sin(2.0), 1.0 - std::cos(2.0), 2.0};
  expect_pose_near(integrate({0.0, 0.0, 0.0}, to_body(rates, params), 2.0), expected);
  // RK4 with h = 1 ms has a global error of order h^4 = 1e-12 per unit of time: 1e-9 is ample.
  const Pose2 rk4 = rk4_integrate({0.0, 0.0, 0.0}, rates, params, 2.0, 2000);
  EXPECT_NEAR(rk4.x, expected.x, 1e-9);
  EXPECT_NEAR(rk4.y, expected.y, 1e-9);
  EXPECT_NEAR(rk4.theta, expected.theta, 1e-9);
}

TEST(SkidSteer, SlippageOnOneTrackCurvesAStraightCommand) {
  // Equal sprocket rates of 10 rad/s on r = 0.1 m, 20 % slip on the right only: ground speeds 1.0 and 0.8 m/s, so by
  // eq. 3.2–3.4 v = 0.9 m/s and yaw rate -0.2 / 0.5 = -0.4 rad/s, a clockwise circle of radius R = v / yaw rate.
  SkidSteerParams params = skid_params();
  params.track_separation_m = 0.5;
  params.left_sprocket_radius_m = params.right_sprocket_radius_m = 0.1;
  params.left_slip = 0.0;
  params.right_slip = 0.2;
  const SprocketRates rates{10.0, 10.0};
  const double yaw_rate = -0.4, radius = 0.9 / yaw_rate, phi = yaw_rate * 2.0;
  const Pose2 expected{radius * std::sin(phi), radius * (1.0 - std::cos(phi)), phi};
  expect_pose_near(integrate({0.0, 0.0, 0.0}, to_body(rates, params), 2.0), expected);
  const Pose2 rk4 = rk4_integrate({0.0, 0.0, 0.0}, rates, params, 2.0, 2000);  // Tolerance as above.
  EXPECT_NEAR(rk4.x, expected.x, 1e-9);
  EXPECT_NEAR(rk4.y, expected.y, 1e-9);
  EXPECT_NEAR(rk4.theta, expected.theta, 1e-9);

  // Commanding the rates to_sprocket_rates asks for compensates the slip and drives straight.
  const SprocketRates straight = to_sprocket_rates({0.9, 0.0}, params);
  EXPECT_NEAR(straight.right_radps / straight.left_radps, 1.0 / 0.8, kTolerance);
  expect_pose_near(integrate({0.0, 0.0, 0.0}, to_body(straight, params), 2.0), {1.8, 0.0, 0.0});
}

TEST(SkidSteer, ClampingKeepsTheTurnRatio) {
  const WheelSpeeds clamped = clamp_to_max_speed({-1.0, 4.0}, skid_params());
  EXPECT_DOUBLE_EQ(clamped.right_mps, 2.0);
  EXPECT_DOUBLE_EQ(clamped.left_mps, -0.5);
  const WheelSpeeds unchanged = clamp_to_max_speed({1.5, -2.0}, skid_params());
  EXPECT_EQ(unchanged.left_mps, 1.5);
  EXPECT_EQ(unchanged.right_mps, -2.0);
}

TEST(SkidSteer, ValidateNamesTheBadField) {
  EXPECT_NO_THROW(validate(skid_params()));
  const auto message = [](const SkidSteerParams& params) {
    try {
      validate(params);
    } catch (const std::invalid_argument& error) {
      return std::string(error.what());
    }
    return std::string("no exception");
  };
  SkidSteerParams bad = skid_params();
  bad.track_separation_m = -1.0;
  EXPECT_EQ(message(bad), "SkidSteerParams.track_separation_m must be positive and finite, got -1.000000");
  bad = skid_params();
  bad.right_sprocket_radius_m = 0.0;
  EXPECT_EQ(message(bad), "SkidSteerParams.right_sprocket_radius_m must be positive and finite, got 0.000000");
  bad = skid_params();
  bad.right_slip = 1.0;
  EXPECT_EQ(message(bad), "SkidSteerParams.right_slip must be in [0, 1), got 1.000000");
  bad = skid_params();
  bad.left_slip = -0.1;
  EXPECT_EQ(message(bad), "SkidSteerParams.left_slip must be in [0, 1), got -0.100000");
  bad = skid_params();
  bad.max_track_speed_mps = std::nan("");
  EXPECT_EQ(message(bad), "SkidSteerParams.max_track_speed_mps must be positive and finite, got nan");
  EXPECT_THROW(validate(SkidSteerParams{}), std::invalid_argument);
}

TEST(SkidSteer, UgvParamsUseTheThesisFootprint) {
  const SkidSteerParams ugv = ugv_skid_steer_params();
  EXPECT_NO_THROW(validate(ugv));
  // Seed 004 §3.1: 27 in x 15 in; b is the diagonal, sqrt(954) in = 30.8869 in.
  EXPECT_NEAR(ugv.track_separation_m, std::sqrt(954.0) * 0.0254, kTolerance);
  EXPECT_NEAR(ugv.track_separation_m, 0.784527, 1e-6);
  EXPECT_EQ(ugv.left_slip, 0.0);
  EXPECT_EQ(ugv.right_slip, 0.0);
}

// The planar shortcut every octree footprint query takes must be the general 6-DoF pose with zero roll and pitch.
TEST(Pose3, FromPose2EqualsTheGeneralFormWithoutRollAndPitch) {
  for (const double theta : {-3.1, -1.5707963267948966, -0.3, 0.0, 0.7, 2.0, 3.14159}) {
    const Pose2 planar{1.25, -0.5, theta};
    const Pose3 fast = Pose3::from_pose2(planar);
    const Pose3 general = Pose3::from_xyz_rpy(1.25, -0.5, 0.0, 0.0, 0.0, theta);
    EXPECT_TRUE(fast.transform.matrix().isApprox(general.transform.matrix(), 1e-15)) << "theta " << theta;
    const Eigen::Vector3d p_B(0.4, -0.2, 0.3);
    const Eigen::Vector2d in_plane = planar.transform({p_B.x(), p_B.y()});
    EXPECT_NEAR((fast.transform * p_B).x(), in_plane.x(), kTolerance);
    EXPECT_NEAR((fast.transform * p_B).y(), in_plane.y(), kTolerance);
    EXPECT_NEAR((fast.transform * p_B).z(), 0.3, kTolerance);
    EXPECT_NEAR(wrap_angle(fast.to_pose2().theta - theta), 0.0, kTolerance);
  }
}

}  // namespace
}  // namespace occgeo::geometry
