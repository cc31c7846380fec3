// Who may talk to the server and what each role may send: per-role tokens in the hello, throttled
// failures, the refusal to listen beyond loopback without tokens, TLS, and the role x message table.
#include <google/protobuf/descriptor.h>
#include <google/protobuf/reflection.h>
#include <gtest/gtest.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/asio/write.hpp>
#include <fstream>
#include <map>
#include <set>
#include <thread>

#include "occgeo/proto/framing.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/service/config.h"
#include "process.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

using namespace std::chrono_literals;

struct RoleToken {
  v1::Role role;
  const char* token;
};

constexpr const char* kOperatorToken = "operator-7f3a";
const std::vector<RoleToken> kRoles = {{v1::ROLE_DRIVER, "driver-1b9c"},
                                       {v1::ROLE_CONTROLLER, "controller-44e0"},
                                       {v1::ROLE_OBSERVER, "observer-a2d7"},
                                       {v1::ROLE_QUERY, "query-5c61"}};

std::string token_config(std::size_t max_failures, double window_s) {
  std::string yaml = "auth:\n  operator_token: " + std::string(kOperatorToken) + "\n";
  yaml += "  driver_token: driver-1b9c\n  controller_token: controller-44e0\n";
  yaml += "  observer_token: observer-a2d7\n  query_token: query-5c61\n";
  yaml +=
      "  max_failures: " + std::to_string(max_failures) + "\n  failure_window_s: " + std::to_string(window_s) + "\n";
  return yaml;
}

std::unique_ptr<ServerProcess> start_server(const TempDir& dir, const std::string& yaml) {
  const auto config = dir.path() / "occgeod.yaml";
  std::ofstream(config) << yaml;
  return std::make_unique<ServerProcess>(dir.path(), std::vector<std::string>{"--config", config.string()});
}

v1::Hello make_hello(v1::Role role, const std::string& token, const std::string& robot_id = "") {
  v1::Hello hello;
  hello.set_protocol_version(proto::kProtocolVersion);
  hello.set_role(role);
  hello.set_auth_token(token);
  hello.set_client_name("security-test");
  if (role == v1::ROLE_DRIVER) hello.set_robot_id(robot_id.empty() ? "sec-robot" : robot_id);
  return hello;
}

// The hello's outcome: "" when welcomed, else the client's error text.
std::string try_hello(const std::string& address, const v1::Hello& hello) {
  auto connection = client::Connection::open(client::Endpoint::parse(address));
  try {
    connection.hello(hello);
    return "";
  } catch (const client::ClientError& e) {
    return e.what();
  }
}

// A refused hello leaves nothing but a closed connection: no other message is answered.
bool refused_and_closed(const std::string& address, const v1::Hello& hello, std::string* error_text) {
  auto connection = client::Connection::open(client::Endpoint::parse(address));
  try {
    connection.hello(hello);
    *error_text = "welcomed";
    return false;
  } catch (const client::ClientError& e) {
    *error_text = e.what();
  }
  v1::ClientMessage status;
  status.mutable_status();
  status.set_request_id(1);
  try {
    connection.send(status);
    for (int i = 0; i < 50; ++i) {
      if (connection.receive(100ms)) return false;  // answered: the session is still open
    }
  } catch (const client::ClientError&) {
    return true;  // closed by the server
  }
  return false;
}

TEST(Security, EachRoleNeedsItsOwnTokenOrTheOperatorsAndRefusalsSayNothingMore) {
  TempDir dir;
  auto server = start_server(dir, token_config(1000, 60.0));
  int robot = 0;
  for (const auto& [role, token] : kRoles) {
    SCOPED_TRACE(v1::Role_Name(role));
    const std::string robot_id = "sec-robot-" + std::to_string(robot++);
    EXPECT_EQ(try_hello(server->address(), make_hello(role, token, robot_id)), "");
    EXPECT_EQ(try_hello(server->address(), make_hello(role, kOperatorToken, robot_id + "-op")), "");
    std::vector<std::string> wrong = {"", "nonsense", std::string(token) + "x", std::string(token).substr(1)};
    for (const auto& other : kRoles) {
      if (other.role != role) wrong.emplace_back(other.token);
    }
    std::set<std::string> refusals;
    for (const auto& bad : wrong) {
      std::string error;
      EXPECT_TRUE(refused_and_closed(server->address(), make_hello(role, bad, robot_id + "-bad"), &error))
          << "token '" << bad << "': " << error;
      EXPECT_NE(error.find("ERROR_UNAUTHENTICATED"), std::string::npos) << error;
      refusals.insert(error);
    }
    // Every wrong token (missing, near miss, another role's) gets the very same words.
    EXPECT_EQ(refusals.size(), 1U);
    EXPECT_EQ(refusals.begin()->find("token"), std::string::npos) << *refusals.begin();
  }
  // A robot id is not revealed to an unauthenticated driver: the refusal for a connected robot is the same.
  auto driver = client::Connection::open(client::Endpoint::parse(server->address()));
  driver.hello(make_hello(v1::ROLE_DRIVER, "driver-1b9c", "connected-robot"));
  std::string error;
  EXPECT_TRUE(refused_and_closed(server->address(), make_hello(v1::ROLE_DRIVER, "bad", "connected-robot"), &error));
  EXPECT_NE(error.find("ERROR_UNAUTHENTICATED hello: authentication failed"), std::string::npos) << error;
}

