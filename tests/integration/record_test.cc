// Recording a session: the observers' data subscription (WatchRequest.with_data) against the real server, and
// `occgeo record` writing MCAP that `occgeo replay --format mcap` turns back into the same map.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <numbers>
#include <thread>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/write.hpp>

#include "occgeo/proto/framing.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/replay/mcap.h"
#include "process.h"
#include "raw_client.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

using namespace std::chrono_literals;

client::Connection open_observer(const std::string& address, bool with_data, const std::string& robot_id = "") {
  auto connection = client::Connection::open(client::Endpoint::parse(address));
  v1::Hello hello;
  hello.set_protocol_version(proto::kProtocolVersion);
  hello.set_role(v1::ROLE_OBSERVER);
  hello.set_client_name("record-test");
  connection.hello(hello);
  v1::ClientMessage watch;
  watch.set_request_id(7);
  watch.mutable_watch()->set_robot_id(robot_id);
  watch.mutable_watch()->set_with_data(with_data);
  EXPECT_TRUE(connection.call(watch, 7).has_watch());
  return connection;
}

// A driver sending `scans` odometry + scan pairs in lockstep; returns the commands it received.
std::vector<v1::MotionCommand> drive(client::Connection& driver, int scans, int first_seq = 1) {
  std::vector<v1::MotionCommand> commands;
  for (int seq = first_seq; seq < first_seq + scans; ++seq) {
    const double t = seq * 0.1;
    const geometry::Pose2 X_WB{0.5 * std::cos(t), 0.5 * std::sin(t), t};
    driver.send(sim::make_odometry_message(static_cast<std::uint64_t>(seq), t, X_WB, {0.1, 0.1}));
    driver.send(sim::make_laser_scan_message("front_laser", static_cast<std::uint64_t>(seq), t,
                                             room_ranges(X_WB.x, X_WB.y, X_WB.theta)));
    bool acked = false;
    const auto deadline = std::chrono::steady_clock::now() + 10s;
    while (!acked && std::chrono::steady_clock::now() < deadline) {
      const auto reply = driver.receive(100ms);
      if (!reply) continue;
      EXPECT_FALSE(reply->has_error()) << reply->DebugString();
      if (reply->has_motion_command()) commands.push_back(reply->motion_command());
      acked = reply->has_scan_ack() && reply->scan_ack().seq() == static_cast<std::uint64_t>(seq);
    }
    EXPECT_TRUE(acked) << "scan " << seq << " not acknowledged";
  }
  while (const auto reply = driver.receive(300ms)) {
    if (reply->has_motion_command()) commands.push_back(reply->motion_command());
  }
  return commands;
}

std::vector<v1::WatchEvent> drain_events(client::Connection& observer) {
  std::vector<v1::WatchEvent> events;
  while (const auto message = observer.receive(500ms)) {
    if (message->has_watch_event()) events.push_back(message->watch_event());
  }
  return events;
}

