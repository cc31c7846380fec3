#include <boost/asio/post.hpp>

#include "../ingest/model_ingest.h"
#include "robot_control.h"
#include "sensor_ingest.h"

namespace occgeo::service {

void handle_servo_range(const SessionPtr& session, v1::ServoRange message) {
  auto robot = session->info().robot;
  if (auto error = check_servo_range(message, robot->model())) {
    reject_sensor_message(session, *robot, *error, message.seq());
    return;
  }
  asio::post(robot->world().strand(), [session, robot, message = std::move(message)] {
    run_guarded(session, "servo_range", 0, [&] {
      const RobotModel& model = robot->model();
      const ServoRangeModel& servo = *model.find_servo_range(message.sensor());
      WorkAfterCommand after_command(robot->world());
      const bool accepted = ingest_sensor_message_on_strand(
          session, *robot, {"servo_range", message.seq(), message.stamp_s(), &message},
          [&](const geometry::Pose2& X_WB, IngestTarget& target) { insert_servo_range(target, X_WB, servo, message); },
          &after_command);
      // A robot whose only range sensor is a servo-swept beam steers by its first one: every reading is answered with
      // a command once the robot is meant to be steered (its spec names a default behaviour, or a lease holder set
      // one), as for a range array.
      if (!accepted || !model.lasers.empty() || !model.range_arrays.empty() || &servo != &model.servo_ranges.front()) {
        return;
      }
      if (model.spec.default_behaviour() == v1::BEHAVIOUR_UNSPECIFIED && robot->control().state().drive_generation == 0)
        return;
      const ServerConfig& config = session->core().config();
      v1::MotionCommand command = command_for_scan_on_strand(
          *robot, control::ScanView{}, message.stamp_s(), config.control.command_expiry_s, config, std::nullopt,
          control::ServoSample{message.servo_angle_rad(), static_cast<double>(message.range_m()), message.stamp_s()});
      send_command_on_strand(session, *robot, std::move(command), message.seq());
    });
  });
}

}  // namespace occgeo::service
