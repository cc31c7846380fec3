#include <boost/asio/post.hpp>
#include <limits>
#include <variant>
#include <vector>

#include "model_geometry.h"
#include "sensor_ingest.h"

namespace occgeo::service {

namespace {

double footprint_height_m(const geometry::Footprint& footprint) {
  return std::visit([](const auto& shape) { return shape.height; }, footprint);
}

}  // namespace

// The 2D grid holds what the robot would hit: points between the ground and the robot's height.
// Each is ray-cast from the sensor's position on the ground, clearing the cells before it and
// marking its own. Points above the robot (overhangs it passes under) or on the ground are left
// for a 3D model.
//
// The OctoMap takes every point (floor and overhangs too), through the PCL filters the `octomap:`
// config enables, each a 3D ray from the sensor's full 6-DoF pose.
void insert_point_cloud(IngestTarget& target, const geometry::Pose2& X_WB, const RobotModel& model,
                        const PointCloudModel& cloud, const v1::PointCloud& message) {
  const geometry::Pose3 X_WS = geometry::Pose3::from_pose2(X_WB).compose(cloud.X_BS);
  const Eigen::Vector2d origin_W = X_WS.translation().head<2>();
  target.touch(origin_W, cloud.beam_limits.reach_m(cloud.range_max_m));
  const double top_m = footprint_height_m(model.footprint);
  // Points lower than this above the ground are the ground itself (noise on a flat floor), not obstacles.
  const double ground_band_m = target.octomap_params.terrain.ground_band_m;
  std::vector<Eigen::Vector3f> points_S;
  points_S.reserve(static_cast<std::size_t>(message.xyz_size() / 3));
  for (int i = 0; i + 2 < message.xyz_size(); i += 3) {
    points_S.emplace_back(message.xyz(i), message.xyz(i + 1), message.xyz(i + 2));
    const Eigen::Vector3d p_W = X_WS.transform * points_S.back().cast<double>();
    if (p_W.z() < ground_band_m || p_W.z() > top_m) continue;
    const Eigen::Vector2d ray_W = p_W.head<2>() - origin_W;
    const double length_m = ray_W.norm();
    if (length_m == 0.0) {
      target.grid.insert_ray(origin_W, origin_W, true);
      continue;
    }
    // A point has no "no return": every one is a return, however far.
    insert_limited_ray(target.grid, origin_W, ray_W / length_m, length_m, std::numeric_limits<double>::infinity(),
                       cloud.beam_limits);
  }
  target.octree_work.emplace_back(
      [X_WS, limits = cloud.beam_limits, points_S = std::move(points_S)](mapping::OctoMapModel& octomap) {
        octomap.insert_cloud(X_WS, points_S, limits);
      });
}

void handle_point_cloud(const SessionPtr& session, v1::PointCloud message) {
  auto robot = session->info().robot;
  if (auto error = check_point_cloud(message, robot->model())) {
    reject_sensor_message(session, *robot, *error, message.seq());
    return;
  }
  const ServerConfig& config = session->core().config();
  const std::uint64_t voxels = cloud_voxel_estimate(message, *robot->model().find_point_cloud(message.sensor()),
                                                    config.octomap.max_range_m, config.octomap.resolution_m);
  if (auto error = check_voxel_budget(voxels, config.limits.max_scan_voxels, "point_cloud.xyz")) {
    reject_sensor_message(session, *robot, *error, message.seq());
    return;
  }
  asio::post(robot->world().strand(), [session, robot, message = std::move(message)] {
    run_guarded(session, "point_cloud", 0, [&] {
      const RobotModel& model = robot->model();
      const PointCloudModel& cloud = *model.find_point_cloud(message.sensor());
      ingest_sensor_message_on_strand(session, *robot, {"point_cloud", message.seq(), message.stamp_s(), &message},
                                      [&](const geometry::Pose2& X_WB, IngestTarget& target) {
                                        insert_point_cloud(target, X_WB, model, cloud, message);
                                      });
    });
  });
}

}  // namespace occgeo::service
