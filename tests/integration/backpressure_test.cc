// Slow and hostile clients against ingest: an observer that reads nothing, a client that stops reading, a client
// flooding queries, a controller that vanishes. Ingest latency is printed beside a baseline measured in the same
// run (figures, not assertions); what is asserted is what a user relies on: every scan acknowledged, every event
// accounted for, memory bounded, the robot stopped.
#include <gtest/gtest.h>
#include <sched.h>
#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/write.hpp>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <numbers>
#include <sstream>
#include <thread>
#include <vector>

#include "occgeo/proto/framing.h"
#include "occgeo/proto/protocol.h"
#include "process.h"
#include "raw_client.h"
#include "realtime.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// How long the slow observers read nothing: OCCGEO_SLOW_OBSERVER_S (the acceptance form is 30), default 6 s.
double slow_observer_seconds() {
  const char* text = std::getenv("OCCGEO_SLOW_OBSERVER_S");
  if (text == nullptr) return 6.0;
  const double value = std::atof(text);
  return value > 0.0 && value <= 600.0 ? value : 6.0;
}

std::unique_ptr<ServerProcess> start_server(const TempDir& dir, const std::string& yaml) {
  const auto config = dir.path() / "occgeod.yaml";
  std::ofstream(config) << yaml;
  return std::make_unique<ServerProcess>(dir.path(), std::vector<std::string>{"--config", config.string()});
}

// The server's resident memory in bytes, from /proc (the process whose command line names this data directory).
std::size_t server_rss_bytes(const TempDir& dir) {
  const std::string port_file = (dir.path() / "occgeod.port").string();
  for (const auto& entry : std::filesystem::directory_iterator("/proc")) {
    std::ifstream cmdline(entry.path() / "cmdline");
    std::string args((std::istreambuf_iterator<char>(cmdline)), std::istreambuf_iterator<char>());
    if (args.find("occgeod") == std::string::npos || args.find(port_file) == std::string::npos) continue;
    std::ifstream status(entry.path() / "status");
    std::string line;
    while (std::getline(status, line)) {
      if (line.rfind("VmRSS:", 0) == 0) return std::stoull(line.substr(6)) * 1024;
    }
  }
  return 0;
}

// A driver in lockstep: each scan waits for its ScanAck; the latency of each is kept.
class LockstepDriver {
 public:
  LockstepDriver(const std::string& address, const std::string& robot_id, const std::string& world)
      : connection_(client::Connection::open(client::Endpoint::parse(address))) {
    v1::Hello hello;
    hello.set_protocol_version(proto::kProtocolVersion);
    hello.set_role(v1::ROLE_DRIVER);
    hello.set_robot_id(robot_id);
    hello.set_world(world);
    connection_.hello(hello);
    v1::ClientMessage spec;
    *spec.mutable_robot_spec() = bearcat_spec();
    connection_.send(spec);
  }

  // One odometry + scan along a fixed slow circle; returns false when no ack came within 10 s.
  bool step() {
    ++seq_;
    const double t = static_cast<double>(seq_) * 0.1;
    const double x = 2.0 * std::cos(t * 0.05);
    const double y = 2.0 * std::sin(t * 0.05);
    const double theta = t * 0.05 + std::numbers::pi / 2.0;
    const auto sent = Clock::now();
    connection_.send(sim::make_odometry_message(seq_, t, {x, y, theta}, {0.1, 0.05}));
    connection_.send(sim::make_laser_scan_message("front_laser", seq_, t, room_ranges(x, y, theta)));
    const auto deadline = sent + 10s;
    while (Clock::now() < deadline) {
      const auto reply = connection_.receive(100ms);
      if (!reply) continue;
      if (reply->has_error()) ADD_FAILURE() << client::describe(reply->error());
      if (reply->has_motion_command()) commands_.push_back(reply->motion_command());
      if (reply->has_scan_ack() && reply->scan_ack().seq() == seq_) {
        latencies_us_.push_back(std::chrono::duration<double, std::micro>(Clock::now() - sent).count());
        return true;
      }
    }
    return false;
  }

  // Steps until `seconds` have passed; returns the number of scans acknowledged (stops at the first missing ack).
  std::size_t run_for(double seconds, const std::function<void()>& every_second = {}) {
    const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
    auto next_tick = Clock::now() + 1s;
    std::size_t acked = 0;
    while (Clock::now() < end) {
      if (!step()) return acked;
      ++acked;
      if (every_second && Clock::now() >= next_tick) {
        every_second();
        next_tick += 1s;
      }
    }
    return acked;
  }

