#pragma once

#include "occgeo/geometry/pose.h"

namespace occgeo::geometry {

// A differential-drive base: two driven wheels on a common axle through base_link. Every field must be set to a
// positive value (see validate).
struct DifferentialDriveParams {
  double wheel_separation_m = 0.0;   // Distance between the wheels' contact points, metres.
  double wheel_radius_m = 0.0;       // Wheel radius, metres.
  double max_wheel_speed_mps = 0.0;  // Largest rim speed either wheel may be commanded, metres per second.
};

// Throws std::invalid_argument naming the first field that is not positive and finite.
void validate(const DifferentialDriveParams& params);

// Rim speeds of the two wheels, metres per second, positive forwards.
struct WheelSpeeds {
  double left_mps = 0.0;
  double right_mps = 0.0;
};

// Velocity of base_link in its own frame: forward speed in metres per second, yaw rate in radians per second
// counter-clockwise.
struct BodyVelocity {
  double linear_mps = 0.0;
  double angular_radps = 0.0;
};

// The body velocity produced by these wheel speeds.
BodyVelocity to_body(const WheelSpeeds& wheels, const DifferentialDriveParams& params);

// The wheel speeds that produce this body velocity, not limited to max_wheel_speed_mps.
WheelSpeeds to_wheels(const BodyVelocity& body, const DifferentialDriveParams& params);

// Scales both wheel speeds by one factor so that neither exceeds max_wheel_speed_mps, keeping the ratio between
// them (hence the path's curvature); speeds already within the limit are returned unchanged.
WheelSpeeds clamp_to_max_speed(const WheelSpeeds& wheels, const DifferentialDriveParams& params);

// The pose reached after driving at constant body velocity v for dt_s seconds from X_WB, integrated exactly along
// the circular arc (a straight line when the yaw rate is zero).
Pose2 integrate(const Pose2& X_WB, const BodyVelocity& v, double dt_s);

}  // namespace occgeo::geometry
