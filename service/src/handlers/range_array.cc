#include <algorithm>
#include <boost/asio/post.hpp>
#include <cmath>
#include <limits>

#include "../ingest/model_ingest.h"
#include "robot_control.h"
#include "sensor_ingest.h"

namespace occgeo::service {

namespace {

// The readings as seen from base_link: each element's axis bearing, and its reading plus the element's offset along
// that axis (a ring's radius), so the behaviour judges distances from the robot's centre. No echo reads +inf.
control::RangeSet ring_in_base(const RangeArrayModel& array, const v1::RangeArray& message) {
  control::RangeSet ring;
  double largest_offset_m = 0.0;
  for (std::size_t k = 0; k < array.X_SE.size(); ++k) {
    const geometry::Pose2 X_BE = planar_beam_pose(geometry::Pose2{}, array.X_BS, array.X_SE[k]);
    const double offset_m = X_BE.x * std::cos(X_BE.theta) + X_BE.y * std::sin(X_BE.theta);
    largest_offset_m = std::max(largest_offset_m, offset_m);
    const auto reading = static_cast<double>(message.ranges(static_cast<int>(k)));
    const double range_m =
        reading >= array.range_max_m ? std::numeric_limits<double>::infinity() : std::max(reading, 0.0) + offset_m;
    ring.beams.push_back({X_BE.theta, range_m});
  }
  ring.range_max_m = array.range_max_m + largest_offset_m;
  return ring;
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
      const RobotModel& model = robot->model();
      const RangeArrayModel& array = *model.find_range_array(message.sensor());
      WorkAfterCommand after_command(robot->world());
      const bool accepted = ingest_sensor_message_on_strand(
          session, *robot, {"range_array", message.seq(), message.stamp_s(), &message},
          [&](const geometry::Pose2& X_WB, IngestTarget& target) { insert_range_array(target, X_WB, array, message); },
          &after_command);
      // A robot without a laser steers by its first range array: every firing is answered with a command, once the
      // robot is meant to be steered (its spec names a default behaviour, or a lease holder set one); a driver that
      // declared neither keeps deciding how it moves, as before range arrays could steer.
      if (!accepted || !model.lasers.empty() || &array != &model.range_arrays.front()) return;
      if (model.spec.default_behaviour() == v1::BEHAVIOUR_UNSPECIFIED && robot->control().state().drive_generation == 0)
        return;
      const ServerConfig& config = session->core().config();
      v1::MotionCommand command =
          command_for_scan_on_strand(*robot, control::ScanView{}, message.stamp_s(), config.control.command_expiry_s,
                                     config, ring_in_base(array, message));
      send_command_on_strand(session, *robot, std::move(command), message.seq());
    });
  });
}

}  // namespace occgeo::service