  [[nodiscard]] double percentile_us(double p) const {
    if (latencies_us_.empty()) return 0.0;
    std::vector<double> sorted = latencies_us_;
    std::sort(sorted.begin(), sorted.end());
    return sorted[static_cast<std::size_t>(p * static_cast<double>(sorted.size() - 1))];
  }
  [[nodiscard]] std::uint64_t last_seq() const { return seq_; }
  // The motion commands received so far (also those that arrive within `wait`), oldest first; clears them.
  std::vector<v1::MotionCommand> take_commands(std::chrono::milliseconds wait) {
    while (const auto message = connection_.receive(wait)) {
      if (message->has_motion_command()) commands_.push_back(message->motion_command());
    }
    return std::exchange(commands_, {});
  }

 private:
  client::Connection connection_;
  std::uint64_t seq_ = 0;
  std::vector<double> latencies_us_;
  std::vector<v1::MotionCommand> commands_;
};

v1::ClientMessage hello_message(v1::Role role) {
  v1::ClientMessage message;
  message.mutable_hello()->set_protocol_version(proto::kProtocolVersion);
  message.mutable_hello()->set_role(role);
  message.mutable_hello()->set_client_name("backpressure-test");
  return message;
}

v1::ClientMessage watch_message(const std::string& world) {
  v1::ClientMessage message;
  message.set_request_id(1);
  message.mutable_watch()->set_world(world);
  return message;
}