TEST(Security, RepeatedFailuresFromOneAddressAreRefusedUncheckedUntilTheWindowPasses) {
  TempDir dir;
  auto server = start_server(dir, token_config(3, 1.5));
  for (int i = 0; i < 3; ++i) {
    EXPECT_NE(try_hello(server->address(), make_hello(v1::ROLE_QUERY, "guess-" + std::to_string(i))), "");
  }
  // The right token is refused now: guessing gains nothing.
  const auto throttled_at = std::chrono::steady_clock::now();
  EXPECT_NE(try_hello(server->address(), make_hello(v1::ROLE_QUERY, "query-5c61")), "");
  EXPECT_NE(try_hello(server->address(), make_hello(v1::ROLE_CONTROLLER, "controller-44e0")), "");
  EXPECT_NE(server->log().find("\"throttled\":true"), std::string::npos);
  std::this_thread::sleep_until(throttled_at + 1600ms);
  EXPECT_EQ(try_hello(server->address(), make_hello(v1::ROLE_QUERY, "query-5c61")), "");
}

// What a role may send, by ClientMessage field; every other role gets ERROR_NOT_ALLOWED naming the message.
const std::map<std::string, std::set<v1::Role>>& allowed_roles() {
  static const std::set<v1::Role> all = {v1::ROLE_DRIVER, v1::ROLE_CONTROLLER, v1::ROLE_OBSERVER, v1::ROLE_QUERY};
  static const std::map<std::string, std::set<v1::Role>> table = {
      {"robot_spec", {v1::ROLE_DRIVER}},
      {"odometry", {v1::ROLE_DRIVER}},
      {"laser_scan", {v1::ROLE_DRIVER}},
      {"range_array", {v1::ROLE_DRIVER}},
      {"servo_range", {v1::ROLE_DRIVER}},
      {"wheel_encoders", {v1::ROLE_DRIVER}},
      {"point_cloud", {v1::ROLE_DRIVER}},
      {"collision", all},
      {"clearance", all},
      {"status", all},
      {"grid", all},
      {"ptem", all},
      {"octree", all},
      {"collision_batch", all},
      {"clearance_batch", all},
      {"raycast", all},
      {"occupancy", all},
      {"swept", all},
      {"grid_window", all},
      {"octree_window", all},
      {"lease", {v1::ROLE_CONTROLLER}},
      {"drive", {v1::ROLE_CONTROLLER}},
      {"estop", {v1::ROLE_DRIVER, v1::ROLE_CONTROLLER, v1::ROLE_OBSERVER}},
      {"watch", {v1::ROLE_CONTROLLER, v1::ROLE_OBSERVER}},
  };
  return table;
}

// Sends one empty message of `field` then a status request, and reports whether the server refused the
// message for the session's role (ERROR_NOT_ALLOWED whose field is the message's name).
bool refused_for_role(client::Connection& connection, const google::protobuf::FieldDescriptor* field) {
  v1::ClientMessage message;
  message.GetReflection()->MutableMessage(&message, field);
  connection.send(message);
  constexpr std::uint64_t kMarker = 424242;
  v1::ClientMessage status;
  status.mutable_status();
  status.set_request_id(kMarker);
  connection.send(status);
  bool refused = false;
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (std::chrono::steady_clock::now() < deadline) {
    const auto reply = connection.receive(200ms);
    if (!reply) continue;
    if (reply->has_error() && reply->error().code() == v1::ERROR_NOT_ALLOWED &&
        reply->error().field() == field->name()) {
      refused = true;
    }
    if (client::reply_request_id(*reply) == kMarker) return refused;
  }
  ADD_FAILURE() << "no answer to the status request after " << field->name();
  return refused;
}

