#include <boost/asio/post.hpp>
#include <limits>
#include <variant>
#include <vector>

#include "../ingest/model_ingest.h"
#include "model_geometry.h"
#include "sensor_ingest.h"

namespace occgeo::service {

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
