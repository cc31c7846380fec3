// Bad input over the wire: each case gets a clear error (or, for broken framing, a closed
// connection), the server goes on serving other clients, and the map is unchanged.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <random>
#include <thread>

#include "../support/process.h"
#include "occgeo/proto/framing.h"
#include "occgeo/proto/protocol.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

// A plain TCP socket for sending bytes no well-behaved client would send.
class RawSocket {
 public:
  // receive_buffer_bytes > 0 shrinks the kernel's receive buffer (set before connecting, so the window is small from
  // the start): a client that never reads then holds few bytes in the kernel, whatever the machine's TCP defaults.
  explicit RawSocket(std::uint16_t port, int receive_buffer_bytes = 0) : fd_(socket(AF_INET, SOCK_STREAM, 0)) {
    if (receive_buffer_bytes > 0) {
      setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &receive_buffer_bytes, sizeof receive_buffer_bytes);
    }
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(port);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
      throw std::runtime_error("cannot connect");
    }
    timeval timeout{5, 0};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  }
  ~RawSocket() { close(fd_); }
  RawSocket(const RawSocket&) = delete;
  RawSocket& operator=(const RawSocket&) = delete;

  void send_bytes(const std::string& bytes) {
    ASSERT_EQ(::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL), static_cast<ssize_t>(bytes.size()));
  }
  void send_message(const v1::ClientMessage& message) { send_bytes(proto::encode_frame(message)); }
  // Sends what the kernel takes now without waiting (a peer that stopped reading, or closed, takes nothing).
  void send_what_fits(const std::string& bytes) {
    (void)::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  }
  void finish_sending() { shutdown(fd_, SHUT_WR); }

  // Reads until the server closes the connection or 5 s pass without data; decodes the frames.
  struct Received {
    std::vector<v1::ServerMessage> messages;
    bool closed = false;
  };
  // Reads until `count` frames arrived or 5 s pass without data.
  std::vector<v1::ServerMessage> read_messages(std::size_t count) {
    std::vector<v1::ServerMessage> messages;
    proto::FrameDecoder decoder(64U * 1024U * 1024U);
    char buffer[65536];
    while (messages.size() < count) {
      const ssize_t n = recv(fd_, buffer, sizeof buffer, 0);
      if (n <= 0) break;
      decoder.append(buffer, static_cast<std::size_t>(n));
      v1::ServerMessage message;
      while (decoder.next(message) == proto::FrameStatus::frame) messages.push_back(message);
    }
    return messages;
  }

  Received read_until_closed() {
    Received received;
    proto::FrameDecoder decoder(64U * 1024U * 1024U);
    char buffer[65536];
    while (true) {
      const ssize_t n = recv(fd_, buffer, sizeof buffer, 0);
      if (n == 0) {
        received.closed = true;
        break;
      }
      if (n < 0) break;  // timeout
      decoder.append(buffer, static_cast<std::size_t>(n));
      v1::ServerMessage message;
      while (decoder.next(message) == proto::FrameStatus::frame) received.messages.push_back(message);
    }
    return received;
  }

 private:
  int fd_;
};

v1::ClientMessage hello_message(v1::Role role, const std::string& robot_id = {}) {
  v1::ClientMessage message;
  auto* hello = message.mutable_hello();
  hello->set_protocol_version(proto::kProtocolVersion);
  hello->set_role(role);
  hello->set_robot_id(robot_id);
  return message;
}