TEST(ObserverData, ADataWatcherGetsTheSpecEveryAcceptedMessageWithItsPlacementAndTheCommandsInOrder) {
  TempDir dir;
  ServerProcess server(dir.path());
  // One robot registered before the watcher subscribes (its spec comes at once), one after (its spec comes when sent).
  auto early = open_driver_session(server.address(), "early-bot");
  auto data_watcher = open_observer(server.address(), true);
  auto ack_watcher = open_observer(server.address(), false);
  auto late = open_driver_session(server.address(), "late-bot");
  constexpr int kScans = 12;
  const auto commands = drive(late, kScans);
  ASSERT_FALSE(commands.empty());

  const auto events = drain_events(data_watcher);
  std::vector<std::string> specs;
  std::vector<std::uint64_t> odometry_seqs, scan_seqs, command_seqs;
  for (const auto& event : events) {
    if (event.has_robot_spec()) specs.push_back(event.robot_id());
    if (event.robot_id() != "late-bot") continue;
    if (event.has_odometry()) {
      odometry_seqs.push_back(event.odometry().seq());
      EXPECT_EQ(specs.back(), "late-bot") << "the robot's data came before its spec";
    }
    if (event.has_laser_scan()) {
      scan_seqs.push_back(event.seq());
      ASSERT_EQ(event.laser_scan().ranges_size(), 181);
      // Placed at the odometry pose sent just before it, with the grid cells it may have changed.
      const double t = static_cast<double>(event.seq()) * 0.1;
      EXPECT_NEAR(event.pose().x(), 0.5 * std::cos(t), 1e-9);
      EXPECT_NEAR(event.pose().y(), 0.5 * std::sin(t), 1e-9);
      ASSERT_TRUE(event.has_changed_cells());
      EXPECT_LT(event.changed_cells().min().ix(), event.changed_cells().max().ix());
      EXPECT_GT(event.cell_size_m(), 0.0);
      EXPECT_GT(event.world_version(), 0U);
    }
    if (event.has_motion_command()) command_seqs.push_back(event.motion_command().seq());
    EXPECT_EQ(event.dropped_since_last(), 0U);
  }
  EXPECT_EQ(specs, (std::vector<std::string>{"early-bot", "late-bot"}));
  std::vector<std::uint64_t> expected(kScans);
  for (int i = 0; i < kScans; ++i) expected[static_cast<std::size_t>(i)] = static_cast<std::uint64_t>(i + 1);
  EXPECT_EQ(odometry_seqs, expected);
  EXPECT_EQ(scan_seqs, expected);
  // Every command the driver received, in order (the sensor watchdog's stop may follow once the driver falls silent).
  ASSERT_GE(command_seqs.size(), commands.size());
  for (std::size_t i = 0; i < commands.size(); ++i) EXPECT_EQ(command_seqs[i], commands[i].seq());

  // The ack-only watcher is unchanged: one event per acknowledged scan, no data.
  const auto acks = drain_events(ack_watcher);
  ASSERT_EQ(acks.size(), static_cast<std::size_t>(kScans));
  for (const auto& event : acks) EXPECT_EQ(event.data_case(), v1::WatchEvent::DATA_NOT_SET);
}

TEST(ObserverData, AWatcherOfOneRobotGetsNothingOfAnother) {
  TempDir dir;
  ServerProcess server(dir.path());
  auto watcher = open_observer(server.address(), true, "watched-bot");
  auto other = open_driver_session(server.address(), "other-bot");
  drive(other, 3);
  EXPECT_TRUE(drain_events(watcher).empty());
}

