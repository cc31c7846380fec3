#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/kinematics.h"
#include "occgeo/geometry/pose.h"

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

// Everything the simulator needs to be one kind of robot.
struct RobotPreset {
  std::string name;                         // the --robot name, also the RobotSpec model
  geometry::DifferentialDriveParams drive;  // wheel geometry and speed limit
  geometry::BoxFootprint footprint;         // body outline in base_link, metres
  LaserPreset laser;                        // the one laser scanner
  double command_timeout_s = 0.0;           // watchdog: the wheels stop when no command arrived within this, seconds
};

// Every robot the simulator can be, in the order `--help` lists them.
const std::vector<RobotPreset>& robot_presets();

// The preset called name, or nullptr when there is none.
const RobotPreset* find_robot_preset(std::string_view name);

// The preset names separated by ", ", for messages.
std::string robot_preset_names();

}  // namespace occgeo::sim