TEST(Security, EveryRoleAgainstEveryClientMessage) {
  TempDir dir;
  auto server = start_server(dir, token_config(1000, 60.0));
  const auto* oneof = v1::ClientMessage::descriptor()->FindOneofByName("body");
  ASSERT_NE(oneof, nullptr);
  int checked = 0;
  int robot = 0;
  for (const auto& [role, token] : kRoles) {
    for (int i = 0; i < oneof->field_count(); ++i) {
      const auto* field = oneof->field(i);
      if (field->name() == "hello") continue;
      SCOPED_TRACE(v1::Role_Name(role) + " sends " + field->name());
      const auto entry = allowed_roles().find(field->name());
      // A message kind missing from the table is a decision nobody has made yet.
      ASSERT_NE(entry, allowed_roles().end()) << "add '" << field->name() << "' to the role table";
      auto connection = client::Connection::open(client::Endpoint::parse(server->address()));
      connection.hello(make_hello(role, token, "matrix-" + std::to_string(robot++)));
      EXPECT_EQ(refused_for_role(connection, field), !entry->second.contains(role));
      ++checked;
    }
  }
  std::printf("role x message pairs checked: %d\n", checked);
}

TEST(Security, OnlyTheLeaseHoldingControllerDrivesAndOtherRolesAreRefusedEveryTime) {
  TempDir dir;
  auto server = start_server(dir, token_config(1000, 60.0));
  auto driver = client::Connection::open(client::Endpoint::parse(server->address()));
  driver.hello(make_hello(v1::ROLE_DRIVER, "driver-1b9c", "bot"));
  v1::ClientMessage spec;
  *spec.mutable_robot_spec() = bearcat_spec();
  driver.send(spec);

  std::vector<client::Connection> intruders;
  for (const v1::Role role : {v1::ROLE_DRIVER, v1::ROLE_OBSERVER, v1::ROLE_QUERY}) {
    const auto& token = std::find_if(kRoles.begin(), kRoles.end(), [&](const RoleToken& r) { return r.role == role; });
    intruders.push_back(client::Connection::open(client::Endpoint::parse(server->address())));
    intruders.back().hello(make_hello(role, token->token, "intruder"));
  }
  int refused = 0;
  int attempts = 0;
  std::uint64_t request_id = 1;
  for (int round = 0; round < 30; ++round) {
    for (auto& intruder : intruders) {
      for (const bool lease : {true, false}) {
        v1::ClientMessage message;
        const std::uint64_t id = request_id++;
        if (lease) {
          message.set_request_id(id);
          message.mutable_lease()->set_robot_id("bot");
          message.mutable_lease()->set_action(round % 2 == 0 ? v1::LeaseRequest::ACQUIRE : v1::LeaseRequest::TAKE);
        } else {
          message.set_request_id(id);
          message.mutable_drive()->set_robot_id("bot");
          message.mutable_drive()->set_behaviour(v1::BEHAVIOUR_TELEOP);
          message.mutable_drive()->set_linear_mps(0.5);
        }
        ++attempts;
        try {
          intruder.call(message, id, 5s);
        } catch (const client::ClientError& e) {
          if (std::string(e.what()).find("ERROR_NOT_ALLOWED") != std::string::npos) ++refused;
        }
      }
    }
  }
  EXPECT_EQ(refused, attempts);
  std::printf("drive attempts by drivers, observers and queries: %d, refused: %d\n", attempts, refused);

  // The robot was never leased to anyone: a controller acquires it at once.
  auto controller = client::Connection::open(client::Endpoint::parse(server->address()));
  controller.hello(make_hello(v1::ROLE_CONTROLLER, "controller-44e0"));
  v1::ClientMessage acquire;
  acquire.set_request_id(1);
  acquire.mutable_lease()->set_robot_id("bot");
  acquire.mutable_lease()->set_action(v1::LeaseRequest::ACQUIRE);
  const auto reply = controller.call(acquire, 1, 5s);
  EXPECT_TRUE(reply.lease().granted());
}

