#include <boost/asio/post.hpp>

#include "sensor_ingest.h"

namespace occgeo::service {

// HIMM updates only the cells on each element's acoustic axis, traced from the element itself:
// tracing from the robot centre instead (seed 001 §3) shifts every obstacle by the ring's radius.
// The OctoMap gets the same axis from the element's full 6-DoF pose X_WB ∘ X_BS ∘ X_SE.
void insert_range_array(IngestTarget& target, const geometry::Pose2& X_WB, const RangeArrayModel& array,
                        const v1::RangeArray& message) {
  const geometry::Pose3 X_WS = geometry::Pose3::from_pose2(X_WB).compose(array.X_BS);
  for (std::size_t k = 0; k < array.X_SE.size(); ++k) {
    const double reading = static_cast<double>(message.ranges(static_cast<int>(k)));
    const geometry::Pose2 X_WE = planar_beam_pose(X_WB, array.X_BS, array.X_SE[k]);
    insert_beam(target.grid, X_WE, reading, array.range_min_m, array.range_max_m);
    insert_beam_3d(target, X_WS.compose(geometry::Pose3::from_pose2(array.X_SE[k])), reading, array.range_min_m,
                   array.range_max_m);
  }
}

void handle_range_array(const SessionPtr& session, v1::RangeArray message) {
  auto robot = session->info().robot;
  if (auto error = check_range_array(message, robot->model())) {
    reject_sensor_message(session, *robot, *error, message.seq());
    return;
  }
  asio::post(robot->world().strand(), [session, robot, message = std::move(message)] {
    run_guarded(session, "range_array", 0, [&] {
      const RangeArrayModel& array = *robot->model().find_range_array(message.sensor());
      ingest_sensor_message_on_strand(
          session, *robot, {"range_array", message.seq(), message.stamp_s(), &message},
          [&](const geometry::Pose2& X_WB, IngestTarget& target) { insert_range_array(target, X_WB, array, message); });
    });
  });
}

}  // namespace occgeo::service
