// The live view's WebSocket on the real server: the page gets the whole map once, then only the tiles a scan
// changed; robots where the status says they are; the e-stop under the protocol's rule.
// Boost.PropertyTree (the JSON reader here) pulls in boost/bind.hpp, which otherwise warns about its placeholders.
#define BOOST_BIND_GLOBAL_PLACEHOLDERS
#include <gtest/gtest.h>

#include <array>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/property_tree/json_parser.hpp>
#include <boost/property_tree/ptree.hpp>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <sstream>
#include <thread>
#include <vector>

#include "../support/http_get.h"
#include "../support/process.h"
#include "../support/temp_dir.h"
#include "occgeo/mapfile/map_file.h"
#include "occgeo/proto/labels.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

namespace beast = boost::beast;
using boost::property_tree::ptree;

std::vector<std::uint8_t> decode_base64(const std::string& text) {
  std::vector<std::uint8_t> out;
  std::uint32_t bits = 0;
  int count = 0;
  for (const char c : text) {
    int value = -1;
    if (c >= 'A' && c <= 'Z') value = c - 'A';
    if (c >= 'a' && c <= 'z') value = c - 'a' + 26;
    if (c >= '0' && c <= '9') value = c - '0' + 52;
    if (c == '+') value = 62;
    if (c == '/') value = 63;
    if (value < 0) continue;
    bits = (bits << 6) | static_cast<std::uint32_t>(value);
    count += 6;
    if (count >= 8) {
      count -= 8;
      out.push_back(static_cast<std::uint8_t>((bits >> count) & 0xff));
    }
  }
  return out;
}

