#include <boost/asio/post.hpp>
#include <cmath>

#include "../validation.h"
#include "handlers.h"

namespace occgeo::service {

namespace {

// Dead-reckons the robot's pose from the new counts unless the message is out of order; runs on
// the robot's world strand, so sensor messages after it are placed at the new pose.
void apply_on_strand(const SessionPtr& session, Robot& robot, const v1::WheelEncoders& message,
                     double max_abs_coordinate_m) {
  const RobotState before = robot.state();
  if (before.last_encoder_stamp_s && message.stamp_s() < *before.last_encoder_stamp_s) {
    session->send_error(v1::ERROR_OUT_OF_ORDER, "wheel_encoders.stamp_s",
                        "timestamp went backwards (the last wheel_encoders had " +
                            std::to_string(*before.last_encoder_stamp_s) + " s); the counts were ignored",
                        0, message.seq());
    return;
  }
  if (before.last_encoder_seq && message.seq() <= *before.last_encoder_seq) {
    session->send_error(v1::ERROR_OUT_OF_ORDER, "wheel_encoders.seq",
                        "sequence number did not increase (the last wheel_encoders had " +
                            std::to_string(*before.last_encoder_seq) + "); the counts were ignored",
                        0, message.seq());
    return;
  }
  auto& odometry = robot.encoder_odometry_on_strand();
  // Updated on a copy so that counts driving the pose off any map leave the dead reckoning as it was.
  geometry::EncoderOdometry next = *odometry;
  const geometry::Pose2 X_WB = next.update({message.left_ticks(), message.right_ticks(), message.stamp_s()});
  if (!(std::abs(X_WB.x) <= max_abs_coordinate_m && std::abs(X_WB.y) <= max_abs_coordinate_m)) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "wheel_encoders",
                        "these counts would dead-reckon the robot to (" + std::to_string(X_WB.x) + ", " +
                            std::to_string(X_WB.y) + "), beyond ±" + std::to_string(max_abs_coordinate_m) +
                            " m; the counts were ignored",
                        0, message.seq());
    return;
  }
  *odometry = next;
  robot.update_state([&](RobotState& state) {
    state.last_encoder_stamp_s = message.stamp_s();
    state.last_encoder_seq = message.seq();
    state.X_WB = X_WB;
  });
}

}  // namespace

void handle_wheel_encoders(const SessionPtr& session, const v1::WheelEncoders& message) {
  auto robot = session->info().robot;
  if (auto error = check_wheel_encoders(message, robot->model())) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, error->field, error->message, 0, message.seq());
    return;
  }
  const double max_abs_coordinate_m = session->core().config().limits.max_abs_coordinate_m;
  asio::post(robot->world().strand(), [session, robot, message, max_abs_coordinate_m] {
    run_guarded(session, "wheel_encoders", 0, [&] { apply_on_strand(session, *robot, message, max_abs_coordinate_m); });
  });
}

}  // namespace occgeo::service