TEST(Backpressure, SlowObserversLoseTheirOldestEventsAndAreToldWhileIngestAndMemoryStayPut) {
  const double seconds = slow_observer_seconds();
  constexpr int kObservers = 8;
  TempDir dir;
  auto server = start_server(dir, "limits:\n  max_watch_queue_messages: 64\n");

  // Side by side in one run: a baseline driver in a world nobody watches and the watched driver in the other world
  // take turns, scan for scan, along the same trajectory, so both see the same machine load and the same map growth
  // (measured one after the other, the ratio swung from 0.92 to 1.27 with the load of the moment).
  LockstepDriver baseline(server->address(), "baseline-bot", "baseline");
  LockstepDriver watched(server->address(), "watched-bot", "watched");

  std::vector<std::unique_ptr<RawClient>> observers;
  for (int i = 0; i < kObservers; ++i) {
    observers.push_back(std::make_unique<RawClient>(server->port()));
    observers.back()->send(hello_message(v1::ROLE_OBSERVER));
    observers.back()->send(watch_message("watched"));
    ASSERT_TRUE(observers.back()->receive(5s)) << "no welcome";
    const auto reply = observers.back()->receive(5s);
    ASSERT_TRUE(reply && reply->has_watch()) << (reply ? reply->DebugString() : "nothing");
    // Then it asks for more than the socket buffers hold (20 windows of 250 000 cells) and reads nothing: its
    // connection is stalled from the first event on, so its event queue fills and drops, as a slow link's would.
    for (std::uint64_t id = 2; id < 22; ++id) {
      v1::ClientMessage window;
      window.set_request_id(id);
      window.mutable_grid_window()->set_world("watched");
      window.mutable_grid_window()->mutable_min_corner()->set_x(-25.0);
      window.mutable_grid_window()->mutable_min_corner()->set_y(-25.0);
      window.mutable_grid_window()->mutable_max_corner()->set_x(24.95);
      window.mutable_grid_window()->mutable_max_corner()->set_y(24.95);
      ASSERT_TRUE(observers.back()->send_within(window, 1000ms));
    }
  }
  // The windows are built on the query pool and queued: memory is measured from once they all are (bounded wait).
  std::size_t rss_before = server_rss_bytes(dir);
  for (int i = 0; i < 25; ++i) {
    std::this_thread::sleep_for(200ms);
    const std::size_t now = server_rss_bytes(dir);
    const bool settled = now < rss_before + (std::size_t{1} << 20);
    rss_before = std::max(rss_before, now);
    if (settled && i >= 2) break;
  }
  std::size_t rss_max = rss_before;
  std::vector<std::size_t> rss_samples;
  std::size_t baseline_scans = 0;
  std::size_t watched_scans = 0;
  const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  auto next_sample = Clock::now() + 1s;
  while (Clock::now() < end) {
    // Which goes first alternates, so neither gains from following the other.
    for (const bool watched_turn : {watched_scans % 2 == 0, watched_scans % 2 != 0}) {
      if (watched_turn) {
        ASSERT_TRUE(watched.step()) << "the watched driver's scan was not acknowledged";
        ++watched_scans;
      } else {
        ASSERT_TRUE(baseline.step()) << "the baseline driver's scan was not acknowledged";
        ++baseline_scans;
      }
    }
    if (Clock::now() >= next_sample) {
      rss_samples.push_back(server_rss_bytes(dir));
      rss_max = std::max(rss_max, rss_samples.back());
      next_sample += 1s;
    }
  }
  ASSERT_GT(watched_scans, 10U);
  const std::size_t rss_after = server_rss_bytes(dir);

  const double base_p50 = baseline.percentile_us(0.5);
  const double watched_p50 = watched.percentile_us(0.5);
  std::printf("slow observers: %d reading nothing for %.0f s\n", kObservers, seconds);
  std::printf("  ingest ack latency  baseline: p50 %.0f us p99 %.0f us (%zu scans)\n", base_p50,
              baseline.percentile_us(0.99), baseline_scans);
  std::printf("  ingest ack latency  observed: p50 %.0f us p99 %.0f us (%zu scans)  p50 ratio %.3f\n", watched_p50,
              watched.percentile_us(0.99), watched_scans, watched_p50 / base_p50);
  std::printf("  server VmRSS: %.1f MiB before, %.1f MiB max, %.1f MiB after; per second:", rss_before / 1048576.0,
              rss_max / 1048576.0, rss_after / 1048576.0);
  for (const std::size_t sample : rss_samples) std::printf(" %.1f", sample / 1048576.0);
  std::printf("\n");

  // Now the observers read: every event is either delivered or counted as dropped, and the newest ones arrive.
  for (int i = 0; i < kObservers; ++i) {
    std::uint64_t received = 0;
    std::uint64_t dropped = 0;
    std::uint64_t last_seq = 0;
    while (last_seq < watched.last_seq()) {
      const auto message = observers[i]->receive(10s);
      ASSERT_TRUE(message) << "observer " << i << " stopped at seq " << last_seq;
      if (!message->has_watch_event()) continue;
      EXPECT_EQ(message->watch_event().robot_id(), "watched-bot");
      EXPECT_GT(message->watch_event().seq(), last_seq);
      ++received;
      dropped += message->watch_event().dropped_since_last();
      last_seq = message->watch_event().seq();
    }
    EXPECT_EQ(received + dropped, watched_scans) << "observer " << i;
    if (i == 0) {
      std::printf("  observer 0: %llu events delivered, %llu dropped (oldest first)\n",
                  static_cast<unsigned long long>(received), static_cast<unsigned long long>(dropped));
    }
  }
  // Queued events are bounded per observer; 64 MiB is far above the models' own growth over this run.
  EXPECT_LT(rss_max, rss_before + (std::size_t{64} << 20));
}

// A client with a tiny receive buffer asks for 40 grid windows of 500 x 500 cells (10 MB of replies, more than the
// loopback socket buffers hold, less than limits.max_send_queue_bytes) and reads nothing: the server's write stalls
// and the write timeout, not the queue limit, ends the session, while a driver goes on being served.
TEST(Backpressure, AClientThatStopsReadingIsDisconnectedAfterTheWriteTimeout) {
  TempDir dir;
  auto server = start_server(dir, "limits:\n  write_timeout_s: 1.0\n");
  RawClient stalled(server->port(), 2048);
  stalled.send(hello_message(v1::ROLE_QUERY));
  LockstepDriver driver(server->address(), "bot", "default");
  const std::size_t warmup_acked = driver.run_for(0.3);
  ASSERT_EQ(warmup_acked, driver.last_seq());
  for (std::uint64_t id = 1; id <= 40; ++id) {
    v1::ClientMessage window;
    window.set_request_id(id);
    window.mutable_grid_window()->mutable_min_corner()->set_x(-25.0);
    window.mutable_grid_window()->mutable_min_corner()->set_y(-25.0);
    window.mutable_grid_window()->mutable_max_corner()->set_x(24.95);
    window.mutable_grid_window()->mutable_max_corner()->set_y(24.95);
    if (!stalled.send_within(window, 1000ms)) break;
  }
  const auto start = Clock::now();
  bool dropped = false;
  while (Clock::now() < start + 15s && !dropped) {
    ASSERT_TRUE(driver.step());  // ingest goes on meanwhile
    dropped = server->log().find("session_write_timeout") != std::string::npos;
  }
  EXPECT_TRUE(dropped) << server->log();
  EXPECT_EQ(server->log().find("session_slow_client_dropped"), std::string::npos)
      << "the queue limit, not the write timeout, ended the session";
  const double after_s = std::chrono::duration<double>(Clock::now() - start).count();
  std::printf("stalled client dropped %.2f s after its requests (write_timeout_s 1.0)\n", after_s);
  // What the kernel had buffered drains, then the stream ends.
  for (int i = 0; i < 100000 && !stalled.closed(); ++i) {
    if (!stalled.receive(2s)) break;
  }
  EXPECT_TRUE(stalled.closed());
}

