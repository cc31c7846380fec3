#include <algorithm>
#include <string_view>
#include <utility>
#include <vector>

#include "../metrics.h"
#include "handlers.h"
#include "occgeo/service/log.h"
#include "robot_control.h"

namespace occgeo::service {

void SessionContext::send_error(v1::ErrorCode code, const std::string& field, const std::string& message,
                                std::uint64_t request_id, std::uint64_t seq) {
  v1::ServerMessage reply;
  auto* error = reply.mutable_error();
  error->set_code(code);
  error->set_field(field);
  error->set_message(message);
  reply.set_request_id(request_id);
  error->set_seq(seq);
  send(reply);
}

void SessionContext::watch(std::uint64_t request_id, const v1::WatchRequest& /*request*/) {
  send_error(v1::ERROR_NOT_ALLOWED, "watch", "this session cannot receive watch events", request_id);
}

bool is_request(v1::ClientMessage::BodyCase body) {
  switch (body) {
    case v1::ClientMessage::kCollision:
    case v1::ClientMessage::kClearance:
    case v1::ClientMessage::kStatus:
    case v1::ClientMessage::kGrid:
    case v1::ClientMessage::kPtem:
    case v1::ClientMessage::kOctree:
    case v1::ClientMessage::kCollisionBatch:
    case v1::ClientMessage::kClearanceBatch:
    case v1::ClientMessage::kRaycast:
    case v1::ClientMessage::kOccupancy:
    case v1::ClientMessage::kSwept:
    case v1::ClientMessage::kGridWindow:
    case v1::ClientMessage::kOctreeWindow:
      return true;
    default:
      return false;
  }
}

bool is_answer(v1::ServerMessage::BodyCase body) {
  switch (body) {
    case v1::ServerMessage::kCollision:
    case v1::ServerMessage::kClearance:
    case v1::ServerMessage::kStatus:
    case v1::ServerMessage::kGrid:
    case v1::ServerMessage::kPtem:
    case v1::ServerMessage::kOctree:
    case v1::ServerMessage::kCollisionBatch:
    case v1::ServerMessage::kClearanceBatch:
    case v1::ServerMessage::kRaycast:
    case v1::ServerMessage::kOccupancy:
    case v1::ServerMessage::kSwept:
    case v1::ServerMessage::kGridWindow:
    case v1::ServerMessage::kOctreeWindow:
    case v1::ServerMessage::kError:
      return true;
    default:
      return false;
  }
}

namespace {

// Everything run here that is not a sensor or odometry message is a query.
bool is_sensor_work(std::string_view what) {
  return what == "laser_scan" || what == "range_array" || what == "servo_range" || what == "point_cloud" ||
         what == "odometry" || what == "wheel_encoders";
}

// The ClientMessage body's field numbers by name, sorted by name: built once, so that timing a query costs a binary
// search rather than a string made and looked up in the descriptor's tables every time.
const std::vector<std::pair<std::string_view, int>>& body_field_numbers() {
  static const std::vector<std::pair<std::string_view, int>> numbers = [] {
    std::vector<std::pair<std::string_view, int>> all;
    const auto* descriptor = v1::ClientMessage::descriptor();
    all.reserve(static_cast<std::size_t>(descriptor->field_count()));
    for (int i = 0; i < descriptor->field_count(); ++i) {
      all.emplace_back(descriptor->field(i)->name(), descriptor->field(i)->number());
    }
    std::sort(all.begin(), all.end());
    return all;
  }();
  return numbers;
}

// occgeo_query_duration_seconds of one kind, named as the ClientMessage body's field.
metrics::Histogram& query_histogram(ServerCore& core, std::string_view what) {
  const auto& numbers = body_field_numbers();
  const auto found = std::ranges::lower_bound(numbers, what, {}, &std::pair<std::string_view, int>::first);
  const bool known = found != numbers.end() && found->first == what;
  return core.query_durations().at(known ? static_cast<std::size_t>(found->second) : ServerCore::kBodyFieldCount, what);
}

}  // namespace

void run_guarded(const SessionPtr& session, std::string_view what, std::uint64_t request_id,
                 const std::function<void()>& work) {
  try {
    std::optional<metrics::ScopedTimer> timer;
    if (!is_sensor_work(what)) timer.emplace(query_histogram(session->core(), what));
    work();
  } catch (const std::exception& e) {
    log::error("handler_failed", {{"handler", what}, {"error", e.what()}});
    session->send_error(v1::ERROR_INTERNAL, std::string(what),
                        std::string("the server could not complete this: ") + e.what(), request_id);
  }
}

namespace {
bool require_driver_with_spec(const SessionPtr& session, const char* field) {
  const SessionInfo& info = session->info();
  if (info.role != v1::ROLE_DRIVER) {
    session->send_error(v1::ERROR_NOT_ALLOWED, field, "only driver sessions may send robot data");
    return false;
  }
  if (!info.robot) {
    session->send_error(v1::ERROR_OUT_OF_ORDER, field, "send the robot_spec before any sensor data");
    return false;
  }
  return true;
}

// Leases and behaviours are for controllers only: observers, queries and drivers never drive.
bool require_controller(const SessionPtr& session, const char* field, std::uint64_t request_id) {
  const v1::Role role = session->info().role;
  if (role == v1::ROLE_CONTROLLER) return true;
  session->send_error(
      v1::ERROR_NOT_ALLOWED, field,
      std::string("only ROLE_CONTROLLER sessions may send ") + field + "; this session is " + v1::Role_Name(role),
      request_id);
  return false;
}
}  // namespace

void dispatch_message(const SessionPtr& session, v1::ClientMessage& message) {
  if (message.body_case() == v1::ClientMessage::BODY_NOT_SET) {
    session->send_error(v1::ERROR_UNKNOWN_MESSAGE, "",
                        "the message has no body this server knows (protocol occgeo.v1); it was ignored",
                        message.request_id());
    return;
  }
  if (message.has_hello()) {
    handle_hello(session, message.hello());
    return;
  }
  if (!session->info().greeted) {
    session->send_error(v1::ERROR_OUT_OF_ORDER, "hello", "the first message of a session must be a hello",
                        message.request_id());
    return;
  }
  if (is_request(message.body_case())) {
    const int body_case = message.body_case();
    session->core()
        .query_counts()
        .at(static_cast<std::size_t>(body_case), v1::ClientMessage::descriptor()->FindFieldByNumber(body_case)->name())
        .inc();
  }
  switch (message.body_case()) {
    case v1::ClientMessage::kRobotSpec:
      if (session->info().role != v1::ROLE_DRIVER) {
        session->send_error(v1::ERROR_NOT_ALLOWED, "robot_spec", "only driver sessions may send a robot_spec");
        return;
      }
      handle_robot_spec(session, message.robot_spec());
      return;
    case v1::ClientMessage::kOdometry:
      if (require_driver_with_spec(session, "odometry")) handle_odometry(session, message.odometry());
      return;
    case v1::ClientMessage::kLaserScan:
      if (require_driver_with_spec(session, "laser_scan")) {
        handle_laser_scan(session, std::move(*message.mutable_laser_scan()));
      }
      return;
    case v1::ClientMessage::kRangeArray:
      if (require_driver_with_spec(session, "range_array")) {
        handle_range_array(session, std::move(*message.mutable_range_array()));
      }
      return;
    case v1::ClientMessage::kServoRange:
      if (require_driver_with_spec(session, "servo_range")) {
        handle_servo_range(session, std::move(*message.mutable_servo_range()));
      }
      return;
    case v1::ClientMessage::kWheelEncoders:
      if (require_driver_with_spec(session, "wheel_encoders")) handle_wheel_encoders(session, message.wheel_encoders());
      return;
    case v1::ClientMessage::kPointCloud:
      if (require_driver_with_spec(session, "point_cloud")) {
        handle_point_cloud(session, std::move(*message.mutable_point_cloud()));
      }
      return;
    case v1::ClientMessage::kCollision:
      handle_collision_query(session, message.request_id(), message.collision());
      return;
    case v1::ClientMessage::kClearance:
      handle_clearance_query(session, message.request_id(), message.clearance());
      return;
    case v1::ClientMessage::kCollisionBatch:
      handle_collision_batch(session, message.request_id(), message.collision_batch());
      return;
    case v1::ClientMessage::kClearanceBatch:
      handle_clearance_batch(session, message.request_id(), message.clearance_batch());
      return;
    case v1::ClientMessage::kRaycast:
      handle_raycast_query(session, message.request_id(), message.raycast());
      return;
    case v1::ClientMessage::kOccupancy:
      handle_occupancy_query(session, message.request_id(), message.occupancy());
      return;
    case v1::ClientMessage::kSwept:
      handle_swept_query(session, message.request_id(), message.swept());
      return;
    case v1::ClientMessage::kGridWindow:
      handle_grid_window(session, message.request_id(), message.grid_window());
      return;
    case v1::ClientMessage::kOctreeWindow:
      handle_octree_window(session, message.request_id(), message.octree_window());
      return;
    case v1::ClientMessage::kStatus:
      handle_status_request(session, message.request_id(), message.status());
      return;
    case v1::ClientMessage::kGrid:
      handle_grid_request(session, message.request_id(), message.grid());
      return;
    case v1::ClientMessage::kPtem:
      handle_ptem_query(session, message.request_id(), message.ptem());
      return;
    case v1::ClientMessage::kOctree:
      handle_octree_request(session, message.request_id(), message.octree());
      return;
    case v1::ClientMessage::kLease:
      if (require_controller(session, "lease", message.request_id())) {
        handle_lease_request(session, message.request_id(), message.lease());
      }
      return;
    case v1::ClientMessage::kDrive:
      if (require_controller(session, "drive", message.request_id())) {
        handle_drive_request(session, message.request_id(), message.drive());
      }
      return;
    case v1::ClientMessage::kEstop:
      if (session->info().role == v1::ROLE_QUERY) {
        session->send_error(v1::ERROR_NOT_ALLOWED, "estop",
                            "query sessions may not send estop; connect as a driver, controller or observer",
                            message.request_id());
        return;
      }
      handle_estop(session, message.request_id(), message.estop());
      return;
    case v1::ClientMessage::kWatch:
      if (session->info().role != v1::ROLE_OBSERVER && session->info().role != v1::ROLE_CONTROLLER) {
        session->send_error(v1::ERROR_NOT_ALLOWED, "watch",
                            "only ROLE_OBSERVER and ROLE_CONTROLLER sessions may watch; this session is " +
                                v1::Role_Name(session->info().role),
                            message.request_id());
        return;
      }
      session->watch(message.request_id(), message.watch());
      return;
    default:
      session->send_error(v1::ERROR_UNKNOWN_MESSAGE, "", "unhandled message", message.request_id());
  }
}

void handle_disconnect(ServerCore& core, SessionInfo& info) {
  release_session_control(core, info);
  if (info.robot) {
    info.robot->update_state([](RobotState& state) { state.connected = false; });
    log::info("robot_disconnected", {{"robot", info.robot_id}, {"session", info.id}});
  }
}

}  // namespace occgeo::service