TEST(Security, ListeningBeyondLoopbackNeedsEveryToken) {
  TempDir dir;
  const auto result = run_process(
      {binary("service/occgeod").string(), "--listen", "0.0.0.0:0", "--data-dir", (dir.path() / "data").string()}, 20s);
  EXPECT_EQ(result.exit_code, 2) << result.err;
  for (const char* key : {"auth.driver_token", "auth.controller_token", "auth.observer_token", "auth.query_token",
                          "auth.operator_token"}) {
    EXPECT_NE(result.err.find(key), std::string::npos) << key << " not named in: " << result.err;
  }
  const auto partial = dir.path() / "partial.yaml";
  std::ofstream(partial) << "listen: 0.0.0.0:0\nauth:\n  driver_token: a\n  controller_token: b\n  query_token: c\n";
  const auto partial_result = run_process({binary("service/occgeod").string(), "--config", partial.string()}, 20s);
  EXPECT_EQ(partial_result.exit_code, 2) << partial_result.err;
  EXPECT_NE(partial_result.err.find("missing: auth.observer_token, auth.operator_token"), std::string::npos)
      << partial_result.err;
  EXPECT_EQ(partial_result.err.find("auth.driver_token"), std::string::npos) << partial_result.err;

  service::ServerConfig config;
  config.listen = "[::]:7700";
  EXPECT_THROW(config.validate(), service::ConfigError);
  config.auth = {kOperatorToken, "d", "c", "o", "q", 5, 60.0};
  EXPECT_NO_THROW(config.validate());
  config.listen = "localhost:7700";
  config.auth = {};
  EXPECT_NO_THROW(config.validate());
}

// A TLS client of its own (Asio SSL): connects, checks the server's certificate, and speaks frames.
class TlsClient {
 public:
  TlsClient(std::uint16_t port, const std::filesystem::path& ca_file)
      : context_(boost::asio::ssl::context::tls_client) {
    context_.load_verify_file(ca_file.string());
    stream_ = std::make_unique<boost::asio::ssl::stream<boost::asio::ip::tcp::socket>>(io_, context_);
    stream_->set_verify_mode(boost::asio::ssl::verify_peer);
    stream_->set_verify_callback(boost::asio::ssl::host_name_verification("localhost"));
    stream_->next_layer().connect({boost::asio::ip::make_address("127.0.0.1"), port});
    stream_->handshake(boost::asio::ssl::stream_base::client);
  }
  void send(const v1::ClientMessage& message) {
    boost::asio::write(*stream_, boost::asio::buffer(proto::encode_frame(message)));
  }
  v1::ServerMessage receive() {
    v1::ServerMessage message;
    while (decoder_.next(message) != proto::FrameStatus::frame) {
      std::array<char, 4096> buffer{};
      const std::size_t size = stream_->read_some(boost::asio::buffer(buffer));
      decoder_.append(buffer.data(), size);
    }
    return message;
  }

 private:
  boost::asio::io_context io_;
  boost::asio::ssl::context context_;
  std::unique_ptr<boost::asio::ssl::stream<boost::asio::ip::tcp::socket>> stream_;
  proto::FrameDecoder decoder_{std::size_t{64} << 20};
};

TEST(Security, TlsWithASelfSignedCertificate) {
  TempDir dir;
  const auto cert = dir.path() / "cert.pem";
  const auto key = dir.path() / "key.pem";
  const auto made = run_process(
      {"/usr/bin/openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj", "/CN=localhost",
       "-addext", "subjectAltName=DNS:localhost,IP:127.0.0.1", "-keyout", key.string(), "-out", cert.string()},
      60s);
  ASSERT_EQ(made.exit_code, 0) << made.err;
  auto server = start_server(
      dir, token_config(1000, 60.0) + "tls:\n  cert: " + cert.string() + "\n  key: " + key.string() + "\n");

  TlsClient tls(server->port(), cert);
  v1::ClientMessage hello;
  *hello.mutable_hello() = make_hello(v1::ROLE_QUERY, "query-5c61");
  tls.send(hello);
  const auto welcome = tls.receive();
  ASSERT_TRUE(welcome.has_welcome()) << welcome.DebugString();
  v1::ClientMessage status;
  status.mutable_status();
  status.set_request_id(7);
  tls.send(status);
  const auto reply = tls.receive();
  ASSERT_TRUE(reply.has_status()) << reply.DebugString();
  EXPECT_EQ(reply.request_id(), 7U);

  // Plain TCP to the TLS socket gets no session: the handshake fails and the server closes.
  EXPECT_NE(try_hello(server->address(), make_hello(v1::ROLE_QUERY, "query-5c61")), "");
  EXPECT_TRUE(server->running());
  EXPECT_NE(server->log().find("session_tls_failed"), std::string::npos);

  // A key that does not exist stops the start with the key named.
  const auto broken = dir.path() / "broken.yaml";
  std::ofstream(broken) << "tls:\n  cert: " << cert.string() << "\n  key: " << (dir.path() / "missing.pem").string()
                        << "\n";
  const auto result = run_process({binary("service/occgeod").string(), "--config", broken.string(), "--listen",
                                   "127.0.0.1:0", "--data-dir", (dir.path() / "data2").string()},
                                  20s);
  EXPECT_EQ(result.exit_code, 2) << result.err;
  EXPECT_NE(result.err.find("tls.key"), std::string::npos) << result.err;
}

}  // namespace
}  // namespace occgeo::testing