class BadInput : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<ServerProcess>(dir_.path());
    driver_ = std::make_unique<client::Connection>(open_driver_session(server_->address(), "robot-a"));
    send_odometry(1, 0.0);
    // One good scan so the map has content, answered by a motion command.
    send_scan(1, 0.1, std::vector<float>(181, 3.0F));
    // The ack says the scan is in the published map (the command leaves before the publication).
    bool commanded = false, acknowledged = false;
    for (int i = 0; i < 10 && !(commanded && acknowledged); ++i) {
      const auto reply = driver_->receive(std::chrono::seconds(5));
      if (!reply) break;
      commanded = commanded || (reply->has_motion_command() && reply->motion_command().answers_scan_seq() == 1);
      acknowledged = acknowledged || (reply->has_scan_ack() && reply->scan_ack().seq() == 1);
    }
    ASSERT_TRUE(commanded && acknowledged);
    map_before_ = grid();
  }

  void send_odometry(std::uint64_t seq, double stamp, double x = 0.0) {
    v1::ClientMessage message;
    auto* odometry = message.mutable_odometry();
    odometry->set_seq(seq);
    odometry->set_stamp_s(stamp);
    odometry->mutable_pose()->set_x(x);
    driver_->send(message);
  }

  void send_scan(std::uint64_t seq, double stamp, const std::vector<float>& ranges) {
    v1::ClientMessage message;
    auto* scan = message.mutable_laser_scan();
    scan->set_sensor("front_laser");
    scan->set_seq(seq);
    scan->set_stamp_s(stamp);
    for (const float r : ranges) scan->add_ranges(r);
    driver_->send(message);
  }

  std::optional<v1::MotionCommand> send_scan_expect_command(std::uint64_t seq, double stamp,
                                                            const std::vector<float>& ranges) {
    send_scan(seq, stamp, ranges);
    for (int i = 0; i < 10; ++i) {
      auto reply = driver_->receive(std::chrono::seconds(5));
      if (!reply) break;
      if (reply->has_motion_command() && reply->motion_command().answers_scan_seq() == seq)
        return reply->motion_command();
    }
    return std::nullopt;
  }

  // The next error the driver receives (skipping acks and commands).
  v1::Error expect_driver_error() {
    for (int i = 0; i < 10; ++i) {
      auto reply = driver_->receive(std::chrono::seconds(5));
      if (!reply) break;
      if (reply->has_error()) return reply->error();
    }
    ADD_FAILURE() << "no error arrived";
    return {};
  }

  v1::GridReply grid() {
    auto query = open_query_session(server_->address());
    v1::ClientMessage request;
    request.set_request_id(9);
    request.mutable_grid()->set_world("default");
    return query.call(request, 9).grid();
  }

  // The server still answers another client, and the map is exactly as before.
  void expect_serving_and_map_unchanged() {
    ASSERT_TRUE(server_->running()) << server_->log();
    const v1::GridReply now = grid();
    EXPECT_EQ(now.version(), map_before_.version());
    EXPECT_EQ(now.cells(), map_before_.cells());
  }

  TempDir dir_;
  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<client::Connection> driver_;
  v1::GridReply map_before_;
};

TEST_F(BadInput, RandomBytesCloseTheConnection) {
  for (unsigned seed = 1; seed <= 20; ++seed) {
    RawSocket raw(server_->port());
    std::mt19937 rng(seed);
    std::string bytes(4096, '\0');
    for (auto& b : bytes) b = static_cast<char>(rng() & 0xFFU);
    raw.send_bytes(bytes);
    raw.finish_sending();
    const auto received = raw.read_until_closed();
    EXPECT_TRUE(received.closed) << "seed " << seed;
    for (const auto& message : received.messages) {
      ASSERT_TRUE(message.has_error()) << "seed " << seed << ": random bytes got a non-error reply";
    }
  }
  expect_serving_and_map_unchanged();
}

TEST_F(BadInput, LengthPrefixOverTheLimitGetsFrameTooLargeAndClose) {
  RawSocket raw(server_->port());
  raw.send_bytes(std::string("\x80\x80\x80\x40", 4));  // varint 128 MiB, over the 4 MiB default limit
  const auto received = raw.read_until_closed();
  EXPECT_TRUE(received.closed);
  ASSERT_EQ(received.messages.size(), 1U);
  EXPECT_EQ(received.messages[0].error().code(), v1::ERROR_FRAME_TOO_LARGE);
  EXPECT_NE(received.messages[0].error().message().find("134217728"), std::string::npos)
      << received.messages[0].error().message();
  expect_serving_and_map_unchanged();
}

