// Figures for the durability policies, printed in one run (no wall-clock assertions): ingest cost per scan for
// `every`, `batch` (5 ms) and `none` — pipelined (the driver sends without waiting, so group commit can gather) and in
// lockstep (each scan waits for its ack) — and the restart time for a journal of N scans.
#include <gtest/gtest.h>

#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <vector>

#include "fault_support.h"

namespace occgeo::testing {
namespace {

using Clock = std::chrono::steady_clock;

double micros(Clock::duration d) { return std::chrono::duration<double, std::micro>(d).count(); }

// Sends `count` steps of robot alpha without waiting, then waits for every ack; µs per scan from first send to last
// ack.
double pipelined_us_per_scan(const std::string& address, std::uint64_t first_seq, int count, std::mt19937& random) {
  auto connection = open_driver_session(address, "alpha");
  std::vector<Step> steps;
  for (int k = 0; k < count; ++k) steps.push_back(make_step(0, first_seq + static_cast<std::uint64_t>(k), random));
  const auto started = Clock::now();
  for (const Step& step : steps) {
    connection.send(step.odometry);
    connection.send(step.scan);
  }
  // Acks come in the order the scans were sent (the batch policy once let a scan found durable at once overtake the
  // acks its group commit was still sending, and a driver waiting for each ack in turn then waited forever).
  for (const Step& step : steps) {
    const auto reply = next_sensor_reply(connection, std::chrono::seconds(60));
    if (!reply) throw std::runtime_error("a pipelined scan was not acknowledged within 60 s");
    if (!reply->has_scan_ack()) throw std::runtime_error("a pipelined scan was refused: " + reply->DebugString());
    if (reply->scan_ack().seq() != step.scan.laser_scan().seq()) {
      throw std::runtime_error("the ack of scan " + std::to_string(reply->scan_ack().seq()) + " overtook scan " +
                               std::to_string(step.scan.laser_scan().seq()) + "'s");
    }
  }
  return micros(Clock::now() - started) / count;
}

// Mean µs from sending a scan to its ack, one at a time.
double lockstep_us_per_scan(const std::string& address, std::uint64_t first_seq, int count, std::mt19937& random) {
  auto connection = open_driver_session(address, "beta");
  double total_us = 0;
  for (int k = 0; k < count; ++k) {
    const Step step = make_step(1, first_seq + static_cast<std::uint64_t>(k), random);
    connection.send(step.odometry);
    const auto started = Clock::now();
    connection.send(step.scan);
    const auto reply = await_reply(connection, step.scan.laser_scan().seq());
    if (!reply || !reply->has_scan_ack()) throw std::runtime_error("a lockstep scan was not acknowledged");
    total_us += micros(Clock::now() - started);
  }
  return total_us / count;
}

TEST(DurabilityFigures, IngestCostPerPolicyAndRestartTime) {
  // CI runs a short form; OCCGEO_FULL_FIGURES=1 gives the figures quoted in the docs.
  const bool full = std::getenv("OCCGEO_FULL_FIGURES") != nullptr;
  const int kPipelined = full ? 400 : 100;
  const int kLockstep = full ? 100 : 30;
  std::cout << std::fixed << std::setprecision(0);
  for (const std::string policy : {"every", "batch", "none"}) {
    TempDir dir;
    const auto data = dir.path() / "data";
    std::filesystem::create_directories(data);
    FaultServer server(data, write_durability_config(dir.path(), policy, 0, 0.005));
    std::mt19937 random(5);
    const double pipelined = pipelined_us_per_scan(server.address(), 1, kPipelined, random);
    const double lockstep = lockstep_us_per_scan(server.address(), 1, kLockstep, random);
    std::cout << "[ durability ] policy " << std::setw(5) << policy << ": pipelined " << std::setw(6) << pipelined
              << " us/scan (" << kPipelined << " scans), lockstep " << std::setw(6) << lockstep
              << " us/scan ack latency (" << kLockstep << " scans)\n";
    server.kill9();
  }
  for (const int scans : full ? std::vector<int>{500, 2000} : std::vector<int>{200}) {
    TempDir dir;
    const auto data = dir.path() / "data";
    std::filesystem::create_directories(data);
    const auto config = write_durability_config(dir.path(), "none", 0);
    {
      FaultServer server(data, config);
      std::mt19937 random(6);
      pipelined_us_per_scan(server.address(), 1, scans, random);
      server.kill9();
    }
    const auto journal_bytes = std::filesystem::file_size(data / "journal" / "default.journal");
    const auto started = Clock::now();
    FaultServer restarted(data, config, {}, "restarted");
    const double restart_ms = micros(Clock::now() - started) / 1e3;
    const bool replayed =
        restarted.log().find("\"journal_records_replayed\":" + std::to_string(scans)) != std::string::npos;
    std::cout << "[ durability ] restart with a journal of " << scans << " scans (" << journal_bytes / 1024
              << " KiB): " << restart_ms << " ms to listening\n";
    EXPECT_TRUE(replayed) << restarted.log();
  }
}

}  // namespace
}  // namespace occgeo::testing
