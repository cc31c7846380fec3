// Control ownership and watchdogs over the wire, all on 127.0.0.1: the real occgeod with a driver
// stepping at 10 Hz, controllers and the occgeo CLI's lease, drive and estop commands; and the real
// occgeo-sim against a stand-in server that stops answering, to show the driver's own watchdog.
#include <gtest/gtest.h>

#include <atomic>
#include <boost/asio.hpp>
#include <csignal>
#include <fstream>
#include <functional>
#include <sstream>
#include <thread>

#include "../support/process.h"
#include "occgeo/proto/framing.h"
#include "occgeo/proto/protocol.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

using namespace std::chrono_literals;

client::Connection open_role(const std::string& address, v1::Role role, const std::string& name,
                             const std::string& token = {}) {
  auto connection = client::Connection::open(client::Endpoint::parse(address));
  v1::Hello hello;
  hello.set_protocol_version(proto::kProtocolVersion);
  hello.set_role(role);
  hello.set_client_name(name);
  hello.set_auth_token(token);
  connection.hello(hello);
  return connection;
}

v1::LeaseReply lease(client::Connection& c, v1::LeaseRequest::Action action, std::uint64_t id, double timeout_s = 0) {
  v1::ClientMessage m;
  m.set_request_id(id);
  m.mutable_lease()->set_robot_id("r1");
  m.mutable_lease()->set_action(action);
  m.mutable_lease()->set_timeout_s(timeout_s);
  return c.call(m, id).lease();
}

// Asks for teleop driving of r1 as request 2, answered by a Drive reply.
v1::ClientMessage teleop_drive(double linear_mps, double angular_radps = 0.0) {
  v1::ClientMessage drive;
  drive.set_request_id(2);
  drive.mutable_drive()->set_robot_id("r1");
  drive.mutable_drive()->set_behaviour(v1::BEHAVIOUR_TELEOP);
  drive.mutable_drive()->set_linear_mps(linear_mps);
  drive.mutable_drive()->set_angular_radps(angular_radps);
  return drive;
}

// A driver that sends odometry and a Bearcat laser scan (open space, every beam at 6 m) per step.
class SteppingDriver {
 public:
  explicit SteppingDriver(const std::string& address) : connection_(open_driver_session(address, "r1")) {}

  // Sends one scan and returns the command that answers it.
  v1::MotionCommand step() {
    ++seq_;
    v1::ClientMessage odometry;
    odometry.mutable_odometry()->set_seq(seq_);
    odometry.mutable_odometry()->set_stamp_s(0.1 * static_cast<double>(seq_));
    odometry.mutable_odometry()->mutable_pose();
    connection_.send(odometry);
    v1::ClientMessage scan;
    scan.mutable_laser_scan()->set_sensor("front_laser");
    scan.mutable_laser_scan()->set_seq(seq_);
    scan.mutable_laser_scan()->set_stamp_s(0.1 * static_cast<double>(seq_));
    for (int i = 0; i < 181; ++i) scan.mutable_laser_scan()->add_ranges(6.0F);
    connection_.send(scan);
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    while (std::chrono::steady_clock::now() < deadline) {
      auto message = connection_.receive(1s);
      if (!message) continue;
      EXPECT_FALSE(message->has_error()) << message->DebugString();
      if (message->has_motion_command() && message->motion_command().answers_scan_seq() == seq_) {
        return message->motion_command();
      }
    }
    ADD_FAILURE() << "no command answered scan " << seq_;
    return {};
  }

 private:
  client::Connection connection_;
  std::uint64_t seq_ = 0;
};

class ControlOverTheWire : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto config = dir_.path() / "occgeod.yaml";
    std::ofstream(config) << "auth:\n  operator_token: s3cret\n";
    server_ = std::make_unique<ServerProcess>(dir_.path(), std::vector<std::string>{"--config", config.string()});
  }

  ProcessResult cli(std::vector<std::string> args) {
    args.insert(args.begin(), {binary("clients/occgeo").string()});
    args.insert(args.end(), {"--server", server_->address()});
    return run_process(args, 30s);
  }

  TempDir dir_;
  std::unique_ptr<ServerProcess> server_;
};

