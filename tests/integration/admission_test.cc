// Queries are admitted against a bounded backlog: under an overload of query clients some requests are answered
// ERROR_BUSY at once, every request is answered one way or the other, and a robot's driver keeps receiving the
// MotionCommand of each of its scans meanwhile.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <numbers>
#include <thread>
#include <vector>

#include "../support/process.h"
#include "../support/temp_dir.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// What one flooding query client saw.
struct FloodResult {
  std::uint64_t sent = 0;
  std::uint64_t answered = 0;  // replies of the request's own kind
  std::uint64_t busy = 0;      // ERROR_BUSY errors
  std::uint64_t other_errors = 0;
  std::optional<v1::Error> a_busy_error;
  std::uint64_t a_busy_request_id = 0;  // the envelope request_id of a_busy_error's ServerMessage
};

// Keeps `depth` large clearance batches (computed on the query pool) in flight, for `rounds` rounds or until `stop`.
FloodResult flood(const std::string& address, int depth, int rounds, const std::atomic<bool>& stop,
                  std::atomic<std::uint64_t>& sent_by_all, std::atomic<std::uint64_t>& replies_to_all) {
  FloodResult result;
  auto connection = open_query_session(address);
  std::uint64_t request_id = 0;
  for (int round = 0; round < rounds && !stop.load(); ++round) {
    for (int i = 0; i < depth; ++i) {
      v1::ClientMessage message;
      message.set_request_id(++request_id);
      auto* query = message.mutable_clearance_batch();
      query->set_robot_id("bot-1");
      query->set_max_distance_m(3.0);
      for (int p = 0; p < 500; ++p) {
        auto* pose = query->add_poses();
        pose->set_x(-4.0 + 8.0 * static_cast<double>(p % 25) / 25.0);
        pose->set_y(-4.0 + 8.0 * static_cast<double>(p / 25) / 20.0);
        pose->set_theta(0.1 * p);
      }
      connection.send(message);
      ++result.sent;
      ++sent_by_all;
    }
    for (int i = 0; i < depth; ++i) {
      const auto reply = connection.receive(30s);
      if (!reply) return result;  // the count check below reports it
      ++replies_to_all;
      if (reply->has_clearance_batch()) {
        ++result.answered;
      } else if (reply->has_error() && reply->error().code() == v1::ERROR_BUSY) {
        ++result.busy;
        if (!result.a_busy_error) {
          result.a_busy_error = reply->error();
          result.a_busy_request_id = reply->request_id();
        }
      } else {
        ++result.other_errors;
        ADD_FAILURE() << (reply->has_error() ? client::describe(reply->error()) : reply->DebugString());
      }
    }
  }
  return result;
}

