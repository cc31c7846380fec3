#include <algorithm>
#include <boost/asio/post.hpp>
#include <cmath>
#include <optional>
#include <variant>
#include <vector>

#include "occgeo/service/log.h"
#include "robot_control.h"
#include "sensor_ingest.h"

namespace occgeo::service {

namespace {

// The sensor's pose projected on the ground plane, and whether it is mounted upside down (its
// beams then sweep clockwise in the world).
struct PlanarSensorPose {
  geometry::Pose2 X_WS;
  bool mirrored = false;
};

PlanarSensorPose planar_sensor_pose(const geometry::Pose2& X_WB, const LaserModel& laser) {
  const geometry::Pose3 X_WS = geometry::Pose3::from_pose2(X_WB).compose(laser.X_BS);
  return {X_WS.to_pose2(), X_WS.transform.linear()(2, 2) < 0.0};
}

// Inserts the scan's readings into the grid; readings below the sensor's minimum range carry no
// information and are skipped.
void insert_scan(mapping::HimmGrid& grid, const PlanarSensorPose& sensor, const LaserModel& laser,
                 const v1::LaserScan& scan) {
  const double sign = sensor.mirrored ? -1.0 : 1.0;
  const auto angle_min = static_cast<float>(sign * laser.angle_min_rad);
  const auto angle_increment = static_cast<float>(sign * laser.angle_increment_rad);
  const std::span<const float> ranges(scan.ranges().data(), static_cast<std::size_t>(scan.ranges_size()));
  const auto range_min = static_cast<float>(laser.range_min_m);
  const bool all_valid = std::all_of(ranges.begin(), ranges.end(), [&](float r) { return r >= range_min; });
  if (all_valid) {
    grid.insert_scan(sensor.X_WS, angle_min, angle_increment, ranges, static_cast<float>(laser.range_max_m),
                     laser.beam_limits);
    return;
  }
  const Eigen::Vector2d origin = sensor.X_WS.position();
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    if (ranges[i] < range_min) continue;
    const double bearing =
        sensor.X_WS.theta + sign * (laser.angle_min_rad + laser.angle_increment_rad * static_cast<double>(i));
    insert_limited_ray(grid, origin, Eigen::Vector2d(std::cos(bearing), std::sin(bearing)),
                       static_cast<double>(ranges[i]), laser.range_max_m, laser.beam_limits);
  }
}

// Inserts the scan into the world's OctoMap from the laser's full 6-DoF pose X_WS = X_WB (at z = 0)
// ∘ mount, so a pitched or rolled laser maps what it sees in 3D (an upside-down mount needs no
// mirroring here: the rotation does it). Readings below range_min_m become 0, which the model skips.
void insert_scan_3d(IngestTarget& target, const geometry::Pose2& X_WB, const LaserModel& laser,
                    const v1::LaserScan& scan) {
  const geometry::Pose3 X_WS = geometry::Pose3::from_pose2(X_WB).compose(laser.X_BS);
  target.touch(X_WS.translation().head<2>(), laser.beam_limits.reach_m(laser.range_max_m));
  std::vector<float> ranges(scan.ranges().begin(), scan.ranges().end());
  const auto range_min = static_cast<float>(laser.range_min_m);
  for (float& r : ranges) {
    if (r < range_min) r = 0.0F;
  }
  target.octree_work.emplace_back([X_WS, angle_min = static_cast<float>(laser.angle_min_rad),
                                   angle_increment = static_cast<float>(laser.angle_increment_rad),
                                   range_max = static_cast<float>(laser.range_max_m), limits = laser.beam_limits,
                                   ranges = std::move(ranges)](mapping::OctoMapModel& octomap) {
    octomap.insert_scan(X_WS, angle_min, angle_increment, ranges, range_max, limits);
  });
}

// Feeds the scan's returns to the world's PTEM (seed 004 §4.2): the end points of the beams whose
// reading lies in [range_min_m, range_max_m) and within the laser's max_insert_range_m, placed in the
// world frame from the sensor's ground pose exactly as the grid insertion places them, with the sector
// the scan covered (centred on the middle beam, one angle increment per beam wide, out to the shorter
// of range_max_m and max_insert_range_m) for the single-scan rule.
void insert_ptem(World& world, const PlanarSensorPose& sensor, const LaserModel& laser, const v1::LaserScan& scan) {
  constexpr double kTwoPi = 2.0 * M_PI;
  const double sign = sensor.mirrored ? -1.0 : 1.0;
  const Eigen::Vector2d origin = sensor.X_WS.position();
  std::vector<Eigen::Vector2d> points_W;
  points_W.reserve(static_cast<std::size_t>(scan.ranges_size()));
  const double insert_range_m = laser.beam_limits.max_insert_range_m;
  for (int i = 0; i < scan.ranges_size(); ++i) {
    const double reading = static_cast<double>(scan.ranges(i));
    if (reading < laser.range_min_m || reading >= laser.range_max_m || reading > insert_range_m) continue;
    const double bearing =
        sensor.X_WS.theta + sign * (laser.angle_min_rad + laser.angle_increment_rad * static_cast<double>(i));
    points_W.push_back(origin + reading * Eigen::Vector2d(std::cos(bearing), std::sin(bearing)));
  }
  const double beams = static_cast<double>(laser.beam_count);
  mapping::PtemScan ptem_scan;
  ptem_scan.stamp_s = scan.stamp_s();
  ptem_scan.p_WS = origin;
  ptem_scan.yaw_WS = sensor.X_WS.theta + sign * (laser.angle_min_rad + laser.angle_increment_rad * (beams - 1.0) / 2.0);
  ptem_scan.field_of_view_rad = std::clamp(std::abs(laser.angle_increment_rad) * beams, 1e-9, kTwoPi);
  ptem_scan.max_range_m = std::min(laser.range_max_m, insert_range_m);
  ptem_scan.points_W = points_W;
  world.insert_ptem_on_strand(ptem_scan);
}

// Viewers draw at most this many returns of a scan (a Hokuyo UTM-30LX's 1081 beams); denser scans are thinned.
constexpr std::size_t kMaxViewedScanPoints = 1081;

// The end points of the scan's returns in [range_min_m, range_max_m), world frame, placed as the grid places them;
// for viewers (the live view), so floats and at most kMaxViewedScanPoints of them.
std::vector<Eigen::Vector2f> scan_returns_W(const geometry::Pose2& X_WB, const LaserModel& laser,
                                            const v1::LaserScan& scan) {
  const PlanarSensorPose sensor = planar_sensor_pose(X_WB, laser);
  const double sign = sensor.mirrored ? -1.0 : 1.0;
  const Eigen::Vector2d origin = sensor.X_WS.position();
  const auto beams = static_cast<std::size_t>(scan.ranges_size());
  const std::size_t stride = (beams + kMaxViewedScanPoints - 1) / kMaxViewedScanPoints;
  std::vector<Eigen::Vector2f> points_W;
  points_W.reserve(std::min(beams, kMaxViewedScanPoints));
  for (std::size_t i = 0; i < beams; i += std::max<std::size_t>(stride, 1)) {
    const double reading = static_cast<double>(scan.ranges(static_cast<int>(i)));
    if (reading < laser.range_min_m || reading >= laser.range_max_m) continue;
    const double bearing =
        sensor.X_WS.theta + sign * (laser.angle_min_rad + laser.angle_increment_rad * static_cast<double>(i));
    points_W.push_back((origin + reading * Eigen::Vector2d(std::cos(bearing), std::sin(bearing))).cast<float>());
  }
  return points_W;
}

// Orders, maps and answers one validated scan; runs on the robot's world strand.
void ingest_on_strand(const SessionPtr& session, const std::shared_ptr<Robot>& robot, const v1::LaserScan& scan,
                      double expiry_s) {
  const RobotModel& model = robot->model();
  const LaserModel& laser = *model.find_laser(scan.sensor());
  std::optional<geometry::Pose2> placed_at_W;
  WorkAfterCommand after_command(robot->world());
  const bool accepted = ingest_sensor_message_on_strand(
      session, *robot, {"laser_scan", scan.seq(), scan.stamp_s(), &scan},
      [&](const geometry::Pose2& X_WB, IngestTarget& target) {
        placed_at_W = X_WB;
        insert_laser_scan(robot->world(), target, X_WB, laser, scan);
      },
      &after_command);
  if (!accepted) return;

  // The behaviour steers from the robot's first laser; other lasers and the other sensor kinds
  // only update the map, so a robot without a laser gets no motion commands.
  if (&laser != &model.lasers.front()) return;
  // What answers the scan is the behaviour the lease holder set (bearcat while nobody set one),
  // overridden by a latched e-stop.
  const control::ScanView view{
      laser.angle_min_rad, laser.angle_increment_rad,
      std::span<const float>(scan.ranges().data(), static_cast<std::size_t>(scan.ranges_size())), laser.range_max_m};
  v1::MotionCommand command =
      command_for_scan_on_strand(*robot, view, scan.stamp_s(), expiry_s, session->core().config());
  if (placed_at_W) {
    auto scan_W = std::make_shared<const std::vector<Eigen::Vector2f>>(scan_returns_W(*placed_at_W, laser, scan));
    robot->update_state([&](RobotState& state) {
      state.scan_W = std::move(scan_W);
      state.scan_stamp_s = scan.stamp_s();
    });
  }
  send_command_on_strand(session, *robot, std::move(command), scan.seq());
}

}  // namespace

