#include <algorithm>
#include <boost/asio/post.hpp>
#include <cmath>
#include <optional>
#include <variant>
#include <vector>

#include "../ingest/model_ingest.h"
#include "occgeo/service/log.h"
#include "robot_control.h"
#include "sensor_ingest.h"

namespace occgeo::service {

namespace {

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
        insert_laser_scan(robot->world(), target, model.id, X_WB, laser, scan);
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
