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

// A skid-steered tracked base after the slippage model of seed 004 (Desai thesis, §3.3.2, eq. 3.2–3.4): each
// track's ground speed is its sprocket rim speed r*omega reduced by a constant slippage fraction s. Every length must
// be positive and each slippage in [0, 1) (see validate).
struct SkidSteerParams {
  double track_separation_m = 0.0;       // The thesis's b ("diagonal width of the vehicle"), metres.
  double left_sprocket_radius_m = 0.0;   // The thesis's rl, radius of the left drive sprocket, metres.
  double right_sprocket_radius_m = 0.0;  // The thesis's rr, radius of the right drive sprocket, metres.
  double left_slip = 0.0;   // The thesis's s_l, dimensionless fraction of the left rim speed lost to slippage.
  double right_slip = 0.0;  // The thesis's s_r, dimensionless fraction of the right rim speed lost to slippage.
  double max_track_speed_mps = 0.0;  // Largest rim speed r*omega either track may be commanded, metres per second.
};

// Throws std::invalid_argument naming the first field that is out of range.
void validate(const SkidSteerParams& params);

// The tracked UGV of seed 004 (27 in x 15 in platform, §3.1), with every number's source documented in the
// definition; numbers the thesis does not give are documented defaults.
SkidSteerParams ugv_skid_steer_params();

// Angular velocities of the two drive sprockets, radians per second, positive driving the vehicle forwards.
struct SprocketRates {
  double left_radps = 0.0;
  double right_radps = 0.0;
};

// Rate of change of a planar pose in the world frame: metres per second along x and y, radians per second of yaw.
struct PoseRate {
  double x_mps = 0.0;
  double y_mps = 0.0;
  double theta_radps = 0.0;
};

// The world-frame pose rate of seed 004's eq. 3.2–3.4 for a vehicle at heading X_WB.theta driven at these sprocket
// rates.
PoseRate pose_rate(const Pose2& X_WB, const SprocketRates& rates, const SkidSteerParams& params);

// The body velocity produced by these sprocket rates, slippage included (eq. 3.2–3.4 in the body frame).
BodyVelocity to_body(const SprocketRates& rates, const SkidSteerParams& params);

// The sprocket rates that produce this body velocity despite the slippage (eq. 3.2–3.4 inverted), not limited to
// max_track_speed_mps.
SprocketRates to_sprocket_rates(const BodyVelocity& body, const SkidSteerParams& params);

// The body velocity produced by these commanded track rim speeds r*omega in metres per second, slippage included.
BodyVelocity to_body(const WheelSpeeds& track_rim_speeds, const SkidSteerParams& params);

// The track rim speeds r*omega, metres per second, that produce this body velocity despite the slippage, not limited
// to max_track_speed_mps.
WheelSpeeds to_wheels(const BodyVelocity& body, const SkidSteerParams& params);

// Scales both track rim speeds by one factor so that neither exceeds max_track_speed_mps, keeping their ratio;
// speeds already within the limit are returned unchanged.
WheelSpeeds clamp_to_max_speed(const WheelSpeeds& track_rim_speeds, const SkidSteerParams& params);

}  // namespace occgeo::geometry
