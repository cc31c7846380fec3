#include <boost/asio/post.hpp>

#include "../validation.h"
#include "handlers.h"
#include "occgeo/service/log.h"
#include "robot_control.h"

namespace occgeo::service {

void handle_robot_spec(const SessionPtr& session, const v1::RobotSpec& spec) {
  SessionInfo& info = session->info();
  if (info.robot) {
    session->send_error(v1::ERROR_OUT_OF_ORDER, "robot_spec", "the robot_spec was already sent on this session");
    return;
  }
  FieldError error;
  auto model = robot_model_from_spec(info.robot_id, spec, session->core().config().limits, error,
                                     session->core().config().sensors);
  if (!model) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, error.field, error.message);
    return;
  }
  std::string limit_error;
  auto robot = session->core().register_robot(model, info.world, limit_error);
  if (!robot) {
    session->send_error(v1::ERROR_NOT_ALLOWED, "robot_spec", limit_error);
    return;
  }
  robot->update_state([](RobotState& state) { state.connected = true; });
  robot->control().update([&](ControlState& c) {
    c.driver = session;
    c.last_sensor_at.reset();
    c.sensor_stale = false;
  });
  info.robot = std::move(robot);
  if (session->data_watched()) {
    // Published from the world's strand like every later data event of the robot, so it reaches watchers first.
    auto event = std::make_shared<v1::WatchEvent>();
    *event->mutable_robot_spec() = spec;
    asio::post(info.robot->world().strand(),
               [session, event = std::move(event)]() mutable { session->publish_data(std::move(event)); });
  }
  log::info(
      "robot_registered",
      {{"robot", info.robot_id}, {"world", info.world}, {"model", spec.model()}, {"sensors", spec.sensors_size()}});
}

}  // namespace occgeo::service