// Killing the lease holder's connection makes the next command to the robot a stop: within 5
// scans at 10 Hz (0.5 s).
TEST_F(ControlOverTheWire, TheHoldersDisconnectStopsTheRobotWithinHalfASecond) {
  SteppingDriver driver(server_->address());
  EXPECT_EQ(driver.step().behaviour(), v1::BEHAVIOUR_BEARCAT)
      << "without a controller the robot keeps the Bearcat behaviour";
  {
    auto controller = open_role(server_->address(), v1::ROLE_CONTROLLER, "test-controller");
    ASSERT_TRUE(lease(controller, v1::LeaseRequest::ACQUIRE, 1, 10.0).granted());
    ASSERT_TRUE(controller.call(teleop_drive(0.3), 2).has_drive());
    const v1::MotionCommand moving = driver.step();
    EXPECT_EQ(moving.behaviour(), v1::BEHAVIOUR_TELEOP);
    EXPECT_FALSE(moving.stop());
    EXPECT_NEAR(moving.linear_mps(), 0.3, 1e-9);
    controller.close();
  }
  int scans = 0;
  bool stopped = false;
  while (scans < 5 && !stopped) {
    std::this_thread::sleep_for(100ms);
    stopped = driver.step().stop();
    ++scans;
  }
  EXPECT_TRUE(stopped) << "no stop within 5 scans (0.5 s) of the holder's disconnect\n" << server_->log();
  auto query = open_query_session(server_->address());
  v1::ClientMessage status;
  status.mutable_status();
  status.set_request_id(1);
  const auto reply = query.call(status, 1).status();
  ASSERT_EQ(reply.robots_size(), 1);
  EXPECT_FALSE(reply.robots(0).has_lease_holder());
  EXPECT_EQ(reply.robots(0).behaviour(), v1::BEHAVIOUR_STOP);
}

// The same with the real occgeo-sim --lockstep as the driver: once the server has seen the
// holder's connection close (the status shows the lease free after N scans), the simulated robot
// stands still from scan N + 5 on (0.5 s of sim time at 10 Hz), read from its trace.
TEST_F(ControlOverTheWire, TheHoldersDisconnectStopsTheLockstepSimulator) {
  const auto trace = dir_.path() / "sim_trace.csv";
  BackgroundProcess sim({binary("clients/sim/occgeo-sim").string(), "--server", server_->address(), "--world",
                         source("clients/sim/worlds/open_field.yaml").string(), "--robot", "bearcat", "--id", "r1",
                         "--lockstep", "--duration", "600", "--trace-out", trace.string(), "--json"},
                        dir_.path() / "sim.out", dir_.path() / "sim.err");
  auto query = open_query_session(server_->address());
  std::uint64_t status_id = 0;
  const auto robot_status = [&]() -> std::optional<v1::RobotStatus> {
    v1::ClientMessage status;
    status.mutable_status();
    status.set_request_id(++status_id);
    const auto reply = query.call(status, status_id).status();
    if (reply.robots_size() != 1) return std::nullopt;
    return reply.robots(0);
  };
  const auto wait_for = [&](const std::function<bool(const v1::RobotStatus&)>& done) -> std::optional<v1::RobotStatus> {
    for (int i = 0; i < 2000; ++i) {
      if (auto status = robot_status(); status && done(*status)) return status;
      std::this_thread::sleep_for(5ms);
    }
    return std::nullopt;
  };
  ASSERT_TRUE(wait_for([](const v1::RobotStatus& r) { return r.connected() && r.scans_ingested() > 0; }))
      << server_->log();
  std::uint64_t teleop_from = 0;
  {
    auto controller = open_role(server_->address(), v1::ROLE_CONTROLLER, "test-controller");
    ASSERT_TRUE(lease(controller, v1::LeaseRequest::ACQUIRE, 1, 10.0).granted());
    ASSERT_TRUE(controller.call(teleop_drive(0.3, 0.2), 2).has_drive());
    teleop_from = robot_status()->scans_ingested();
    ASSERT_TRUE(wait_for([&](const v1::RobotStatus& r) { return r.scans_ingested() > teleop_from + 20; }));
    controller.close();
  }
  const auto freed = wait_for([](const v1::RobotStatus& r) { return !r.has_lease_holder(); });
  ASSERT_TRUE(freed);
  const std::uint64_t freed_at = freed->scans_ingested();
  ASSERT_TRUE(wait_for([&](const v1::RobotStatus& r) { return r.scans_ingested() > freed_at + 30; }));
  ASSERT_EQ(sim.stop(SIGTERM, 20s), 0);

  std::ifstream in(trace);
  std::string line;
  std::getline(in, line);
  std::vector<std::array<double, 2>> rows;  // x, y at scan 1, 2, ...
  while (std::getline(in, line)) {
    double t = 0.0;
    double x = 0.0;
    double y = 0.0;
    char comma = 0;
    std::istringstream fields(line);
    fields >> t >> comma >> x >> comma >> y;
    rows.push_back({x, y});
  }
  ASSERT_GT(rows.size(), freed_at + 30);
  const auto distance = [&](std::size_t a, std::size_t b) {
    return std::hypot(rows[a][0] - rows[b][0], rows[a][1] - rows[b][1]);
  };
  EXPECT_GT(distance(teleop_from + 2, freed_at - 1), 0.1) << "teleop moved the robot before the disconnect";
  const std::size_t still_from = freed_at + 5 - 1;  // row of scan freed_at + 5
  for (std::size_t i = still_from + 1; i < rows.size(); ++i) {
    EXPECT_LT(distance(still_from, i), 1e-9)
        << "moving at scan " << i + 1 << "; the lease was freed by scan " << freed_at;
  }
  std::ifstream out(dir_.path() / "sim.out");
  const std::string summary((std::istreambuf_iterator<char>(out)), std::istreambuf_iterator<char>());
  EXPECT_NE(summary.find("\"teleop\""), std::string::npos) << summary;
  EXPECT_NE(summary.find("\"last_state\": \"stop\""), std::string::npos) << summary;
}