TEST(Admission, AQueryOverloadIsToldBusyWhileTheRobotKeepsGettingItsCommands) {
  TempDir dir;
  const auto config = dir.path() / "occgeod.yaml";
  std::ofstream(config) << "limits:\n  max_query_backlog: 4\n";
  ServerProcess server(dir.path(), {"--config", config.string()});

  auto driver = open_driver_session(server.address(), "bot-1");
  std::uint64_t seq = 0;
  // One odometry and scan; true when the scan's own MotionCommand arrived within the (generous) liveness bound.
  auto scan_and_await_command = [&]() {
    ++seq;
    const double t = static_cast<double>(seq) * 0.1;
    const double x = std::cos(t * 0.05);
    const double y = std::sin(t * 0.05);
    const double theta = t * 0.05 + std::numbers::pi / 2.0;
    driver.send(sim::make_odometry_message(seq, t, {x, y, theta}, {0.1, 0.05}));
    driver.send(sim::make_laser_scan_message("front_laser", seq, t, room_ranges(x, y, theta)));
    const auto deadline = Clock::now() + 10s;
    for (int i = 0; i < 100 && Clock::now() < deadline; ++i) {
      const auto reply = driver.receive(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
      if (!reply) return false;
      if (reply->has_error()) ADD_FAILURE() << "driver: " << client::describe(reply->error());
      if (reply->has_motion_command() && reply->motion_command().answers_scan_seq() == seq) return true;
    }
    return false;
  };
  ASSERT_TRUE(scan_and_await_command()) << "the robot is not driven even before the overload";

  constexpr int kFlooders = 8;
  constexpr int kDepth = 24;
  std::atomic<bool> stop{false};
  std::atomic<std::uint64_t> sent_by_all{0};
  std::atomic<std::uint64_t> replies_to_all{0};
  std::vector<FloodResult> results(kFlooders);
  std::vector<std::thread> flooders;
  for (int i = 0; i < kFlooders; ++i) {
    flooders.emplace_back(
        [&, i] { results[i] = flood(server.address(), kDepth, 5000, stop, sent_by_all, replies_to_all); });
  }
  // The overload is on before the robot's scans are measured.
  for (int i = 0; i < 500 && sent_by_all.load() < kFlooders * kDepth; ++i) std::this_thread::sleep_for(10ms);
  // At least kScans scans, and on until the flood has been answered a while meanwhile (a slow machine answers a round
  // of batches slower than a fast one drives 30 scans), bounded by kMaxScans.
  const std::uint64_t replies_before_scans = replies_to_all.load();
  int scans = 0;
  int driven = 0;
  constexpr int kScans = 30;
  constexpr int kMaxScans = 600;
  Clock::duration slowest_command{};
  while (scans < kMaxScans && (scans < kScans || replies_to_all.load() - replies_before_scans < kFlooders * kDepth)) {
    const auto start = Clock::now();
    if (scan_and_await_command()) ++driven;
    slowest_command = std::max(slowest_command, Clock::now() - start);
    ++scans;
  }
  const std::uint64_t replies_during_scans = replies_to_all.load() - replies_before_scans;
  stop = true;
  for (auto& thread : flooders) thread.join();
  std::printf(
      "admission: %d scans driven during the flood, slowest scan-to-command %.1f ms, %llu flood replies meanwhile\n",
      driven, std::chrono::duration<double, std::milli>(slowest_command).count(),
      static_cast<unsigned long long>(replies_during_scans));
  EXPECT_GE(replies_during_scans, static_cast<std::uint64_t>(kFlooders * kDepth))
      << "the overload went on while the robot was driven";

  EXPECT_EQ(driven, scans) << "every scan during the overload must be answered by its MotionCommand";
  FloodResult total;
  for (const FloodResult& r : results) {
    total.sent += r.sent;
    total.answered += r.answered;
    total.busy += r.busy;
    total.other_errors += r.other_errors;
    if (!total.a_busy_error) {
      total.a_busy_error = r.a_busy_error;
      total.a_busy_request_id = r.a_busy_request_id;
    }
  }
  std::printf("admission: %llu queries sent, %llu answered, %llu ERROR_BUSY\n",
              static_cast<unsigned long long>(total.sent), static_cast<unsigned long long>(total.answered),
              static_cast<unsigned long long>(total.busy));
  EXPECT_EQ(total.answered + total.busy + total.other_errors, total.sent) << "every request gets one answer";
  EXPECT_GT(total.busy, 0U) << "an overload of a backlog of 4 must be told ERROR_BUSY";
  EXPECT_GT(total.answered, 0U) << "admitted queries are still answered";
  ASSERT_TRUE(total.a_busy_error.has_value());
  const v1::Error& busy = *total.a_busy_error;
  EXPECT_EQ(busy.field(), "clearance_batch");
  EXPECT_GT(total.a_busy_request_id, 0U);
  EXPECT_GT(busy.retry_after_s(), 0.0);
  const std::string text = client::describe(busy);  // what the CLI prints
  EXPECT_NE(text.find("ERROR_BUSY"), std::string::npos) << text;
  EXPECT_NE(text.find("retry in"), std::string::npos) << text;

  // Once the overload is over the same kind of query is admitted again.
  auto query = open_query_session(server.address());
  v1::ClientMessage status;
  status.mutable_status();
  status.set_request_id(7);
  EXPECT_TRUE(query.call(status, 7).has_status());
}

}  // namespace
}  // namespace occgeo::testing
