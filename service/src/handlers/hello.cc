#include "../secret_compare.h"
#include "../validation.h"
#include "handlers.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/service/log.h"
#include "robot_control.h"

namespace occgeo::service {

namespace {
using proto::kProtocolVersion;
constexpr const char* kServerVersion = "occgeod 0.1.0";

// The token a role must present; empty leaves the role open.
const std::string& role_token(const AuthConfig& auth, v1::Role role) {
  switch (role) {
    case v1::ROLE_DRIVER:
      return auth.driver_token;
    case v1::ROLE_CONTROLLER:
      return auth.controller_token;
    case v1::ROLE_OBSERVER:
      return auth.observer_token;
    default:
      return auth.query_token;
  }
}

// Checks the hello's token against its role's (the operator token passes for every role). A refusal says
// nothing about what was wrong, counts against the peer's address, and closes the connection.
bool authenticate(const SessionPtr& session, const v1::Hello& hello) {
  const AuthConfig& auth = session->core().config().auth;
  const std::string& required = role_token(auth, hello.role());
  if (required.empty()) return true;
  SessionInfo& info = session->info();
  HelloThrottle* throttle = session->hello_throttle();
  const auto now = HelloThrottle::Clock::now();
  const bool throttled =
      throttle != nullptr && !throttle->allowed(info.peer_address, auth.max_failures, auth.failure_window_s, now);
  // Both comparisons always run, so the time taken does not tell which token was close.
  const bool role_ok = constant_time_equal(hello.auth_token(), required);
  const bool operator_ok = !auth.operator_token.empty() && constant_time_equal(hello.auth_token(), auth.operator_token);
  if (!throttled && (role_ok || operator_ok)) return true;
  if (throttle != nullptr && !throttled) throttle->record_failure(info.peer_address, auth.failure_window_s, now);
  log::warn(
      "session_unauthenticated",
      {{"session", info.id}, {"peer", info.peer}, {"role", v1::Role_Name(hello.role())}, {"throttled", throttled}});
  session->send_error(v1::ERROR_UNAUTHENTICATED, "hello", "authentication failed; closing the connection");
  session->close_after_send();
  return false;
}
}  // namespace

bool HelloThrottle::allowed(const std::string& address, std::size_t max_failures, double window_s,
                            Clock::time_point now) {
  const std::lock_guard lock(mutex_);
  const auto it = failures_.find(address);
  if (it == failures_.end()) return true;
  const auto window = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(window_s));
  while (!it->second.empty() && it->second.front() + window <= now) it->second.pop_front();
  if (it->second.empty()) {
    failures_.erase(it);
    return true;
  }
  return it->second.size() < max_failures;
}

void HelloThrottle::record_failure(const std::string& address, double window_s, Clock::time_point now) {
  const std::lock_guard lock(mutex_);
  // Bounded memory under a flood from many addresses: forget addresses whose failures have all expired.
  if (failures_.size() > 4096) {
    const auto window = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(window_s));
    std::erase_if(failures_, [&](const auto& entry) { return entry.second.back() + window <= now; });
  }
  auto& times = failures_[address];
  times.push_back(now);
  if (times.size() > 1024) times.pop_front();
}

void handle_hello(const SessionPtr& session, const v1::Hello& hello) {
  SessionInfo& info = session->info();
  if (info.greeted) {
    session->send_error(v1::ERROR_OUT_OF_ORDER, "hello", "the session has already said hello");
    return;
  }
  if (hello.protocol_version() != kProtocolVersion) {
    session->send_error(v1::ERROR_PROTOCOL_VERSION, "hello.protocol_version",
                        "this server speaks protocol version " + std::to_string(kProtocolVersion) + ", not " +
                            std::to_string(hello.protocol_version()) +
                            " (version 2 carried request_id on the message envelope, version 3 also names behaviours "
                            "and their states by the Behaviour and BehaviourState enums); upgrade the client");
    return;
  }
  switch (hello.role()) {
    case v1::ROLE_DRIVER: {
      if (!authenticate(session, hello)) return;
      if (!valid_name(hello.robot_id())) {
        session->send_error(v1::ERROR_INVALID_ARGUMENT, "hello.robot_id",
                            "a driver must name its robot: 1-64 characters of A-Z a-z 0-9 _ . -");
        return;
      }
      const std::string world = hello.world().empty() ? session->core().config().default_world : hello.world();
      if (!valid_name(world)) {
        session->send_error(v1::ERROR_INVALID_ARGUMENT, "hello.world",
                            "a world name is 1-64 characters of A-Z a-z 0-9 _ . -");
        return;
      }
      if (const auto existing = session->core().find_robot(hello.robot_id()); existing && existing->state().connected) {
        session->send_error(v1::ERROR_NOT_ALLOWED, "hello.robot_id",
                            "robot '" + hello.robot_id() + "' already has a driver connected");
        return;
      }
      info.robot_id = hello.robot_id();
      info.world = world;
      break;
    }
    case v1::ROLE_QUERY:
    case v1::ROLE_CONTROLLER:
    case v1::ROLE_OBSERVER:
      if (!authenticate(session, hello)) return;
      break;
    default:
      session->send_error(v1::ERROR_INVALID_ARGUMENT, "hello.role",
                          "must be ROLE_DRIVER, ROLE_CONTROLLER, ROLE_OBSERVER or ROLE_QUERY");
      return;
  }
  info.greeted = true;
  info.role = hello.role();
  info.client_name = hello.client_name().substr(0, 128);
  const std::string& operator_token = session->core().config().auth.operator_token;
  info.is_operator = !operator_token.empty() && constant_time_equal(hello.auth_token(), operator_token);
  v1::ServerMessage reply;
  auto* welcome = reply.mutable_welcome();
  welcome->set_protocol_version(kProtocolVersion);
  welcome->set_server_version(kServerVersion);
  welcome->set_session_id(info.id);
  session->send(reply);
  log::info("session_hello", {{"session", info.id},
                              {"role", v1::Role_Name(hello.role())},
                              {"robot", info.robot_id},
                              {"client", info.client_name},
                              {"operator", info.is_operator}});
}

}  // namespace occgeo::service