TEST_F(ControlOverTheWire, TheCliLeasesDrivesAndStopsARobot) {
  SteppingDriver driver(server_->address());
  driver.step();

  auto result = cli({"lease", "acquire", "--robot", "r1", "--json"});
  EXPECT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("\"granted\":true"), std::string::npos) << result.out;

  // drive teleop: acquire, set, hold with retains, return.
  result = cli(
      {"drive", "--robot", "r1", "teleop", "--v", "0.25", "--w", "0.1", "--hold", "0.6", "--timeout", "0.3", "--json"});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("\"behaviour\":\"teleop\""), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("\"returned\":true"), std::string::npos) << result.out;
  EXPECT_EQ(result.out.find("\"retains\":0"), std::string::npos) << "a 0.6 s hold of a 0.3 s lease retains it";
  EXPECT_TRUE(driver.step().stop()) << "teleop needs a holder: returning the lease stops the robot";

  // Another controller holds the lease: acquire is refused naming the holder; take needs the token.
  auto holder = open_role(server_->address(), v1::ROLE_CONTROLLER, "alice");
  ASSERT_TRUE(lease(holder, v1::LeaseRequest::ACQUIRE, 1, 20.0).granted());
  result = cli({"lease", "acquire", "--robot", "r1"});
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.out.find("alice"), std::string::npos) << result.out;
  result = cli({"drive", "--robot", "r1", "bearcat"});
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("alice"), std::string::npos) << result.err;
  result = cli({"lease", "take", "--robot", "r1"});
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("ERROR_UNAUTHENTICATED"), std::string::npos) << result.err;
  result = cli({"lease", "take", "--robot", "r1", "--token", "s3cret", "--json"});
  EXPECT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("\"client_name\":\"occgeo-cli\""), std::string::npos) << result.out;
  EXPECT_FALSE(lease(holder, v1::LeaseRequest::RETAIN, 2).granted()) << "alice lost the lease to the operator";

  // The e-stop: engaged by an observer, shown in the status, every command a stop, released by a holder.
  result = cli({"drive", "--robot", "r1", "bearcat"});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_FALSE(driver.step().stop());
  result = cli({"estop", "--robot", "r1", "--json"});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("\"engaged\":true"), std::string::npos) << result.out;
  const v1::MotionCommand stopped = driver.step();
  EXPECT_TRUE(stopped.stop());
  EXPECT_EQ(stopped.state(), v1::BEHAVIOUR_STATE_ESTOP);
  result = cli({"status", "--json"});
  EXPECT_NE(result.out.find("\"estop\":true"), std::string::npos) << result.out;
  result = cli({"estop", "--robot", "r1", "--release"});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const v1::MotionCommand released = driver.step();
  EXPECT_FALSE(released.stop());
  EXPECT_EQ(released.behaviour(), v1::BEHAVIOUR_BEARCAT);

  result = cli({"drive", "--robot", "r1", "dance"});
  EXPECT_EQ(result.exit_code, 2) << "a bad behaviour is a usage error";
}

// A stand-in server on 127.0.0.1 that welcomes occgeo-sim, answers its first `answered` laser
// scans with a forward command, then goes silent (it keeps reading).
class SilentServer {
 public:
  explicit SilentServer(std::uint64_t answered)
      : acceptor_(io_, {boost::asio::ip::make_address("127.0.0.1"), 0}), answered_(answered) {
    thread_ = std::thread([this] { serve(); });
  }
  ~SilentServer() {
    boost::system::error_code ignored;
    acceptor_.close(ignored);
    if (socket_) socket_->close(ignored);
    thread_.join();
  }
  [[nodiscard]] std::string address() const { return "127.0.0.1:" + std::to_string(acceptor_.local_endpoint().port()); }
  [[nodiscard]] double last_answered_stamp_s() const { return last_answered_stamp_s_.load(); }