TEST(Backpressure, AQueryFloodDoesNotStarveIngestOrOtherClients) {
  TempDir dir;
  auto server = start_server(dir, "log_level: info\n");
  LockstepDriver driver(server->address(), "bot", "default");
  constexpr std::size_t kScans = 300;
  for (std::size_t i = 0; i < kScans; ++i) ASSERT_TRUE(driver.step());
  const double quiet_p50 = driver.percentile_us(0.5);

  // The flooder sends collision queries as fast as TCP lets it and reads nothing back.
  std::atomic<bool> stop{false};
  std::atomic<std::uint64_t> flood_sent{0};
  std::thread flooder([&] {
    RawClient client(server->port());
    client.send(hello_message(v1::ROLE_QUERY));
    v1::ClientMessage query;
    auto* collision = query.mutable_collision();
    collision->set_robot_id("bot");
    while (!stop.load()) {
      query.set_request_id(flood_sent.load() + 1);
      if (!client.send_within(query, 200ms)) continue;
      ++flood_sent;
    }
  });
  std::this_thread::sleep_for(300ms);

  LockstepDriver flooded(server->address(), "bot-2", "default");
  auto polite = open_query_session(server->address());
  std::size_t polite_answers = 0;
  double polite_worst_ms = 0.0;
  for (std::size_t i = 0; i < kScans; ++i) {
    ASSERT_TRUE(flooded.step()) << "scan " << i << " not acknowledged during the flood";
    if (i % 10 == 0) {
      v1::ClientMessage status;
      status.mutable_status();
      status.set_request_id(i + 1);
      const auto asked = Clock::now();
      const auto reply = polite.call(status, i + 1, 5s);
      polite_worst_ms =
          std::max(polite_worst_ms, std::chrono::duration<double, std::milli>(Clock::now() - asked).count());
      if (reply.has_status()) ++polite_answers;
    }
  }
  stop = true;
  flooder.join();
  EXPECT_EQ(polite_answers, kScans / 10);
  std::printf(
      "query flood: %llu queries sent unread; ingest ack p50 %.0f us flooded vs %.0f us quiet; "
      "another client's worst status reply %.1f ms\n",
      static_cast<unsigned long long>(flood_sent.load()), flooded.percentile_us(0.5), quiet_p50, polite_worst_ms);
  EXPECT_TRUE(server->running());
}

