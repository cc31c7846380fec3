#pragma once

#include <chrono>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "../core.h"
#include "occgeo/v1/session.pb.h"

namespace occgeo::service {

// What a session knows about its peer; touched only by the session's network strand.
struct SessionInfo {
  std::uint64_t id = 0;
  std::string peer;
  std::string peer_address;  // the peer's IP address alone (hello throttling is per address)
  bool greeted = false;
  v1::Role role = v1::ROLE_UNSPECIFIED;
  std::string client_name;       // from the hello
  bool is_operator = false;      // the hello carried auth.operator_token (may TAKE leases)
  std::string robot_id;          // drivers
  std::string world;             // drivers
  std::shared_ptr<Robot> robot;  // drivers, once the RobotSpec is accepted
};

// Refused hellos per peer address: after auth.max_failures within auth.failure_window_s the address's
// further hellos are refused without looking at their token. Thread-safe.
class HelloThrottle {
 public:
  using Clock = std::chrono::steady_clock;
  // Whether `address` may try a hello now.
  bool allowed(const std::string& address, std::size_t max_failures, double window_s, Clock::time_point now);
  void record_failure(const std::string& address, double window_s, Clock::time_point now);

 private:
  std::mutex mutex_;
  std::map<std::string, std::deque<Clock::time_point>> failures_;
};

// The part of a session that message handlers use. send() may be called from any thread.
class SessionContext {
 public:
  virtual ~SessionContext() = default;
  virtual ServerCore& core() = 0;
  // Only from the session's own network strand.
  virtual SessionInfo& info() = 0;
  // Queues a message to the client (serialised before it returns, so the caller may reuse it); thread-safe, never
  // blocks.
  virtual void send(const v1::ServerMessage& message) = 0;

  void send_error(v1::ErrorCode code, const std::string& field, const std::string& message,
                  std::uint64_t request_id = 0, std::uint64_t seq = 0);

  // Closes the connection once what is queued has been written (a refused hello). Network strand only.
  virtual void close_after_send() {}
  // The server's hello throttle; nullptr where there is none (handler tests).
  virtual HelloThrottle* hello_throttle() { return nullptr; }
  // Subscribes this session to WatchEvents (role already checked). Network strand only.
  virtual void watch(std::uint64_t request_id, const v1::WatchRequest& request);
  // Observers that asked for data (WatchRequest.with_data): whether there are any (lock-free, any thread; the ingest
  // path builds an event only then), and handing one event of this driver's robot to those whose filter matches (world
  // and robot_id are filled in). Any thread; never waits for an observer.
  [[nodiscard]] virtual bool data_watched() const { return false; }
  virtual void publish_data(std::shared_ptr<v1::WatchEvent> /*event*/) {}
};

using SessionPtr = std::shared_ptr<SessionContext>;

// Runs work on a worker pool or strand; an exception escaping it is logged and reported to the
// client as ERROR_INTERNAL instead of taking the server down.
void run_guarded(const SessionPtr& session, std::string_view what, std::uint64_t request_id,
                 const std::function<void()>& work);

// Routes one decoded client message to its handler after the session checks (hello first,
// role allowed to send it). A request's handler gets the envelope's request_id and puts it on its answer. Sensor data
// may be moved out of `message`; nothing refers to it after the call.
void dispatch_message(const SessionPtr& session, v1::ClientMessage& message);
// The same for a message the caller gives away.
inline void dispatch(const SessionPtr& session, v1::ClientMessage message) { dispatch_message(session, message); }

// Client messages answered by exactly one reply or error: the queries, single and batch, map windows and whole-map
// requests. They are counted in occgeo_queries_total and against limits.max_pending_requests.
bool is_request(v1::ClientMessage::BodyCase body);
// Server messages that answer a request (an Error counts too: an error for something else only lets a few more
// requests through early; it never stalls a session).
bool is_answer(v1::ServerMessage::BodyCase body);

void handle_hello(const SessionPtr& session, const v1::Hello& hello);
void handle_robot_spec(const SessionPtr& session, const v1::RobotSpec& spec);
void handle_odometry(const SessionPtr& session, const v1::Odometry& odometry);
void handle_laser_scan(const SessionPtr& session, v1::LaserScan scan);
void handle_range_array(const SessionPtr& session, v1::RangeArray message);
void handle_servo_range(const SessionPtr& session, v1::ServoRange message);
void handle_wheel_encoders(const SessionPtr& session, const v1::WheelEncoders& message);
void handle_point_cloud(const SessionPtr& session, v1::PointCloud message);
void handle_collision_query(const SessionPtr& session, std::uint64_t request_id, const v1::CollisionQuery& query);
void handle_clearance_query(const SessionPtr& session, std::uint64_t request_id, const v1::ClearanceQuery& query);
void handle_collision_batch(const SessionPtr& session, std::uint64_t request_id, const v1::CollisionBatchQuery& query);
void handle_clearance_batch(const SessionPtr& session, std::uint64_t request_id, const v1::ClearanceBatchQuery& query);
void handle_raycast_query(const SessionPtr& session, std::uint64_t request_id, const v1::RaycastQuery& query);
void handle_occupancy_query(const SessionPtr& session, std::uint64_t request_id, const v1::OccupancyQuery& query);
void handle_swept_query(const SessionPtr& session, std::uint64_t request_id, const v1::SweptQuery& query);
void handle_grid_window(const SessionPtr& session, std::uint64_t request_id, const v1::GridWindowRequest& request);
void handle_octree_window(const SessionPtr& session, std::uint64_t request_id, const v1::OctreeWindowRequest& request);
void handle_status_request(const SessionPtr& session, std::uint64_t request_id, const v1::StatusRequest& request);
void handle_grid_request(const SessionPtr& session, std::uint64_t request_id, const v1::GridRequest& request);
void handle_ptem_query(const SessionPtr& session, std::uint64_t request_id, const v1::PtemQuery& query);
void handle_octree_request(const SessionPtr& session, std::uint64_t request_id, const v1::OctreeRequest& request);
void handle_lease_request(const SessionPtr& session, std::uint64_t request_id, const v1::LeaseRequest& request);
void handle_drive_request(const SessionPtr& session, std::uint64_t request_id, const v1::DriveRequest& request);
void handle_estop(const SessionPtr& session, std::uint64_t request_id, const v1::EStop& request);

// Called by the session when its connection ends (any thread-safe cleanup, e.g. robot offline, a
// controller's leases freed and their robots stopped).
void handle_disconnect(ServerCore& core, SessionInfo& info);

}  // namespace occgeo::service
