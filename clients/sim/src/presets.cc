#include "occgeo/sim/presets.h"

#include <numbers>

namespace occgeo::sim {

namespace {

// The Bearcat III (seed 000 §3.2): differential drive, a SICK LMS200 at 1° resolution limited to 8 m (§3.2.4).
RobotPreset bearcat() {
  RobotPreset preset;
  preset.name = "bearcat";
  preset.drive.wheel_separation_m = 0.7;
  preset.drive.wheel_radius_m = 0.2;
  preset.drive.max_wheel_speed_mps = 1.2;
  preset.footprint = geometry::BoxFootprint{.length = 1.0, .width = 0.8, .height = 1.2, .center_x = 0.0};
  preset.laser = LaserPreset{.name = "front_laser",
                             .X_BS = geometry::Pose2{0.45, 0.0, 0.0},
                             .mount_height_m = 0.6,
                             .angle_min_rad = -std::numbers::pi / 2.0,
                             .angle_increment_rad = std::numbers::pi / 180.0,
                             .beam_count = 181,
                             .range_min_m = 0.0,
                             .range_max_m = 8.0,
                             .scan_period_s = 0.1,
                             .range_noise_sigma_m = 0.01};
  preset.command_timeout_s = 0.5;
  return preset;
}

}  // namespace

const std::vector<RobotPreset>& robot_presets() {
  static const std::vector<RobotPreset> presets = {bearcat()};
  return presets;
}

const RobotPreset* find_robot_preset(std::string_view name) {
  for (const RobotPreset& preset : robot_presets()) {
    if (preset.name == name) return &preset;
  }
  return nullptr;
}

std::string robot_preset_names() {
  std::string names;
  for (const RobotPreset& preset : robot_presets()) {
    if (!names.empty()) names += ", ";
    names += preset.name;
  }
  return names;
}

}  // namespace occgeo::sim