void insert_laser_scan(World& world, IngestTarget& target, const geometry::Pose2& X_WB, const LaserModel& laser,
                       const v1::LaserScan& scan) {
  const PlanarSensorPose sensor = planar_sensor_pose(X_WB, laser);
  insert_ptem(world, sensor, laser, scan);
  insert_scan(target.grid, sensor, laser, scan);
  insert_scan_3d(target, X_WB, laser, scan);
}

void handle_laser_scan(const SessionPtr& session, v1::LaserScan scan) {
  auto robot = session->info().robot;
  if (auto error = check_scan(scan, robot->model())) {
    reject_sensor_message(session, *robot, *error, scan.seq());
    return;
  }
  // A scan that would cost the world's strand far more than a sensor's normal scan is refused before it is queued.
  const ServerConfig& config = session->core().config();
  const std::uint64_t voxels = scan_voxel_estimate(scan, *robot->model().find_laser(scan.sensor()),
                                                   config.octomap.max_range_m, config.octomap.resolution_m);
  if (auto error = check_voxel_budget(voxels, config.limits.max_scan_voxels, "laser_scan.ranges")) {
    reject_sensor_message(session, *robot, *error, scan.seq());
    return;
  }
  const double expiry_s = session->core().config().control.command_expiry_s;
  asio::post(robot->world().strand(), [session, robot, scan = std::move(scan), expiry_s] {
    run_guarded(session, "laser_scan", 0, [&] { ingest_on_strand(session, robot, scan, expiry_s); });
  });
}

}  // namespace occgeo::service
