#include <boost/asio/post.hpp>

#include "../validation.h"
#include "handlers.h"

namespace occgeo::service {

namespace {

// Accepts the pose unless its timestamp goes backwards; runs on the robot's world strand.
void apply_on_strand(const SessionPtr& session, Robot& robot, const v1::Odometry& odometry) {
  bool went_backwards = false;
  robot.update_state([&](RobotState& state) {
    if (state.last_odometry_stamp_s && odometry.stamp_s() < *state.last_odometry_stamp_s) {
      went_backwards = true;
      return;
    }
    state.last_odometry_stamp_s = odometry.stamp_s();
    state.X_WB =
        geometry::Pose2{odometry.pose().x(), odometry.pose().y(), geometry::wrap_angle(odometry.pose().theta())};
  });
  if (went_backwards) {
    session->send_error(v1::ERROR_OUT_OF_ORDER, "odometry.stamp_s", "timestamp went backwards; odometry ignored", 0,
                        odometry.seq());
    return;
  }
  // For a robot that dead-reckons from wheel encoders, odometry is a correction (e.g. from a
  // localiser): dead reckoning goes on from this pose, the next counts only setting a reference.
  if (auto& encoder_odometry = robot.encoder_odometry_on_strand()) {
    encoder_odometry->reset(
        geometry::Pose2{odometry.pose().x(), odometry.pose().y(), geometry::wrap_angle(odometry.pose().theta())});
  }
  if (session->data_watched()) {
    auto event = std::make_shared<v1::WatchEvent>();
    event->set_seq(odometry.seq());
    *event->mutable_odometry() = odometry;
    session->publish_data(std::move(event));
  }
}

}  // namespace

void handle_odometry(const SessionPtr& session, const v1::Odometry& odometry) {
  if (auto error = check_odometry(odometry, session->core().config().limits)) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, error->field, error->message, 0, odometry.seq());
    return;
  }
  // Ordering checks and the pose update run on the world's strand, in arrival order with scans.
  auto robot = session->info().robot;
  asio::post(robot->world().strand(), [session, robot, odometry] {
    run_guarded(session, "odometry", 0, [&] { apply_on_strand(session, *robot, odometry); });
  });
}

}  // namespace occgeo::service