TEST(ObserverData, ASlowDataWatcherLosesItsOldestEventsIsToldHowManyAndTheDriverIsNotHeldUp) {
  TempDir dir;
  const auto config = dir.path() / "occgeod.yaml";
  std::ofstream(config) << "limits:\n  max_watch_queue_messages: 8\n";
  ServerProcess server(dir.path(), {"--config", config.string()});
  RawClient watcher(server.port());
  v1::ClientMessage hello;
  hello.mutable_hello()->set_protocol_version(proto::kProtocolVersion);
  hello.mutable_hello()->set_role(v1::ROLE_OBSERVER);
  watcher.send(hello);
  v1::ClientMessage watch;
  watch.set_request_id(1);
  watch.mutable_watch()->set_with_data(true);
  watcher.send(watch);
  ASSERT_TRUE(watcher.receive(5s)) << "no welcome";
  auto driver = open_driver_session(server.address(), "busy-bot");
  drive(driver, 20);
  // Then it asks for more than the socket buffers hold (30 windows of 250 000 cells) and reads nothing, as a slow
  // link would: its event queue fills and drops.
  for (std::uint64_t id = 2; id < 32; ++id) {
    v1::ClientMessage window;
    window.set_request_id(id);
    window.mutable_grid_window()->mutable_min_corner()->set_x(-25.0);
    window.mutable_grid_window()->mutable_min_corner()->set_y(-25.0);
    window.mutable_grid_window()->mutable_max_corner()->set_x(24.95);
    window.mutable_grid_window()->mutable_max_corner()->set_y(24.95);
    watcher.send(window);
  }
  // Every scan is still acknowledged within its bound (drive() checks each).
  constexpr int kScans = 200;
  drive(driver, kScans - 20, 21);
  std::uint64_t events = 0;
  std::uint64_t dropped = 0;
  std::uint64_t last_scan_seq = 0;
  while (const auto message = watcher.receive(2s)) {
    if (!message->has_watch_event()) continue;
    ++events;
    dropped += message->watch_event().dropped_since_last();
    if (message->watch_event().has_laser_scan()) last_scan_seq = message->watch_event().seq();
  }
  EXPECT_GT(dropped, 0U) << "the stalled watcher lost nothing: the test did not stall it";
  // Spec, then odometry, scan and command per step: each event is delivered or counted as dropped.
  EXPECT_GE(events + dropped, static_cast<std::uint64_t>(3 * kScans + 1));
  // The newest are kept: the last scan's event arrives.
  EXPECT_EQ(last_scan_seq, static_cast<std::uint64_t>(kScans));
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

// `occgeo map export` of `world` as PGM bytes.
std::string exported_map(const ServerProcess& server, const std::filesystem::path& prefix) {
  const auto result = run_process({binary("clients/occgeo").string(), "map", "export", "--server", server.address(),
                                   "--world", "default", "--out", prefix.string()},
                                  60s);
  EXPECT_EQ(result.exit_code, 0) << result.err;
  return read_file(prefix.string() + ".pgm");
}

TEST(Record, TheMapRebuiltFromARecordingEqualsTheLiveOne) {
  TempDir dir;
  std::filesystem::create_directories(dir.path() / "live");
  std::filesystem::create_directories(dir.path() / "fresh");
  ServerProcess live(dir.path() / "live");
  const auto file = dir.path() / "session.mcap";
  BackgroundProcess record(
      {binary("clients/occgeo").string(), "record", "--out", file.string(), "--server", live.address()},
      dir.path() / "record.out", dir.path() / "record.err");
  // The recorder is attached once the server logs its watch.
  for (int i = 0; i < 100 && live.log().find("session_watch") == std::string::npos; ++i)
    std::this_thread::sleep_for(50ms);
  ASSERT_NE(live.log().find("session_watch"), std::string::npos) << read_file(dir.path() / "record.err");
  // A bounded run: 30 s of simulated time in lockstep through the corridor, steered by the server.
  const auto sim = run_process(
      {binary("clients/sim/occgeo-sim").string(), "--world", source("clients/sim/worlds/corridor.yaml").string(),
       "--server", live.address(), "--lockstep", "--duration", "30"},
      120s);
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  std::this_thread::sleep_for(500ms);  // the last events reach the recorder
  // Ctrl-C closes the file cleanly.
  ASSERT_EQ(record.stop(SIGINT, 20s), 0) << read_file(dir.path() / "record.err");
  EXPECT_NE(read_file(dir.path() / "record.err").find("messages"), std::string::npos);
  const std::string live_map = exported_map(live, dir.path() / "live-map");
  ASSERT_FALSE(live_map.empty());

  // The recording's /default/grid (the whole window of changed cells, then the changed blocks) rebuilds the live grid.
  std::map<std::pair<std::int32_t, std::int32_t>, std::uint8_t> recorded;
  auto paint = [&](const v1::CellIndex& min, std::uint32_t width, std::uint32_t height, const std::string& cells) {
    ASSERT_EQ(cells.size(), static_cast<std::size_t>(width) * height);
    for (std::uint32_t row = 0; row < height; ++row) {
      for (std::uint32_t col = 0; col < width; ++col) {
        recorded[{min.ix() + static_cast<std::int32_t>(col), min.iy() + static_cast<std::int32_t>(row)}] =
            static_cast<std::uint8_t>(cells[static_cast<std::size_t>(row) * width + col]);
      }
    }
  };
  std::size_t grid_messages = 0;
  replay::McapReader reader(file);
  while (const auto message = reader.next()) {
    if (message->channel->topic != "/default/grid") continue;
    v1::GridWindowReply window;
    ASSERT_TRUE(window.ParseFromArray(message->data.data(), static_cast<int>(message->data.size())));
    if (grid_messages++ == 0) paint(window.min_cell(), window.width(), window.height(), window.cells());
    for (const auto& block : window.changed()) paint(block.min_cell(), block.width(), block.height(), block.cells());
  }
  EXPECT_GE(grid_messages, 2U) << "the grid's changes were not followed during the run";
  auto query = open_query_session(live.address());
  v1::ClientMessage request;
  request.set_request_id(1);
  request.mutable_grid()->set_world("default");
  const v1::GridReply grid = query.call(request, 1).grid();
  std::size_t observed = 0;
  std::size_t differing = 0;
  for (std::uint32_t row = 0; row < grid.height(); ++row) {
    for (std::uint32_t col = 0; col < grid.width(); ++col) {
      const auto value = static_cast<std::uint8_t>(grid.cells()[static_cast<std::size_t>(row) * grid.width() + col]);
      if (value == 255) continue;
      ++observed;
      const auto it = recorded.find({grid.min_cell().ix() + static_cast<std::int32_t>(col),
                                     grid.min_cell().iy() + static_cast<std::int32_t>(row)});
      if (it == recorded.end() || it->second != value) ++differing;
    }
  }
  EXPECT_GT(observed, 1000U);
  EXPECT_EQ(differing, 0U) << "of " << observed << " observed cells, the recorded grid differs in " << differing;

  ServerProcess fresh(dir.path() / "fresh");
  const auto replay = run_process({binary("clients/occgeo").string(), "replay", "--format", "mcap", file.string(),
                                   "--max", "--json", "--server", fresh.address()},
                                  240s);
  ASSERT_EQ(replay.exit_code, 0) << replay.err;
  EXPECT_NE(replay.out.find("\"errors\":0"), std::string::npos) << replay.out;
  EXPECT_NE(replay.out.find("\"scans\":300,\"scans_acked\":300"), std::string::npos) << replay.out;
  const std::string replayed_map = exported_map(fresh, dir.path() / "replayed-map");
  EXPECT_EQ(replayed_map.size(), live_map.size());
  EXPECT_TRUE(replayed_map == live_map) << "the replayed map differs from the live one";
}

TEST(Record, TwoRobotsMappingOneWorldAtOnceReplayIntoTheSameMap) {
  TempDir dir;
  std::filesystem::create_directories(dir.path() / "live");
  std::filesystem::create_directories(dir.path() / "fresh");
  ServerProcess live(dir.path() / "live");
  const auto file = dir.path() / "two.mcap";
  BackgroundProcess record({binary("clients/occgeo").string(), "record", "--out", file.string(), "--compression", "lz4",
                            "--server", live.address()},
                           dir.path() / "record.out", dir.path() / "record.err");
  for (int i = 0; i < 100 && live.log().find("session_watch") == std::string::npos; ++i) {
    std::this_thread::sleep_for(50ms);
  }
  ASSERT_NE(live.log().find("session_watch"), std::string::npos) << read_file(dir.path() / "record.err");
  // Both at once, interleaving on the world's strand in an order only the recording knows.
  auto sim_args = [&](const std::string& id, const std::string& start) {
    return std::vector<std::string>{binary("clients/sim/occgeo-sim").string(),
                                    "--world",
                                    source("clients/sim/worlds/corridor.yaml").string(),
                                    "--server",
                                    live.address(),
                                    "--id",
                                    id,
                                    "--start",
                                    start,
                                    "--lockstep",
                                    "--duration",
                                    "20"};
  };
  BackgroundProcess second(sim_args("second", "3,0,0"), dir.path() / "second.out", dir.path() / "second.err");
  const auto first = run_process(sim_args("first", "0,0,0"), 120s);
  ASSERT_EQ(first.exit_code, 0) << first.err;
  for (int i = 0; i < 1200 && second.running(); ++i) std::this_thread::sleep_for(100ms);
  ASSERT_EQ(second.stop(SIGTERM, 5s), 0) << read_file(dir.path() / "second.err");
  std::this_thread::sleep_for(500ms);
  ASSERT_EQ(record.stop(SIGTERM, 20s), 0) << read_file(dir.path() / "record.err");
  const std::string live_map = exported_map(live, dir.path() / "live-map");

  ServerProcess fresh(dir.path() / "fresh");
  const auto replay = run_process({binary("clients/occgeo").string(), "replay", "--format", "mcap", file.string(),
                                   "--max", "--json", "--server", fresh.address()},
                                  240s);
  ASSERT_EQ(replay.exit_code, 0) << replay.err;
  EXPECT_NE(replay.out.find("\"scans\":400,\"scans_acked\":400"), std::string::npos) << replay.out;
  EXPECT_NE(replay.err.find("robot first of the recording"), std::string::npos) << replay.err;
  EXPECT_NE(replay.err.find("robot second of the recording"), std::string::npos) << replay.err;
  EXPECT_TRUE(exported_map(fresh, dir.path() / "replayed-map") == live_map)
      << "the map replayed from two robots differs from the live one";
}

TEST(Record, DurationEndsTheRecordingWithAValidFileHoldingTheRobotsAlreadyThere) {
  TempDir dir;
  std::filesystem::create_directories(dir.path() / "server");
  ServerProcess server(dir.path() / "server");
  auto driver = open_driver_session(server.address(), "parked-bot");
  drive(driver, 3);
  const auto file = dir.path() / "parked.mcap";
  const auto result = run_process({binary("clients/occgeo").string(), "record", "--out", file.string(), "--duration",
                                   "1", "--compression", "none", "--json", "--server", server.address()},
                                  30s);
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("\"dropped\":0"), std::string::npos) << result.out;
  EXPECT_NE(result.err.find("wrote "), std::string::npos) << result.err;
  const std::string bytes = read_file(file);
  ASSERT_GT(bytes.size(), 16U);
  EXPECT_EQ(bytes.substr(bytes.size() - 8), std::string("\x89MCAP0\r\n", 8)) << "no closing magic: file not closed";
  EXPECT_NE(bytes.find("/default/parked-bot/robot_spec"), std::string::npos) << "the parked robot's spec is missing";
}

TEST(Record, BadOptionsAndAnUnreachableServerAreErrorsNamingWhatWasWrong) {
  TempDir dir;
  const auto no_out = run_process({binary("clients/occgeo").string(), "record", "--duration", "1"}, 30s);
  EXPECT_EQ(no_out.exit_code, 2);
  EXPECT_NE(no_out.err.find("--out"), std::string::npos) << no_out.err;
  const auto bad = run_process(
      {binary("clients/occgeo").string(), "record", "--out", (dir.path() / "x.mcap").string(), "--compression", "gzip"},
      30s);
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("gzip"), std::string::npos) << bad.err;
  const auto unreachable = run_process({binary("clients/occgeo").string(), "record", "--out",
                                        (dir.path() / "y.mcap").string(), "--server", "127.0.0.1:1"},
                                       30s);
  EXPECT_EQ(unreachable.exit_code, 1);
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "y.mcap")) << "a refused recording left a file behind";
}

}  // namespace
}  // namespace occgeo::testing
