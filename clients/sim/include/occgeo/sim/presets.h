#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "occgeo/geometry/dead_reckoning.h"
#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/kinematics.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/v1/control.pb.h"

namespace occgeo::sim {

// A simulated planar laser scanner: where it sits on the robot and how it sweeps. Beam k points at
// angle_min_rad + k * angle_increment_rad in the sensor frame.
struct LaserPreset {
  std::string name;             // sensor name, unique on the robot; every scan carries it
  geometry::Pose2 X_BS;         // sensor pose in base_link: x, y in metres, yaw in radians; the scan plane is level
  double mount_height_m = 0.0;  // height of the scan plane above the ground, metres
  double angle_min_rad = 0.0;   // direction of the first beam, radians
  double angle_increment_rad = 0.0;  // angle between consecutive beams, radians
  std::uint32_t beam_count = 0;      // number of beams per sweep
  double range_min_m = 0.0;          // readings are never shorter than this, metres
  double range_max_m = 0.0;          // a beam with no hit closer than this reads exactly this, metres
  double scan_period_s = 0.0;        // time between sweeps, seconds; a whole number of physics steps
  double range_noise_sigma_m = 0.0;  // standard deviation of the Gaussian noise on each hit's range, metres
};

// A ring or array of single-beam range sensors fired together, e.g. a sonar ring. Element k sits at elements[k] in the
// sensor frame and measures along its own x axis (the acoustic axis). Like a real sonar on smooth surfaces, an element
// hears only SPECULAR echoes: a surface inside its cone echoes only where it faces the transducer within
// specular_tolerance_rad; the element reports the nearest such echo, or range_max_m when there is none (see
// RangeArraySimulator).
struct RangeArrayPreset {
  std::string name;                       // sensor name, unique on the robot
  geometry::Pose2 X_BS;                   // sensor frame in base_link, metres and radians
  double mount_height_m = 0.0;            // height of the elements above the ground, metres
  std::vector<geometry::Pose2> elements;  // each element's pose in the sensor frame
  double beam_width_rad = 0.0;            // full opening angle of each element's cone, radians
  std::uint32_t rays_per_beam = 1;        // rays cast evenly across the cone, edges included; odd, so one is the axis
  // Largest incidence angle (between the reversed ray and the surface normal) at which a ray's hit still echoes back,
  // radians, in (0, π/2]; π/2 accepts every hit (the nearest hit anywhere in the cone).
  double specular_tolerance_rad = 0.0;
  double range_min_m = 0.0;           // readings are never shorter than this, metres
  double range_max_m = 0.0;           // an element with no echo closer than this reads exactly this, metres
  double period_s = 0.0;              // time between firings of the whole array, seconds; whole physics steps
  double range_noise_fraction = 0.0;  // noise standard deviation as a fraction of the measured range
};

// A single-beam rangefinder that a servo sweeps about the sensor frame's z axis, ping-pong from servo_min_rad to
// servo_max_rad and back in servo_step_rad steps, one reading per step. Angle 0 is the sensor frame's x axis,
// counter-clockwise positive.
struct ServoRangePreset {
  std::string name;                 // sensor name, unique on the robot
  geometry::Pose2 X_BS;             // sensor frame (servo axis) in base_link, metres and radians
  double mount_height_m = 0.0;      // height of the beam above the ground, metres
  double servo_min_rad = 0.0;       // first angle of the sweep, radians
  double servo_max_rad = 0.0;       // last angle of the sweep, radians; (max - min) / step is a whole number
  double servo_step_rad = 0.0;      // angle between consecutive readings, radians
  double step_period_s = 0.0;       // time per step (servo move plus measurement), seconds; whole physics steps
  double range_min_m = 0.0;         // readings are never shorter than this, metres
  double range_max_m = 0.0;         // no return closer than this reads exactly this, metres
  double noise_sigma_near_m = 0.0;  // range noise standard deviation below noise_far_from_m, metres
  double noise_sigma_far_m = 0.0;   // range noise standard deviation from noise_far_from_m on, metres
  double noise_far_from_m = 0.0;    // where the far noise starts, metres
};

// A forward-looking depth camera or tilted 3-D lidar: rows x columns rays spread evenly in angle over its fields of
// view about its x axis (see depth_ray_direction_S), cast in 3-D against the shapes and the ground. Each frame is sent
// as a PointCloud of the returns (floor returns included), in the sensor frame.
struct DepthSensorPreset {
  std::string name;                  // sensor name, unique on the robot
  geometry::Pose3 X_BS;              // 6-DoF sensor pose in base_link (x forward, z up; positive pitch looks down)
  std::uint32_t columns = 0;         // rays across, left to right
  std::uint32_t rows = 0;            // rays down, top to bottom
  double horizontal_fov_rad = 0.0;   // full horizontal field of view, radians, in (0, π)
  double vertical_fov_rad = 0.0;     // full vertical field of view, radians, in (0, π)
  double range_min_m = 0.0;          // returns nearer than this are not reported, metres
  double range_max_m = 0.0;          // returns from this on are not reported, metres
  double period_s = 0.0;             // time between frames, seconds; a whole number of physics steps
  double range_noise_sigma_m = 0.0;  // standard deviation of the Gaussian noise on each return's range, metres
};

using SensorPreset = std::variant<LaserPreset, RangeArrayPreset, ServoRangePreset, DepthSensorPreset>;

// The name every sensor preset carries.
const std::string& sensor_name(const SensorPreset& sensor);

// A skid-steered tracked base whose track rim speeds follow their commands through a first-order powertrain lag. The
// simulated tracks slip by exactly the fractions the parameters declare.
struct SkidSteerPreset {
  geometry::SkidSteerParams params;
  double powertrain_time_constant_s = 0.0;  // first-order lag of each track's rim speed, seconds (0: none)
};

using KinematicsPreset = std::variant<geometry::DifferentialDriveParams, SkidSteerPreset>;

// Everything the simulator needs to be one kind of robot.
struct RobotPreset {
  std::string name;                   // the --robot name, also the RobotSpec model
  KinematicsPreset kinematics;        // differential drive or skid steer, with the speed limit
  geometry::BoxFootprint footprint;   // body outline in base_link, metres
  std::vector<SensorPreset> sensors;  // in RobotSpec order; the first laser is the one the server steers by
  std::optional<geometry::EncoderParams> encoders;  // wheel encoders: the driver sends ticks instead of odometry
  // Speed of each wheel during drive_goto, m/s (the ActivityBot's drive_setMaxSpeed default); 0 when the robot has no
  // drive_goto.
  double drive_goto_speed_mps = 0.0;
  // RobotSpec.default_behaviour: what the server runs for it while nobody set a behaviour (unspecified: the server's
  // own).
  v1::Behaviour default_behaviour = v1::BEHAVIOUR_UNSPECIFIED;
  // RobotSpec.command_units: the robot takes drive_goto / drive_speed encoder ticks (seed 003's ActivityBot).
  bool activitybot_units = false;
  double command_timeout_s = 0.0;  // watchdog: the wheels stop when no command arrived within this, seconds

  // The first laser (the one the server steers by), or nullptr when the robot has none.
  [[nodiscard]] const LaserPreset* laser() const;
  [[nodiscard]] LaserPreset* laser();
  // The largest rim speed either wheel or track may be commanded, m/s.
  [[nodiscard]] double max_wheel_speed_mps() const;
};

// Every robot the simulator can be, in the order `--help` lists them.
const std::vector<RobotPreset>& robot_presets();

// The preset called name, or nullptr when there is none.
const RobotPreset* find_robot_preset(std::string_view name);

// The preset names separated by ", ", for messages.
std::string robot_preset_names();

}  // namespace occgeo::sim