// A driver's session moves to the driver loop (queries.driver_loop) right after its hello, also when the spec and
// the first scans arrive in the same write as the hello: they are handled after the move, in order, and answered
// after the welcome. With the loop off the same bytes get the same answers.
TEST(Backpressure, ADriversFramesBehindItsHelloInOneWriteAreAnsweredInOrderAfterItMovesToTheDriverLoop) {
  for (const bool driver_loop : {true, false}) {
    SCOPED_TRACE(driver_loop ? "driver loop" : "no driver loop");
    TempDir dir;
    auto server = start_server(
        dir, std::string("log_level: debug\nqueries:\n  driver_loop: ") + (driver_loop ? "true" : "false") + "\n");
    RawClient client(server->port(), 1 << 20);
    std::string burst;
    v1::ClientMessage hello;
    *hello.mutable_hello() = sim::make_driver_hello("bot", "");
    proto::append_frame(hello, burst);
    v1::ClientMessage spec;
    *spec.mutable_robot_spec() = bearcat_spec();
    proto::append_frame(spec, burst);
    constexpr std::uint64_t kScans = 3;
    for (std::uint64_t seq = 1; seq <= kScans; ++seq) {
      const double t = 0.1 * static_cast<double>(seq);
      proto::append_frame(sim::make_odometry_message(seq, t, {0.0, 0.0, 0.0}, {0.0, 0.0}), burst);
      proto::append_frame(sim::make_laser_scan_message("front_laser", seq, t, room_ranges(0.0, 0.0, 0.0)), burst);
    }
    client.send_bytes(burst);
    const auto first = client.receive(5s);
    ASSERT_TRUE(first && first->has_welcome()) << (first ? first->DebugString() : "nothing");
    std::vector<std::uint64_t> acked;
    std::size_t commands = 0;
    for (int i = 0; i < 50 && acked.size() < kScans; ++i) {
      const auto reply = client.receive(5s);
      ASSERT_TRUE(reply) << "no answer after " << acked.size() << " acks";
      ASSERT_FALSE(reply->has_error()) << reply->DebugString();
      if (reply->has_scan_ack()) acked.push_back(reply->scan_ack().seq());
      if (reply->has_motion_command()) ++commands;
    }
    EXPECT_EQ(acked, (std::vector<std::uint64_t>{1, 2, 3}));
    EXPECT_GE(commands, 1U) << "the server steered the robot from its scans";
    const bool moved = server->log().find("session_moved_to_driver_loop") != std::string::npos;
    EXPECT_EQ(moved, driver_loop);
  }
}

// One numeric field of each of the process's threads' /proc stat (numbered as proc(5) does, counted after the command
// name, which may hold spaces): 19 is the niceness, 41 the scheduling policy (SCHED_OTHER, SCHED_FIFO, ...).
std::vector<int> thread_stat_field(pid_t pid, int number) {
  std::vector<int> values;
  for (const auto& task : std::filesystem::directory_iterator("/proc/" + std::to_string(pid) + "/task")) {
    std::ifstream stat(task.path() / "stat");
    std::string text((std::istreambuf_iterator<char>(stat)), std::istreambuf_iterator<char>());
    std::istringstream after_name(text.substr(text.rfind(')') + 2));
    std::string field;
    for (int i = 3; i <= number && after_name >> field; ++i) {
      if (i == number) values.push_back(std::stoi(field));
    }
  }
  return values;
}
std::vector<int> thread_niceness(pid_t pid) { return thread_stat_field(pid, 19); }
std::vector<int> thread_policies(pid_t pid) { return thread_stat_field(pid, 41); }