 private:
  void serve() {
    boost::system::error_code error;
    socket_.emplace(io_);
    acceptor_.accept(*socket_, error);
    if (error) return;
    proto::FrameDecoder decoder(std::size_t{64} << 20);
    std::array<char, 65536> buffer{};
    std::uint64_t scans = 0;
    for (int reads = 0; reads < 1000000; ++reads) {
      const std::size_t size = socket_->read_some(boost::asio::buffer(buffer), error);
      if (error) return;
      decoder.append(buffer.data(), size);
      v1::ClientMessage message;
      while (decoder.next(message) == proto::FrameStatus::frame) {
        v1::ServerMessage reply;
        if (message.has_hello()) {
          reply.mutable_welcome()->set_protocol_version(proto::kProtocolVersion);
          reply.mutable_welcome()->set_session_id(1);
        } else if (message.has_laser_scan() && ++scans <= answered_) {
          auto* command = reply.mutable_motion_command();
          command->set_seq(scans);
          command->set_answers_scan_seq(message.laser_scan().seq());
          command->set_left_wheel_mps(0.4);
          command->set_right_wheel_mps(0.4);
          command->set_linear_mps(0.4);
          command->set_expires_after_s(0.6);
          command->set_behaviour(v1::BEHAVIOUR_TELEOP);
          last_answered_stamp_s_ = message.laser_scan().stamp_s();
        } else {
          continue;
        }
        boost::asio::write(*socket_, boost::asio::buffer(proto::encode_frame(reply)), error);
        if (error) return;
      }
    }
  }

  boost::asio::io_context io_;
  boost::asio::ip::tcp::acceptor acceptor_;
  std::optional<boost::asio::ip::tcp::socket> socket_;
  std::uint64_t answered_;
  std::atomic<double> last_answered_stamp_s_{0.0};
  std::thread thread_;
};

// The third watchdog lives in the driver: occgeo-sim stops by itself once the last command
// expires (0.6 s here, or its own 0.5 s watchdog if shorter), read from its --trace-out.
TEST(DriverWatchdog, TheSimulatorStopsByItselfWhenCommandsStopComing) {
  TempDir dir;
  SilentServer server(10);
  const auto trace = dir.path() / "trace.csv";
  const auto result = run_process({binary("clients/sim/occgeo-sim").string(), "--server", server.address(), "--world",
                                   source("clients/sim/worlds/open_field.yaml").string(), "--robot", "bearcat",
                                   "--duration", "3", "--trace-out", trace.string(), "--json"},
                                  60s);
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const double last_command_s = server.last_answered_stamp_s();
  ASSERT_GT(last_command_s, 0.0);
  std::ifstream in(trace);
  std::string line;
  std::getline(in, line);
  std::vector<std::array<double, 3>> rows;  // t, x, y
  while (std::getline(in, line)) {
    std::array<double, 4> v{};
    char comma = 0;
    std::istringstream fields(line);
    fields >> v[0] >> comma >> v[1] >> comma >> v[2] >> comma >> v[3];
    rows.push_back({v[0], v[1], v[2]});
  }
  ASSERT_GT(rows.size(), 20U);
  ASSERT_GT(rows.back()[0], last_command_s + 1.5) << "the run must last well past the last command";
  const auto moved = [](const std::array<double, 3>& a, const std::array<double, 3>& b) {
    return std::hypot(a[1] - b[1], a[2] - b[2]) > 1e-6;
  };
  // It drove on after the last command (the command's lifetime), and stood still from 0.6 s (+ one
  // 0.1 s physics/scan period) after it.
  const std::array<double, 3>* at_stop = nullptr;
  bool moved_after_last_command = false;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    if (rows[i][0] > last_command_s && rows[i][0] <= last_command_s + 0.4 && moved(rows[i], rows[i - 1])) {
      moved_after_last_command = true;
    }
    if (rows[i][0] >= last_command_s + 0.7) {
      if (!at_stop) at_stop = &rows[i];
      EXPECT_FALSE(moved(rows[i], *at_stop))
          << "still moving at t = " << rows[i][0] << " s, last command at " << last_command_s << " s";
    }
  }
  EXPECT_TRUE(moved_after_last_command) << "the last command should carry the robot for its lifetime";
  EXPECT_NE(result.out.find("\"commands_received\": 10"), std::string::npos) << result.out;
}

}  // namespace
}  // namespace occgeo::testing
