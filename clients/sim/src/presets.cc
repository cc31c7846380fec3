#include "occgeo/sim/presets.h"

#include <cmath>
#include <numbers>

namespace occgeo::sim {

namespace {

constexpr double kDegree = std::numbers::pi / 180.0;

// The Bearcat III (seed 000 §3.2): differential drive, a SICK LMS200 at 1° resolution limited to 8 m (§3.2.4).
RobotPreset bearcat() {
  RobotPreset preset;
  preset.name = "bearcat";
  preset.kinematics =
      geometry::DifferentialDriveParams{.wheel_separation_m = 0.7, .wheel_radius_m = 0.2, .max_wheel_speed_mps = 1.2};
  preset.footprint = geometry::BoxFootprint{.length = 1.0, .width = 0.8, .height = 1.2, .center_x = 0.0};
  preset.sensors = {LaserPreset{.name = "front_laser",
                                .X_BS = geometry::Pose2{0.45, 0.0, 0.0},
                                .mount_height_m = 0.6,
                                .angle_min_rad = -std::numbers::pi / 2.0,
                                .angle_increment_rad = std::numbers::pi / 180.0,
                                .beam_count = 181,
                                .range_min_m = 0.0,
                                .range_max_m = 8.0,
                                .scan_period_s = 0.1,
                                .range_noise_sigma_m = 0.01}};
  preset.command_timeout_s = 0.5;
  return preset;
}

// The Bearcat with a depth camera at the top of its front (seed 000 §5 names the single laser plane as why the
// short and the overhanging obstacle of Fig. 5.2 are missed): an Intel RealSense D435-like sensor, 87° x 58° field of
// view (the D435's depth figures), sampled as 40 x 30 rays (the real 848 x 480 image would be filtered down to about
// this by the server's 5 cm voxel filter anyway), 0.3-6 m, 5 frames per second, 1 cm range noise (assumed: the D435
// is within about 2 % of the range up to 2 m). Mounted at x = 0.45 m, 1.1 m high (just under the 1.2 m top), pitched
// 20° down: it sees the floor from about 1 m ahead, a 0.3 m kerb from about 1.4 m ahead of the camera and the
// underside of anything lower than the robot within its range.
RobotPreset bearcat_3d() {
  RobotPreset preset = bearcat();
  preset.name = "bearcat_3d";
  preset.sensors.push_back(
      DepthSensorPreset{.name = "front_depth",
                        .X_BS = geometry::Pose3::from_xyz_rpy(0.45, 0.0, 1.1, 0.0, 20.0 * kDegree, 0.0),
                        .columns = 40,
                        .rows = 30,
                        .horizontal_fov_rad = 87.0 * kDegree,
                        .vertical_fov_rad = 58.0 * kDegree,
                        .range_min_m = 0.3,
                        .range_max_m = 6.0,
                        .period_s = 0.2,
                        .range_noise_sigma_m = 0.01});
  return preset;
}

// The Nomad Super Scout II of seed 001 (a simulator run with HIMM on a ring of 16 sonars; the seed numbers the front
// sonars 0-2 and 13-15, so sonar 0 faces forward and the numbering runs counter-clockwise). The seed gives no
// dimensions; these are the commonly published Super Scout II figures (Nomadic Technologies), marked as such:
//   - round body 0.41 m across and 0.35 m tall; the simulator's footprint is a box, so the 0.41 m x 0.41 m square
//     that encloses the disc (conservative in the corners);
//   - two-wheel differential drive at the centre: wheels 0.34 m apart (assumed: inside the 0.41 m body), radius
//     0.095 m (assumed), top speed 1.0 m/s;
//   - 16 Polaroid 6500 sonars 22.5° apart on the body's edge (radius 0.2 m) at 0.3 m height (assumed), each facing
//     outwards: 0.15-6.5 m (the Polaroid ranging module's span), a 25° cone, the whole ring fired every 0.2 s (assumed:
//     the 6.5 m round trip takes 38 ms per sonar, and the Scout fires groups of sonars in turn), range noise 1% of
//     the range;
//   - specular echoes only (Kuc & Siegel 1987; Leonard & Durrant-Whyte, "Directed Sonar Sensing"): a ray's hit echoes
//     when its incidence angle is at most 8°. That is well over half (2.1°) the 25°/6 ≈ 4.2° spacing of the 7 rays,
//     so whenever a surface's normal points back at the transducer from inside the cone, the ray nearest that normal
//     qualifies (its incidence is at most 2.1°, so it reads the perpendicular distance within 0.07%); and it is close
//     to the 7-10° critical angle reported for Polaroid transducers on smooth walls.
RobotPreset scout() {
  RobotPreset preset;
  preset.name = "scout";
  preset.kinematics = geometry::DifferentialDriveParams{
      .wheel_separation_m = 0.34, .wheel_radius_m = 0.095, .max_wheel_speed_mps = 1.0};
  preset.footprint = geometry::BoxFootprint{.length = 0.41, .width = 0.41, .height = 0.35, .center_x = 0.0};
  RangeArrayPreset sonar{.name = "sonar_ring",
                         .X_BS = geometry::Pose2{0.0, 0.0, 0.0},
                         .mount_height_m = 0.3,
                         .elements = {},
                         .beam_width_rad = 25.0 * kDegree,
                         .rays_per_beam = 7,
                         .specular_tolerance_rad = 8.0 * kDegree,
                         .range_min_m = 0.15,
                         .range_max_m = 6.5,
                         .period_s = 0.2,
                         .range_noise_fraction = 0.01};
  constexpr int kSonars = 16;
  constexpr double kRingRadius_m = 0.2;
  for (int k = 0; k < kSonars; ++k) {
    const double yaw = 2.0 * std::numbers::pi * k / kSonars;
    sonar.elements.push_back({kRingRadius_m * std::cos(yaw), kRingRadius_m * std::sin(yaw), yaw});
  }
  preset.sensors = {sonar};
  // Seed 001's system: the server wanders it on its sonar ring and maps with HIMM as it goes.
  preset.default_behaviour = v1::BEHAVIOUR_WANDER;
  preset.command_timeout_s = 0.5;
  return preset;
}

// The Parallax ActivityBot of seed 003 (§3.2-3.4, §4): differential drive with 64-tick encoders (3.25 mm per tick,
// wheels 105.8 mm apart, geometry::activitybot_encoder_params), and a Garmin LIDAR-Lite v3 swept by a standard servo.
//   - top speed: drive_setMaxSpeed's default 128 ticks/s (§3.3.3) = 0.416 m/s, also drive_goto's speed;
//   - footprint 0.15 m x 0.13 m x 0.12 m (assumed: the ActivityBot chassis is about 0.14 m across, wheels outside
//     it; the box encloses chassis and wheels, the height includes the servo and the LIDAR);
//   - LIDAR-Lite v3 (§3.2.4 key features): 0-40 m, accuracy ±2.5 cm under 5 m and ±10 cm from 5 m (used as the
//     noise σ), at the front (x = 0.05 m, assumed) 0.1 m above the ground (assumed);
//   - servo: servo_angle 0..1800 tenths of a degree, 900 straight ahead (§3.3.3), so -90° to +90° in 1° steps,
//     ping-pong. The thesis's program pauses 500 ms per 1° step (§4.4); the simulator uses 0.02 s per step instead:
//     the LIDAR-Lite's 50 Hz default rep rate, and a standard servo turns 1° in about 3 ms. Change step_period_s to
//     reproduce the thesis's pace.
RobotPreset activitybot() {
  const geometry::EncoderParams encoders = geometry::activitybot_encoder_params();
  constexpr double kMaxTicksPerSecond = 128.0;
  const double max_speed_mps = kMaxTicksPerSecond * geometry::metres_per_tick(encoders);
  RobotPreset preset;
  preset.name = "activitybot";
  preset.kinematics = geometry::DifferentialDriveParams{.wheel_separation_m = encoders.wheel_separation_m,
                                                        .wheel_radius_m = encoders.wheel_radius_m,
                                                        .max_wheel_speed_mps = max_speed_mps};
  preset.footprint = geometry::BoxFootprint{.length = 0.15, .width = 0.13, .height = 0.12, .center_x = 0.0};
  preset.sensors = {ServoRangePreset{.name = "lidar_lite",
                                     .X_BS = geometry::Pose2{0.05, 0.0, 0.0},
                                     .mount_height_m = 0.1,
                                     .servo_min_rad = -90.0 * kDegree,
                                     .servo_max_rad = 90.0 * kDegree,
                                     .servo_step_rad = 1.0 * kDegree,
                                     .step_period_s = 0.02,
                                     .range_min_m = 0.0,
                                     .range_max_m = 40.0,
                                     .noise_sigma_near_m = 0.025,
                                     .noise_sigma_far_m = 0.10,
                                     .noise_far_from_m = 5.0}};
  preset.encoders = encoders;
  preset.drive_goto_speed_mps = max_speed_mps;
  // Seed 003's system: the server runs PointBug on its sweeps once a controller gives it a goal; until then it
  // stands, answered reading by reading.
  preset.default_behaviour = v1::BEHAVIOUR_STOP;
  preset.activitybot_units = true;
  preset.command_timeout_s = 0.5;
  return preset;
}

// The tracked UGV of seed 004 (§3.1-3.3): a 27 in x 15 in skid-steered platform (geometry::ugv_skid_steer_params
// documents its numbers) with a Hokuyo URG-04LX (§3.2.1).
//   - footprint 0.686 m x 0.381 m (27 in x 15 in), 0.35 m tall (assumed: platform plus laser);
//   - powertrain: first-order lag τ = 0.1 s on the track rim speeds (assumed; the thesis's Simulink motor model has no
//     published constants); the simulated tracks slip exactly as declared (no slip in the default parameters);
//   - URG-04LX: 4 m range, ±20 mm accuracy (used as σ), 240° in 100 ms (10 Hz). The 682 beams from -120° to +120°
//     (increment 240°/681) follow the CoreSLAM URG log that clients/replay reads; the 0.02 m minimum is the URG's
//     (shorter values are error codes). Mounted at the front, x = 0.3 m, 0.3 m high (assumed; below the 0.7 m cone
//     of §6 so the PTEM worlds' obstacles are seen).
RobotPreset ugv() {
  constexpr double kMetresPerInch = 0.0254;
  RobotPreset preset;
  preset.name = "ugv";
  // Tracks slip (seed 004 §3.3.2 and §5, where slippage is why dead reckoning drifts) but the thesis gives no
  // values: 4 % on the left and 6 % on the right are assumed, unequal so that an uncompensated straight command
  // curves. The RobotSpec declares them, so the server's track commands compensate.
  geometry::SkidSteerParams tracks = geometry::ugv_skid_steer_params();
  tracks.left_slip = 0.04;
  tracks.right_slip = 0.06;
  preset.kinematics = SkidSteerPreset{.params = tracks, .powertrain_time_constant_s = 0.1};
  preset.footprint = geometry::BoxFootprint{
      .length = 27.0 * kMetresPerInch, .width = 15.0 * kMetresPerInch, .height = 0.35, .center_x = 0.0};
  constexpr int kBeams = 682;
  constexpr double kFov_rad = 240.0 * kDegree;
  preset.sensors = {LaserPreset{.name = "urg_04lx",
                                .X_BS = geometry::Pose2{0.3, 0.0, 0.0},
                                .mount_height_m = 0.3,
                                .angle_min_rad = -kFov_rad / 2.0,
                                .angle_increment_rad = kFov_rad / (kBeams - 1),
                                .beam_count = kBeams,
                                .range_min_m = 0.02,
                                .range_max_m = 4.0,
                                .scan_period_s = 0.1,
                                .range_noise_sigma_m = 0.020}};
  preset.command_timeout_s = 0.5;
  return preset;
}

}  // namespace

const std::string& sensor_name(const SensorPreset& sensor) {
  return std::visit([](const auto& preset) -> const std::string& { return preset.name; }, sensor);
}

const LaserPreset* RobotPreset::laser() const {
  for (const SensorPreset& sensor : sensors) {
    if (const auto* laser = std::get_if<LaserPreset>(&sensor)) return laser;
  }
  return nullptr;
}

LaserPreset* RobotPreset::laser() {
  for (SensorPreset& sensor : sensors) {
    if (auto* laser = std::get_if<LaserPreset>(&sensor)) return laser;
  }
  return nullptr;
}

double RobotPreset::max_wheel_speed_mps() const {
  if (const auto* skid = std::get_if<SkidSteerPreset>(&kinematics)) return skid->params.max_track_speed_mps;
  return std::get<geometry::DifferentialDriveParams>(kinematics).max_wheel_speed_mps;
}

const std::vector<RobotPreset>& robot_presets() {
  static const std::vector<RobotPreset> presets = {bearcat(), scout(), activitybot(), ugv(), bearcat_3d()};
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
