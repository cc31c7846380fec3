#include "../validation.h"
#include "handlers.h"
#include "occgeo/service/log.h"
#include "robot_control.h"

namespace occgeo::service {

namespace {
constexpr std::uint32_t kProtocolVersion = 1;
constexpr const char* kServerVersion = "occgeod 0.1.0";
}  // namespace

void handle_hello(const SessionPtr& session, const v1::Hello& hello) {
  SessionInfo& info = session->info();
  if (info.greeted) {
    session->send_error(v1::ERROR_OUT_OF_ORDER, "hello", "the session has already said hello");
    return;
  }
  if (hello.protocol_version() != kProtocolVersion) {
    session->send_error(v1::ERROR_PROTOCOL_VERSION, "hello.protocol_version",
                        "this server speaks protocol version " + std::to_string(kProtocolVersion) + ", not " +
                            std::to_string(hello.protocol_version()));
    return;
  }
  switch (hello.role()) {
    case v1::ROLE_DRIVER: {
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
  session->send(std::move(reply));
  log::info("session_hello", {{"session", info.id},
                              {"role", v1::Role_Name(hello.role())},
                              {"robot", info.robot_id},
                              {"client", info.client_name},
                              {"operator", info.is_operator}});
}

}  // namespace occgeo::service
