// The live view's WebSocket on the real server: the page gets the whole map once, then only the tiles a scan
// changed; robots where the status says they are; the e-stop under the protocol's rule.
// Boost.PropertyTree (the JSON reader here) pulls in boost/bind.hpp, which otherwise warns about its placeholders.
#define BOOST_BIND_GLOBAL_PLACEHOLDERS
#include <gtest/gtest.h>

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/property_tree/json_parser.hpp>
#include <boost/property_tree/ptree.hpp>
#include <map>
#include <regex>
#include <sstream>
#include <thread>

#include "../support/process.h"
#include "occgeo/mapfile/map_file.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

namespace beast = boost::beast;
using boost::property_tree::ptree;

std::uint16_t http_port(const ServerProcess& server) {
  const std::regex pattern(R"re("event":"http_listening".*"port":([0-9]+))re");
  for (int attempt = 0; attempt < 200; ++attempt) {
    std::smatch match;
    const std::string log = server.log();
    if (std::regex_search(log, match, pattern)) return static_cast<std::uint16_t>(std::stoi(match[1]));
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  throw std::runtime_error("occgeod did not log http_listening: " + server.log());
}

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
    request.mutable_status()->set_request_id(++request_id_);
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
  EXPECT_EQ(robot.get<std::string>("behaviour"), truth.behaviour());
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

}  // namespace
}  // namespace occgeo::testing