TEST_F(BadInput, FrameCutOffByDisconnectLeavesNoTrace) {
  {
    RawSocket raw(server_->port());
    raw.send_message(hello_message(v1::ROLE_DRIVER, "robot-b"));
    v1::ClientMessage spec;
    *spec.mutable_robot_spec() = bearcat_spec();
    const std::string frame = proto::encode_frame(spec);
    raw.send_bytes(frame.substr(0, frame.size() / 2));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  auto query = open_query_session(server_->address());
  v1::ClientMessage request;
  request.mutable_status();
  request.set_request_id(1);
  const auto status = query.call(request, 1).status();
  ASSERT_EQ(status.robots_size(), 1) << "the half-sent spec must not register robot-b";
  EXPECT_EQ(status.robots(0).id(), "robot-a");
  expect_serving_and_map_unchanged();
}

TEST_F(BadInput, UnknownMessageGetsAnErrorAndTheSessionGoesOn) {
  auto query = open_query_session(server_->address());
  // A ClientMessage carrying only field 99, which occgeo.v1 does not define.
  v1::ClientMessage unknown;
  unknown.GetReflection()->MutableUnknownFields(&unknown)->AddLengthDelimited(99, "from the future");
  query.send(unknown);
  const auto reply = query.receive(std::chrono::seconds(5));
  ASSERT_TRUE(reply && reply->has_error());
  EXPECT_EQ(reply->error().code(), v1::ERROR_UNKNOWN_MESSAGE);
  v1::ClientMessage request;
  request.mutable_status();
  request.set_request_id(2);
  EXPECT_NO_THROW(query.call(request, 2));
  expect_serving_and_map_unchanged();
}

TEST_F(BadInput, NonFiniteAndNegativeRangesAreRejectedNamingTheBeam) {
  const std::vector<std::pair<float, std::string>> cases = {
      {std::nanf(""), "nan"}, {INFINITY, "inf"}, {-INFINITY, "-inf"}, {-0.5F, "negative"}};
  std::uint64_t seq = 2;
  for (const auto& [bad, name] : cases) {
    std::vector<float> ranges(181, 2.0F);
    ranges[17] = bad;
    send_scan(seq++, 0.2, ranges);
    const v1::Error error = expect_driver_error();
    EXPECT_EQ(error.code(), v1::ERROR_INVALID_ARGUMENT) << name;
    EXPECT_EQ(error.field(), "laser_scan.ranges[17]") << name;
    EXPECT_NE(error.message().find("discarded"), std::string::npos) << error.message();
  }
  expect_serving_and_map_unchanged();
}

TEST_F(BadInput, BeamCountDisagreeingWithTheSpecIsRejected) {
  send_scan(2, 0.2, std::vector<float>(180, 2.0F));
  const v1::Error error = expect_driver_error();
  EXPECT_EQ(error.code(), v1::ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(error.field(), "laser_scan.ranges");
  EXPECT_NE(error.message().find("180"), std::string::npos) << error.message();
  EXPECT_NE(error.message().find("181"), std::string::npos) << error.message();
  expect_serving_and_map_unchanged();
}

TEST_F(BadInput, TimestampsGoingBackwardsAndFarPosesAreRejected) {
  send_scan(2, 0.05, std::vector<float>(181, 2.0F));  // earlier than the accepted scan at 0.1 s
  v1::Error error = expect_driver_error();
  EXPECT_EQ(error.code(), v1::ERROR_OUT_OF_ORDER);
  EXPECT_EQ(error.field(), "laser_scan.stamp_s");

  send_odometry(2, 0.3, 1.0e9);
  error = expect_driver_error();
  EXPECT_EQ(error.code(), v1::ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(error.field(), "odometry.pose.x");
  expect_serving_and_map_unchanged();
}

TEST_F(BadInput, QueryForUnknownRobotNamesIt) {
  auto query = open_query_session(server_->address());
  v1::ClientMessage request;
  request.set_request_id(5);
  auto* collision = request.mutable_collision();
  collision->set_robot_id("ghost");
  collision->mutable_pose();
  query.send(request);
  const auto reply = query.receive(std::chrono::seconds(5));
  ASSERT_TRUE(reply && reply->has_error());
  EXPECT_EQ(reply->error().code(), v1::ERROR_UNKNOWN_ROBOT);
  EXPECT_EQ(reply->error().field(), "collision.robot_id");
  EXPECT_EQ(reply->request_id(), 5U);
  EXPECT_NE(reply->error().message().find("ghost"), std::string::npos);
  expect_serving_and_map_unchanged();
}

// The server decodes the frames of one read into memory it reuses once they are handled; a frame far larger than the
// rest (a 5000-pose batch, about 140 kB) in the middle of small ones must not disturb the ones before or after it.
TEST_F(BadInput, FramesOfOneWriteAroundALargeOneAreEachAnswered) {
  constexpr int kStatusBefore = 10;
  constexpr int kStatusAfter = 30;
  constexpr int kPoses = 5000;
  std::string bytes = proto::encode_frame(hello_message(v1::ROLE_QUERY));
  const auto append_status = [&](std::uint64_t request_id) {
    v1::ClientMessage status;
    status.mutable_status();
    status.set_request_id(request_id);
    proto::append_frame(status, bytes);
  };
  for (int i = 0; i < kStatusBefore; ++i) append_status(100 + i);
  v1::ClientMessage batch;
  batch.set_request_id(50);
  auto* query = batch.mutable_collision_batch();
  query->set_robot_id("robot-a");
  for (int i = 0; i < kPoses; ++i) {
    auto* pose = query->add_poses();
    pose->set_x(-4.0 + 8.0 * i / kPoses);
    pose->set_y(0.25 * (i % 7));
    pose->set_theta(0.001 * i);
  }
  proto::append_frame(batch, bytes);
  ASSERT_GT(bytes.size(), 128U * 1024U);
  for (int i = 0; i < kStatusAfter; ++i) append_status(200 + i);

  RawSocket raw(server_->port());
  raw.send_bytes(bytes);
  const auto messages = raw.read_messages(1 + kStatusBefore + 1 + kStatusAfter);
  ASSERT_EQ(messages.size(), 1U + kStatusBefore + 1 + kStatusAfter);
  EXPECT_TRUE(messages[0].has_welcome()) << messages[0].DebugString();
  std::vector<std::uint64_t> status_ids;
  int batches = 0;
  for (std::size_t i = 1; i < messages.size(); ++i) {
    if (messages[i].has_collision_batch()) {
      ++batches;
      EXPECT_EQ(messages[i].request_id(), 50U);
      EXPECT_EQ(messages[i].collision_batch().results_size(), kPoses);
      continue;
    }
    ASSERT_TRUE(messages[i].has_status()) << messages[i].DebugString();
    status_ids.push_back(messages[i].request_id());
  }
  EXPECT_EQ(batches, 1);
  std::vector<std::uint64_t> expected;
  for (int i = 0; i < kStatusBefore; ++i) expected.push_back(100 + i);
  for (int i = 0; i < kStatusAfter; ++i) expected.push_back(200 + i);
  EXPECT_EQ(status_ids, expected) << "status requests are answered in their order, none lost or mixed up";
  expect_serving_and_map_unchanged();
}

TEST_F(BadInput, SessionsMustStartWithHelloOfTheRightVersion) {
  RawSocket raw(server_->port());
  v1::ClientMessage status;
  status.mutable_status();
  status.set_request_id(1);
  raw.send_message(status);
  auto wrong_version = hello_message(v1::ROLE_QUERY);
  wrong_version.mutable_hello()->set_protocol_version(7);
  raw.send_message(wrong_version);
  raw.finish_sending();
  const auto received = raw.read_until_closed();
  ASSERT_EQ(received.messages.size(), 2U);
  EXPECT_EQ(received.messages[0].error().code(), v1::ERROR_OUT_OF_ORDER);
  EXPECT_EQ(received.messages[1].error().code(), v1::ERROR_PROTOCOL_VERSION);
  EXPECT_EQ(received.messages[1].error().field(), "hello.protocol_version");
}

// A client that asks for much and never reads must not hold up a robot: the robot's scans keep being answered and the
// stuck client is eventually dropped. It keeps asking (in waves, never blocking the test) until it is dropped, so the
// test does not depend on how many bytes the machine's TCP buffers absorb or on how small the map is when it asks.
TEST(SlowClient, StuckReaderIsDroppedWhileTheRobotKeepsDriving) {
  TempDir dir;
  const auto config = dir.path() / "occgeod.yaml";
  std::ofstream(config) << "limits:\n  max_send_queue_bytes: 4194304\n";
  ServerProcess server(dir.path(), {"--config", config.string()});
  auto driver = open_driver_session(server.address(), "robot-a");

  RawSocket stuck(server.port(), 4096);
  stuck.send_message(hello_message(v1::ROLE_QUERY));
  std::uint64_t request_id = 0;
  const auto wave_of_grid_requests = [&] {
    std::string requests;
    for (int i = 0; i < 500; ++i) {
      v1::ClientMessage request;
      request.mutable_grid();
      request.set_request_id(++request_id);
      requests += proto::encode_frame(request);
    }
    return requests;
  };
  const auto log = [&] { return server.log(); };
  const auto dropped = [&] { return log().find("session_slow_client_dropped") != std::string::npos; };
  std::uint64_t answered = 0;
  for (std::uint64_t seq = 1; seq <= 100; ++seq) {
    if (seq % 10 == 2 && !dropped()) stuck.send_what_fits(wave_of_grid_requests());
    v1::ClientMessage odometry;
    odometry.mutable_odometry()->set_seq(seq);
    odometry.mutable_odometry()->set_stamp_s(0.1 * static_cast<double>(seq));
    odometry.mutable_odometry()->mutable_pose()->set_x(0.01 * static_cast<double>(seq));
    driver.send(odometry);
    v1::ClientMessage scan;
    scan.mutable_laser_scan()->set_sensor("front_laser");
    scan.mutable_laser_scan()->set_seq(seq);
    scan.mutable_laser_scan()->set_stamp_s(0.1 * static_cast<double>(seq));
    for (int beam = 0; beam < 181; ++beam)
      scan.mutable_laser_scan()->add_ranges(1.0F + 0.02F * static_cast<float>(beam));
    driver.send(scan);
    // The command answers the scan before its journal record is durable; the durable ScanAcks can trail by dozens of
    // scans when fsync is slow (a busy machine), so the replies read before the command are bounded generously.
    for (int i = 0; i < 200; ++i) {
      auto reply = driver.receive(std::chrono::seconds(10));
      ASSERT_TRUE(reply) << "scan " << seq << " was not answered within 10 s";
      if (reply->has_motion_command() && reply->motion_command().answers_scan_seq() == seq) {
        ++answered;
        break;
      }
    }
  }
  EXPECT_EQ(answered, 100U);
  // Still not dropped (a fast machine answered every request while the map was small): keep asking, for at most 30 s.
  for (int i = 0; i < 300 && !dropped(); ++i) {
    if (i % 10 == 0) stuck.send_what_fits(wave_of_grid_requests());
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_TRUE(dropped()) << "the stuck client should be dropped";
}

// limits.max_batch_queries bounds every batch: one entry more is refused naming the field and the limit, and a batch
// at the limit is answered in full.
TEST(BatchLimit, ConfiguredLimitRefusesALargerBatchNamingIt) {
  TempDir dir;
  const auto config = dir.path() / "occgeod.yaml";
  std::ofstream(config) << "limits:\n  max_batch_queries: 4\n";
  ServerProcess server(dir.path(), {"--config", config.string()});
  auto driver = open_driver_session(server.address(), "robot-a");
  auto query = open_query_session(server.address());
  for (const int poses : {5, 4}) {
    v1::ClientMessage request;
    request.set_request_id(static_cast<std::uint64_t>(poses));
    auto* batch = request.mutable_collision_batch();
    batch->set_robot_id("robot-a");
    for (int i = 0; i < poses; ++i) batch->add_poses()->set_x(0.1 * i);
    query.send(request);
    const auto reply = query.receive(std::chrono::seconds(5));
    ASSERT_TRUE(reply) << poses << " poses: no answer";
    if (poses == 5) {
      ASSERT_TRUE(reply->has_error()) << reply->DebugString();
      EXPECT_EQ(reply->error().code(), v1::ERROR_INVALID_ARGUMENT);
      EXPECT_EQ(reply->error().field(), "collision_batch.poses");
      EXPECT_NE(reply->error().message().find("1 to 4 entries, got 5"), std::string::npos) << reply->error().message();
    } else {
      ASSERT_TRUE(reply->has_collision_batch()) << reply->DebugString();
      EXPECT_EQ(reply->collision_batch().results_size(), 4);
    }
  }
}

// A scan whose rays would touch more octree voxels than limits.max_scan_voxels is refused naming the limit and the
// count; the server stays up, what it took before is still in the map, and the robot's next ordinary scan is taken
// and answered.
TEST(ScanVoxelLimit, ScanOverTheLimitIsRefusedNamingItAndTheRobotCarriesOn) {
  TempDir dir;
  const auto config = dir.path() / "occgeod.yaml";
  // The Bearcat's LMS200: 181 beams; at 4 m each touches 81 voxels of 5 cm, 14661 in all; at 1 m, 3801.
  std::ofstream(config) << "limits:\n  max_scan_voxels: 10000\n";
  ServerProcess server(dir.path(), {"--config", config.string()});
  auto driver = open_driver_session(server.address(), "robot-a");
  v1::ClientMessage odometry;
  odometry.mutable_odometry()->set_seq(1);
  odometry.mutable_odometry()->set_stamp_s(0.1);
  odometry.mutable_odometry()->mutable_pose()->set_x(0.0);
  driver.send(odometry);
  const auto scan_of = [](std::uint64_t seq, float range_m) {
    v1::ClientMessage scan;
    scan.mutable_laser_scan()->set_sensor("front_laser");
    scan.mutable_laser_scan()->set_seq(seq);
    scan.mutable_laser_scan()->set_stamp_s(0.1 * static_cast<double>(seq));
    for (int beam = 0; beam < 181; ++beam) scan.mutable_laser_scan()->add_ranges(range_m);
    return scan;
  };
  // An ordinary scan first: accepted, its walls in the map.
  driver.send(scan_of(2, 1.0F));
  bool acknowledged = false;
  for (int i = 0; i < 10 && !acknowledged; ++i) {
    const auto reply = driver.receive(std::chrono::seconds(5));
    ASSERT_TRUE(reply) << "no answer to the first scan";
    ASSERT_FALSE(reply->has_error()) << reply->DebugString();
    acknowledged = reply->has_scan_ack() && reply->scan_ack().seq() == 2;
  }
  ASSERT_TRUE(acknowledged);
  auto query = open_query_session(server.address());
  const auto world_status = [&query](std::uint64_t id) {
    v1::ClientMessage request;
    request.mutable_status();
    request.set_request_id(id);
    return query.call(request, id).status().worlds(0);
  };
  const v1::WorldStatus before = world_status(1);
  ASSERT_GT(before.occupied_cells(), 0U);

  driver.send(scan_of(3, 4.0F));
  bool refused = false;
  for (int i = 0; i < 10 && !refused; ++i) {
    const auto reply = driver.receive(std::chrono::seconds(5));
    ASSERT_TRUE(reply) << "no answer to the oversized scan";
    if (reply->has_error()) {
      refused = true;
      EXPECT_EQ(reply->error().code(), v1::ERROR_INVALID_ARGUMENT);
      EXPECT_EQ(reply->error().field(), "laser_scan.ranges");
      EXPECT_NE(reply->error().message().find("14661 octree voxels, more than limits.max_scan_voxels (10000)"),
                std::string::npos)
          << reply->error().message();
    }
    EXPECT_FALSE(reply->has_scan_ack()) << "the oversized scan must not be acknowledged";
  }
  ASSERT_TRUE(refused);
  // The refused scan changed nothing; the accepted one is still there.
  const v1::WorldStatus after = world_status(2);
  EXPECT_EQ(after.version(), before.version());
  EXPECT_EQ(after.occupied_cells(), before.occupied_cells());
  driver.send(scan_of(4, 1.0F));
  bool answered = false;
  for (int i = 0; i < 10 && !answered; ++i) {
    const auto reply = driver.receive(std::chrono::seconds(5));
    ASSERT_TRUE(reply) << "no answer to the ordinary scan";
    answered = reply->has_motion_command() && reply->motion_command().answers_scan_seq() == 4;
  }
  EXPECT_TRUE(answered);
}

}  // namespace
}  // namespace occgeo::testing