// A WebSocket client of /ws that keeps the page's copy of the map, as app.js does.
class LiveViewClient {
 public:
  explicit LiveViewClient(std::uint16_t port) : ws_(io_) {
    beast::get_lowest_layer(ws_).connect(
        boost::asio::ip::tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
    beast::get_lowest_layer(ws_).expires_after(std::chrono::seconds(10));
    ws_.handshake("127.0.0.1", "/ws");
  }

  // The next message of the given type (frames are applied to the map copy on the way).
  ptree next(const std::string& type) {
    for (int i = 0; i < 200; ++i) {
      beast::get_lowest_layer(ws_).expires_after(std::chrono::seconds(10));
      beast::flat_buffer buffer;
      ws_.read(buffer);
      std::istringstream in(beast::buffers_to_string(buffer.data()));
      ptree message;
      boost::property_tree::read_json(in, message);
      if (message.get<std::string>("type") == "frame") apply(message);
      if (message.get<std::string>("type") == type) return message;
    }
    throw std::runtime_error("no '" + type + "' message in 200");
  }

  // Frames until the map is complete; returns the tiles received on the way.
  std::size_t until_complete() {
    std::size_t tiles = 0;
    for (int i = 0; i < 100; ++i) {
      const ptree frame = next("frame");
      tiles += last_tiles_;
      if (frame.get<bool>("map.map_complete")) return tiles;
    }
    throw std::runtime_error("the map never completed");
  }

  void send(const std::string& text) {
    beast::get_lowest_layer(ws_).expires_after(std::chrono::seconds(10));
    ws_.write(boost::asio::buffer(text));
  }

  [[nodiscard]] std::size_t occupied_cells() const {
    std::size_t count = 0;
    for (const auto& [key, cells] : tiles_) {
      for (const std::uint8_t c : cells) count += c != 255 && c >= threshold_ ? 1 : 0;
    }
    return count;
  }
  [[nodiscard]] std::size_t last_tiles() const { return last_tiles_; }
  [[nodiscard]] std::uint64_t version() const { return version_; }

 private:
  void apply(const ptree& frame) {
    last_tiles_ = 0;
    const auto map = frame.get_child_optional("map");
    if (!map || map->empty()) return;
    threshold_ = map->get<int>("occupied_threshold");
    version_ = map->get<std::uint64_t>("version");
    const int n = map->get<int>("tile_cells");
    for (const auto& [unused, tile] : map->get_child("tiles")) {
      auto cells = decode_base64(tile.get<std::string>("cells"));
      if (cells.size() != static_cast<std::size_t>(n * n)) throw std::runtime_error("tile of the wrong size");
      tiles_[{tile.get<int>("tx"), tile.get<int>("ty")}] = std::move(cells);
      ++last_tiles_;
    }
  }

  boost::asio::io_context io_;
  beast::websocket::stream<beast::tcp_stream> ws_;
  std::map<std::pair<int, int>, std::vector<std::uint8_t>> tiles_;
  int threshold_ = 0;
  std::uint64_t version_ = 0;
  std::size_t last_tiles_ = 0;
};

class LiveView : public ::testing::Test {
 protected:
  void SetUp() override {
    // The open-field world restored as the default world: a known map from the first frame on.
    const auto world_dir = dir_.path() / "worlds" / "default";
    std::filesystem::create_directories(world_dir);
    mapfile::write_map(world_dir / "grid", mapfile::read_map_yaml(source("clients/sim/worlds/open_field.yaml")));
    server_ = std::make_unique<ServerProcess>(dir_.path(), std::vector<std::string>{"--http", "127.0.0.1:0"});
    port_ = http_port(*server_);
    driver_ = std::make_unique<client::Connection>(open_driver_session(server_->address(), "probe"));
    v1::ClientMessage odometry;
    odometry.mutable_odometry()->set_seq(1);
    odometry.mutable_odometry()->set_stamp_s(1.0);
    odometry.mutable_odometry()->mutable_pose()->set_x(1.5);
    odometry.mutable_odometry()->mutable_pose()->set_y(-2.0);
    odometry.mutable_odometry()->mutable_pose()->set_theta(0.3);
    driver_->send(odometry);
    query_ = std::make_unique<client::Connection>(open_query_session(server_->address()));
    for (int attempt = 0; attempt < 100; ++attempt) {
      const v1::StatusReply reply = status();
      if (reply.robots_size() == 1 && reply.robots(0).has_pose() && reply.robots(0).pose().x() == 1.5) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    FAIL() << "robot 'probe' never got its pose";
  }

  v1::StatusReply status() {
    v1::ClientMessage request;
    request.mutable_status();
    request.set_request_id(++request_id_);
    return query_->call(request, request_id_).status();
  }

  TempDir dir_;
  std::unique_ptr<ServerProcess> server_;
  std::uint16_t port_ = 0;
  std::unique_ptr<client::Connection> driver_;
  std::unique_ptr<client::Connection> query_;
  std::uint64_t request_id_ = 0;
};

TEST_F(LiveView, SendsTheWholeMapOnceThenOnlyTheTilesAScanChanged) {
  LiveViewClient page(port_);
  const std::size_t first_tiles = page.until_complete();
  const v1::StatusReply before = status();
  ASSERT_EQ(before.worlds_size(), 1);
  EXPECT_EQ(page.occupied_cells(), before.worlds(0).occupied_cells());
  EXPECT_GT(first_tiles, 1u);

  // Nothing changed: the next frames carry robots but no tiles.
  for (int i = 0; i < 3; ++i) {
    page.next("frame");
    EXPECT_EQ(page.last_tiles(), 0u);
  }

  // One LMS200 scan (2 m all round) changes the tiles around the robot only.
  v1::ClientMessage scan;
  scan.mutable_laser_scan()->set_sensor("front_laser");
  scan.mutable_laser_scan()->set_seq(2);
  scan.mutable_laser_scan()->set_stamp_s(1.1);
  for (int beam = 0; beam < 181; ++beam) scan.mutable_laser_scan()->add_ranges(2.0F);
  driver_->send(scan);
  std::uint64_t acked_version = 0;
  for (int i = 0; i < 10 && acked_version == 0; ++i) {
    const auto reply = driver_->receive(std::chrono::seconds(10));
    ASSERT_TRUE(reply);
    if (reply->has_scan_ack()) acked_version = reply->scan_ack().world_version();
  }
  ASSERT_GT(acked_version, before.worlds(0).version());
  std::size_t changed_tiles = 0;
  for (int i = 0; i < 50 && page.version() < acked_version; ++i) {
    page.next("frame");
    changed_tiles += page.last_tiles();
  }
  EXPECT_EQ(page.version(), acked_version);
  EXPECT_GT(changed_tiles, 0u);
  EXPECT_LT(changed_tiles, first_tiles);
  EXPECT_EQ(page.occupied_cells(), status().worlds(0).occupied_cells());
}

TEST_F(LiveView, ShowsTheRobotWhereTheStatusSaysAndEngagesItsEStop) {
  LiveViewClient page(port_);
  const ptree frame = page.next("frame");
  const ptree& robot = frame.get_child("robots").begin()->second;
  const v1::RobotStatus truth = status().robots(0);
  EXPECT_EQ(robot.get<std::string>("id"), "probe");
  EXPECT_EQ(robot.get<double>("pose.x"), truth.pose().x());
  EXPECT_EQ(robot.get<double>("pose.y"), truth.pose().y());
  EXPECT_EQ(robot.get<double>("pose.theta"), truth.pose().theta());
  EXPECT_EQ(robot.get<std::string>("footprint.shape"), "box");
  EXPECT_EQ(robot.get<std::string>("behaviour"), proto::behaviour_label(truth.behaviour()));
  EXPECT_FALSE(robot.get<bool>("estop"));

  page.send(R"({"type":"estop","robot":"nobody"})");
  EXPECT_EQ(page.next("error").get<std::string>("field"), "robot");
  page.send(R"({"type":"launch"})");
  EXPECT_EQ(page.next("error").get<std::string>("field"), "type");
  page.send(R"({"type":"estop","robot":"probe"})");
  EXPECT_TRUE(page.next("estop").get<bool>("engaged"));
  EXPECT_TRUE(status().robots(0).estop());
  for (int i = 0; i < 20; ++i) {
    const ptree later = page.next("frame");
    if (later.get_child("robots").begin()->second.get<bool>("estop")) return;
  }
  FAIL() << "the page never showed the e-stop";
}

TEST_F(LiveView, SendsTheLatestScanInTheWorldFrame) {
  LiveViewClient page(port_);
  EXPECT_TRUE(page.next("frame").get_child("robots").begin()->second.get_child("scan").empty()) << "no scan yet";

  // One LMS200 scan: beam k at (-90 + k) deg in the laser's frame, which the Bearcat carries 0.45 m ahead of
  // base_link. Every fifth beam returns at 1 + k/100 m, the others read the laser's maximum (no return).
  const v1::RobotSpec spec = bearcat_spec();
  const v1::LaserSpec& laser = spec.sensors(0).laser();
  const double mount_x = spec.sensors(0).mount().position().x();
  v1::ClientMessage scan;
  scan.mutable_laser_scan()->set_sensor(spec.sensors(0).name());
  scan.mutable_laser_scan()->set_seq(2);
  scan.mutable_laser_scan()->set_stamp_s(1.25);
  std::vector<std::array<double, 2>> expected;
  const v1::Pose2D pose = status().robots(0).pose();
  for (int beam = 0; beam < static_cast<int>(laser.beam_count()); ++beam) {
    const bool returns = beam % 5 == 0;
    const float range = returns ? 1.0F + static_cast<float>(beam) / 100.0F : static_cast<float>(laser.range_max_m());
    scan.mutable_laser_scan()->add_ranges(range);
    if (!returns) continue;
    const double sensor_x = pose.x() + mount_x * std::cos(pose.theta());
    const double sensor_y = pose.y() + mount_x * std::sin(pose.theta());
    const double bearing = pose.theta() + laser.angle_min_rad() + beam * laser.angle_increment_rad();
    const auto reading = static_cast<double>(range);
    expected.push_back({sensor_x + reading * std::cos(bearing), sensor_y + reading * std::sin(bearing)});
  }
  driver_->send(scan);
  for (int i = 0; i < 50; ++i) {
    const ptree frame = page.next("frame");
    const ptree& robot = frame.get_child("robots").begin()->second;
    if (robot.get_child("scan").empty()) continue;
    EXPECT_EQ(robot.get<double>("scan.stamp_s"), 1.25);
    std::vector<std::array<double, 2>> points;
    for (const auto& [unused, point] : robot.get_child("scan.points")) {
      std::vector<double> xy;
      for (const auto& [unused_key, number] : point) xy.push_back(number.get_value<double>());
      ASSERT_EQ(xy.size(), 2u);
      points.push_back({xy[0], xy[1]});
    }
    ASSERT_EQ(points.size(), expected.size());
    for (std::size_t k = 0; k < points.size(); ++k) {
      EXPECT_NEAR(points[k][0], expected[k][0], 0.001) << "point " << k;
      EXPECT_NEAR(points[k][1], expected[k][1], 0.001) << "point " << k;
    }
    EXPECT_TRUE(robot.get_child("path").empty()) << "the Bearcat behaviour follows no path";
    return;
  }
  FAIL() << "no frame carried the scan";
}

// A client of the Foxglove WebSocket protocol (subprotocol foxglove.websocket.v1, JSON encoding).
class FoxgloveClient {
 public:
  explicit FoxgloveClient(std::uint16_t port) : ws_(io_) {
    beast::get_lowest_layer(ws_).connect(
        boost::asio::ip::tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
    beast::get_lowest_layer(ws_).expires_after(std::chrono::seconds(10));
    ws_.set_option(beast::websocket::stream_base::decorator([](beast::websocket::request_type& request) {
      request.set(beast::http::field::sec_websocket_protocol, "foxglove.websocket.v1");
    }));
    beast::websocket::response_type response;
    ws_.handshake(response, "127.0.0.1", "/");
    const auto subprotocol = response[beast::http::field::sec_websocket_protocol];
    subprotocol_ = std::string(subprotocol.data(), subprotocol.size());
  }

  // The next text message, as JSON.
  ptree next_text() {
    for (int i = 0; i < 100; ++i) {
      const auto [binary, bytes] = read();
      if (binary) continue;
      std::istringstream in(bytes);
      ptree message;
      boost::property_tree::read_json(in, message);
      return message;
    }
    throw std::runtime_error("no text message in 100");
  }

  // The next Message Data frame of this subscription: its JSON payload.
  ptree next_data(std::uint32_t subscription) {
    for (int i = 0; i < 200; ++i) {
      const auto [binary, bytes] = read();
      if (!binary || bytes.size() < 13 || bytes[0] != '\x01') continue;
      std::uint32_t id = 0;
      for (int k = 0; k < 4; ++k) id |= std::uint32_t{static_cast<std::uint8_t>(bytes[1 + k])} << (8 * k);
      if (id != subscription) continue;
      std::istringstream in(bytes.substr(13));
      ptree message;
      boost::property_tree::read_json(in, message);
      return message;
    }
    throw std::runtime_error("no data for subscription " + std::to_string(subscription));
  }

  void send(const std::string& text) {
    beast::get_lowest_layer(ws_).expires_after(std::chrono::seconds(10));
    ws_.text(true);
    ws_.write(boost::asio::buffer(text));
  }

  [[nodiscard]] const std::string& subprotocol() const { return subprotocol_; }

 private:
  std::pair<bool, std::string> read() {
    beast::get_lowest_layer(ws_).expires_after(std::chrono::seconds(10));
    beast::flat_buffer buffer;
    ws_.read(buffer);
    return {ws_.got_binary(), beast::buffers_to_string(buffer.data())};
  }

  boost::asio::io_context io_;
  beast::websocket::stream<beast::tcp_stream> ws_;
  std::string subprotocol_;
};

TEST_F(LiveView, PublishesTheGridAndScansOverTheFoxgloveProtocol) {
  FoxgloveClient client(port_);
  EXPECT_EQ(client.subprotocol(), "foxglove.websocket.v1");
  EXPECT_EQ(client.next_text().get<std::string>("op"), "serverInfo");
  const ptree advertise = client.next_text();
  ASSERT_EQ(advertise.get<std::string>("op"), "advertise");
  std::map<std::string, std::pair<int, std::string>> channels;  // topic -> id, schema name
  for (const auto& [unused, channel] : advertise.get_child("channels")) {
    EXPECT_EQ(channel.get<std::string>("encoding"), "json");
    channels[channel.get<std::string>("topic")] = {channel.get<int>("id"), channel.get<std::string>("schemaName")};
  }
  ASSERT_EQ(channels.count("/map"), 1u);
  ASSERT_EQ(channels.count("/scans"), 1u);
  EXPECT_EQ(channels["/map"].second, "foxglove.Grid");
  EXPECT_EQ(channels["/scans"].second, "foxglove.PointCloud");
  client.send(R"({"op":"subscribe","subscriptions":[{"id":7,"channelId":)" + std::to_string(channels["/map"].first) +
              R"(},{"channelId":)" + std::to_string(channels["/scans"].first) + R"(,"id":8}]})");

  // The grid: the restored open field, every occupied cell of the server's count.
  const ptree grid = client.next_data(7);
  EXPECT_EQ(grid.get<std::string>("frame_id"), "world");
  const auto columns = grid.get<std::size_t>("column_count");
  const auto cells = decode_base64(grid.get<std::string>("data"));
  ASSERT_GT(columns, 0u);
  ASSERT_EQ(cells.size() % columns, 0u);
  EXPECT_EQ(grid.get<std::size_t>("row_stride"), columns);
  EXPECT_DOUBLE_EQ(grid.get<double>("cell_size.x"), 0.1);
  const v1::StatusReply truth = status();
  std::size_t occupied = 0;
  for (const std::uint8_t c : cells) occupied += c != 255 && c >= 3 ? 1 : 0;
  EXPECT_EQ(occupied, truth.worlds(0).occupied_cells());

  // A scan: four returns at 2 m, the others no return; the cloud holds their world-frame end points.
  const v1::RobotSpec spec = bearcat_spec();
  const v1::LaserSpec& laser = spec.sensors(0).laser();
  v1::ClientMessage scan;
  scan.mutable_laser_scan()->set_sensor(spec.sensors(0).name());
  scan.mutable_laser_scan()->set_seq(2);
  scan.mutable_laser_scan()->set_stamp_s(1.5);
  for (int beam = 0; beam < static_cast<int>(laser.beam_count()); ++beam) {
    scan.mutable_laser_scan()->add_ranges(beam % 45 == 0 ? 2.0F : static_cast<float>(laser.range_max_m()));
  }
  driver_->send(scan);
  const ptree cloud = client.next_data(8);
  EXPECT_EQ(cloud.get<int>("point_stride"), 8);
  const auto data = decode_base64(cloud.get<std::string>("data"));
  ASSERT_EQ(data.size(), 5u * 8u);  // beams 0, 45, 90, 135, 180
  const v1::Pose2D pose = truth.robots(0).pose();
  const double mount_x = spec.sensors(0).mount().position().x();
  for (std::size_t k = 0; k < 5; ++k) {
    float xy[2];
    std::memcpy(xy, data.data() + 8 * k, sizeof xy);
    const double bearing =
        pose.theta() + laser.angle_min_rad() + static_cast<double>(45 * k) * laser.angle_increment_rad();
    EXPECT_NEAR(static_cast<double>(xy[0]), pose.x() + mount_x * std::cos(pose.theta()) + 2.0 * std::cos(bearing), 1e-4)
        << k;
    EXPECT_NEAR(static_cast<double>(xy[1]), pose.y() + mount_x * std::sin(pose.theta()) + 2.0 * std::sin(bearing), 1e-4)
        << k;
  }
}

// A Foxglove client sending messages the server does not understand keeps its connection, and cannot fill the
// server's log: 100 bad messages give a handful of warnings, each with the count so far, and the subscription sent
// after them is served.
TEST_F(LiveView, FoxgloveMessagesNotUnderstoodAreLoggedSparinglyAndTheConnectionStaysUsable) {
  FoxgloveClient client(port_);
  ASSERT_EQ(client.next_text().get<std::string>("op"), "serverInfo");
  const ptree advertise = client.next_text();
  int map_channel = -1;
  for (const auto& [unused, channel] : advertise.get_child("channels")) {
    if (channel.get<std::string>("topic") == "/map") map_channel = channel.get<int>("id");
  }
  ASSERT_GE(map_channel, 0);
  constexpr int kBadMessages = 100;
  for (int i = 0; i < kBadMessages; ++i) client.send(R"({"op":"subscribe","subscriptions":"all of them"})");
  client.send(R"({"op":"subscribe","subscriptions":[{"id":3,"channelId":)" + std::to_string(map_channel) + "}]}");
  EXPECT_EQ(client.next_data(3).get<std::string>("frame_id"), "world");

  // Messages are handled in order, so every bad one was seen before the map arrived.
  const std::string log = server_->log();
  std::size_t warnings = 0;
  for (std::size_t at = log.find("foxglove_message_not_understood"); at != std::string::npos;
       at = log.find("foxglove_message_not_understood", at + 1)) {
    ++warnings;
  }
  EXPECT_GE(warnings, 1U) << log;
  EXPECT_LE(warnings, 8U) << "one warning per bad message would be " << kBadMessages << "\n" << log;
  EXPECT_NE(log.find("subscribe without a"), std::string::npos) << log;
}

// The HTTP side follows the socket's rules. An address other than loopback needs the observer token: without it the
// server refuses to start, naming the key. With a token, the page, /metrics and the WebSockets need it (the page's
// script and style carry no data); the live view's WebSocket, which can engage an e-stop, refuses a foreign Origin.
TEST(HttpAccess, AddressBeyondLoopbackNeedsTheObserverToken) {
  TempDir dir;
  const ProcessResult refused = run_process({binary("service/occgeod").string(), "--listen", "127.0.0.1:0",
                                             "--data-dir", dir.path().string(), "--http", "0.0.0.0:0"},
                                            std::chrono::seconds(20));
  EXPECT_EQ(refused.exit_code, 2) << refused.err;
  EXPECT_NE(refused.err.find("http.listen"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("auth.observer_token"), std::string::npos) << refused.err;
}

TEST(HttpAccess, RequestsWithoutTheTokenAndForeignOriginsAreRefused) {
  TempDir dir;
  const auto config = dir.path() / "occgeod.yaml";
  std::ofstream(config) << "auth:\n  observer_token: s3cret\n";
  ServerProcess server(dir.path(), {"--config", config.string(), "--http", "127.0.0.1:0"});
  const std::uint16_t port = http_port(server);
  EXPECT_EQ(http_get(port, "/").status, 401U);
  EXPECT_EQ(http_get(port, "/metrics").status, 401U);
  EXPECT_EQ(http_get(port, "/?token=wrong").status, 401U);
  EXPECT_EQ(http_get(port, "/?token=s3cret").status, 200U);
  EXPECT_EQ(http_get(port, "/metrics?token=s3cret").status, 200U);
  EXPECT_EQ(http_get(port, "/app.js").status, 200U) << "the page's script carries no data";

  // The status of a WebSocket upgrade request (101 when it is taken), sent as a browser would.
  const auto upgrade_status = [&](const std::string& target, const std::string& origin) {
    boost::asio::io_context io;
    beast::tcp_stream stream(io);
    stream.expires_after(std::chrono::seconds(10));
    stream.connect(boost::asio::ip::tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
    beast::http::request<beast::http::empty_body> request{beast::http::verb::get, target, 11};
    request.set(beast::http::field::host, "127.0.0.1:" + std::to_string(port));
    request.set(beast::http::field::connection, "Upgrade");
    request.set(beast::http::field::upgrade, "websocket");
    request.set(beast::http::field::sec_websocket_version, "13");
    request.set(beast::http::field::sec_websocket_key, "dGhlIHNhbXBsZSBub25jZQ==");
    if (!origin.empty()) request.set(beast::http::field::origin, origin);
    beast::http::write(stream, request);
    beast::flat_buffer buffer;
    beast::http::response_parser<beast::http::empty_body> response;
    response.skip(true);  // a 101 has no body; an error's body is not needed
    beast::http::read_header(stream, buffer, response);
    return response.get().result_int();
  };
  const std::string self = "http://127.0.0.1:" + std::to_string(port);
  EXPECT_EQ(upgrade_status("/ws", self), 401U) << "no token";
  EXPECT_EQ(upgrade_status("/ws?token=s3cret", self), 101U);
  EXPECT_EQ(upgrade_status("/ws?token=s3cret", "http://attacker.example"), 403U);
}

// The HTTP side's own connections are capped (http.max_connections): one beyond them is closed at once, and a place
// comes back when a connection ends. Idle connections are what a careless or hostile client leaves open.
TEST(HttpAccess, ConnectionsBeyondTheCapAreClosedAndAPlaceComesBackWhenOneEnds) {
  TempDir dir;
  const auto config = dir.path() / "occgeod.yaml";
  std::ofstream(config) << "http:\n  max_connections: 3\n";
  ServerProcess server(dir.path(), {"--config", config.string(), "--http", "127.0.0.1:0"});
  const std::uint16_t port = http_port(server);
  boost::asio::io_context io;
  std::vector<std::unique_ptr<boost::asio::ip::tcp::socket>> idle;
  for (int i = 0; i < 3; ++i) {
    idle.push_back(std::make_unique<boost::asio::ip::tcp::socket>(io));
    idle.back()->connect({boost::asio::ip::make_address("127.0.0.1"), port});
  }
  // Accepted in order: the request's connection comes after the three idle ones and finds no place.
  EXPECT_THROW(http_get(port, "/metrics"), std::exception);
  idle.front()->close();
  std::optional<HttpResult> metrics;
  for (int attempt = 0; attempt < 100 && !metrics; ++attempt) {
    try {
      metrics = http_get(port, "/metrics");
    } catch (const std::exception&) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
  ASSERT_TRUE(metrics) << "no place came back after an idle connection closed";
  EXPECT_EQ(metrics->status, 200U);
  // At least the one request above was refused (retries while the place came back may have been too).
  std::smatch refused;
  ASSERT_TRUE(std::regex_search(metrics->body, refused, std::regex(R"(occgeo_http_refused_total ([0-9]+))")))
      << metrics->body.substr(0, 2000);
  EXPECT_GE(std::stoi(refused[1]), 1);
  EXPECT_NE(server.log().find("http_connection_refused"), std::string::npos);
}
}  // namespace
}  // namespace occgeo::testing