// The network threads answer queries inline, and the query pool computes the larger ones, at queries.network_nice
// below the process's priority; every other thread (ingest and control, journal) keeps the process's own, so a query
// flood yields the CPU to the robot's data.
TEST(Backpressure, OnlyTheQueryThreadsRunAtTheLowerQueryPriorityAndTheOctreeLaneAtItsOwn) {
  constexpr long kQueryPoolThreads = 2;
  constexpr int kLaneNice = 2;
  const int own = getpriority(PRIO_PROCESS, 0);
  for (const int nice : {0, 7}) {
    TempDir dir;
    auto server = start_server(dir, "queries:\n  network_threads: 3\n  network_nice: " + std::to_string(nice) +
                                        "\noctomap:\n  lane_nice: " + std::to_string(kLaneNice) + "\n");
    // The network threads lower their own priority as they start serving, just after the server listens.
    std::vector<int> niceness;
    long lowered = 0;
    for (int attempt = 0; attempt < 100; ++attempt) {
      niceness = thread_niceness(server->pid());
      lowered = std::count(niceness.begin(), niceness.end(), std::min(own + nice, 19));
      if (nice == 0 || lowered == 3 + kQueryPoolThreads) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ASSERT_GT(niceness.size(), 4U);
    const auto kept = std::count(niceness.begin(), niceness.end(), own);
    // The octree's lane thread: below the ingest strand, whatever the queries' niceness.
    EXPECT_EQ(std::count(niceness.begin(), niceness.end(), std::min(own + kLaneNice, 19)), 1);
    if (nice == 0) {
      EXPECT_EQ(kept, static_cast<long>(niceness.size()) - 1);
    } else {
      EXPECT_EQ(lowered, 3 + kQueryPoolThreads) << "one lowered thread per network thread and query pool thread";
      EXPECT_EQ(kept, static_cast<long>(niceness.size()) - 3 - kQueryPoolThreads - 1);
    }
  }
}

// The two threads that turn a robot's scan into its command (the ingest strands' and the drivers' loop) run under
// SCHED_FIFO at control.realtime_priority, every other thread under the normal policy; where the process may not
// (no CAP_SYS_NICE) the server says so in its log and goes on; 0 leaves them all normal.
TEST(Backpressure, TheCommandPathRunsAtRealtimePriorityWhenThePlatformAllowsIt) {
  const bool allowed = may_run_realtime(10);  // the priority tested below
  for (const int priority : {10, 0}) {
    TempDir dir;
    auto server = start_server(dir, "control:\n  realtime_priority: " + std::to_string(priority) + "\n");
    LockstepDriver driver(server->address(), "bot", "default");
    ASSERT_TRUE(driver.step());  // the driver's session is on its loop, whose thread set its policy first
    std::vector<int> policies = thread_policies(server->pid());
    ASSERT_GT(policies.size(), 4U);
    const auto realtime = std::count(policies.begin(), policies.end(), SCHED_FIFO);
    if (priority == 0) {
      EXPECT_EQ(realtime, 0);
    } else if (allowed) {
      EXPECT_EQ(realtime, 2) << "the ingest strands' thread and the drivers' loop";
      EXPECT_EQ(std::count(policies.begin(), policies.end(), SCHED_OTHER), static_cast<long>(policies.size()) - 2);
    } else {
      EXPECT_EQ(realtime, 0);
      EXPECT_NE(server->log().find("ingest_realtime_not_applied"), std::string::npos) << server->log();
      EXPECT_NE(server->log().find("driver_loop_realtime_not_applied"), std::string::npos) << server->log();
    }
  }
}

TEST(Backpressure, AControllerThatVanishesLeavesTheRobotStopped) {
  TempDir dir;
  auto server = start_server(dir, "log_level: info\n");
  LockstepDriver driver(server->address(), "bot", "default");
  ASSERT_TRUE(driver.step());

  // The controller takes a 1 s lease, sets teleop, then falls silent with its socket open (a hung process or a
  // cut cable: no FIN ever comes).
  RawClient controller(server->port());
  controller.send(hello_message(v1::ROLE_CONTROLLER));
  v1::ClientMessage lease;
  lease.set_request_id(1);
  lease.mutable_lease()->set_robot_id("bot");
  lease.mutable_lease()->set_action(v1::LeaseRequest::ACQUIRE);
  lease.mutable_lease()->set_timeout_s(1.0);
  controller.send(lease);
  v1::ClientMessage drive;
  drive.set_request_id(2);
  drive.mutable_drive()->set_robot_id("bot");
  drive.mutable_drive()->set_behaviour(v1::BEHAVIOUR_TELEOP);
  drive.mutable_drive()->set_linear_mps(0.4);
  controller.send(drive);
  bool granted = false;
  for (int i = 0; i < 20 && !granted; ++i) {
    const auto reply = controller.receive(500ms);
    granted = reply && reply->has_drive();
  }
  ASSERT_TRUE(granted);

  // The robot is driven, then stopped within the lease timeout plus the watchdog's latency.
  const auto silent_from = Clock::now();
  bool moving = false;
  bool stopped_after_moving = false;
  double stopped_after_s = 0.0;
  while (Clock::now() < silent_from + 5s && !stopped_after_moving) {
    ASSERT_TRUE(driver.step());
    for (const auto& command : driver.take_commands(10ms)) {
      if (!command.stop() && command.linear_mps() > 0.1) moving = true;
      if (moving && command.stop()) {
        stopped_after_moving = true;
        stopped_after_s = std::chrono::duration<double>(Clock::now() - silent_from).count();
      }
    }
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_TRUE(moving);
  EXPECT_TRUE(stopped_after_moving) << server->log();
  EXPECT_LT(stopped_after_s, 2.0);
  std::printf("silent controller: robot stopped %.2f s after the controller fell silent (lease 1.0 s)\n",
              stopped_after_s);
}

}  // namespace
}  // namespace occgeo::testing
