#include <boost/asio/post.hpp>

#include "sensor_ingest.h"

namespace occgeo::service {

namespace {

// HIMM updates only the cells on each element's acoustic axis, traced from the element itself:
// tracing from the robot centre instead (seed 001 §3) shifts every obstacle by the ring's radius.
void insert_range_array(mapping::HimmGrid& grid, const geometry::Pose2& X_WB, const RangeArrayModel& array,
                        const v1::RangeArray& message) {
  for (std::size_t k = 0; k < array.X_SE.size(); ++k) {
    const geometry::Pose2 X_WE = planar_beam_pose(X_WB, array.X_BS, array.X_SE[k]);
    insert_beam(grid, X_WE, static_cast<double>(message.ranges(static_cast<int>(k))), array.range_min_m,
                array.range_max_m);
  }
}

}  // namespace

void handle_range_array(const SessionPtr& session, v1::RangeArray message) {
  auto robot = session->info().robot;
  if (auto error = check_range_array(message, robot->model())) {
    reject_sensor_message(session, *robot, *error, message.seq());
    return;
  }
  asio::post(robot->world().strand(), [session, robot, message = std::move(message)] {
    run_guarded(session, "range_array", 0, [&] {
      const RangeArrayModel& array = *robot->model().find_range_array(message.sensor());
      ingest_sensor_message_on_strand(session, *robot, {"range_array", message.seq(), message.stamp_s()},
                                      [&](const geometry::Pose2& X_WB, mapping::HimmGrid& grid) {
                                        insert_range_array(grid, X_WB, array, message);
                                      });
    });
  });
}

}  // namespace occgeo::service
