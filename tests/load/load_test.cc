// A bounded load run: occgeo-load starts its own occgeod and runs simulated robots, pipelined query clients and
// observers against it for about 25 s. Any protocol error, lost request or server crash fails the test; the figures
// are printed.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <string>

#include "../support/json_fields.h"
#include "../support/process.h"
#include "../support/realtime.h"

namespace occgeo::testing {
namespace {

// The number stored under key in the tool's JSON summary; NaN when absent.
double json_value(const std::string& json, const std::string& key) {
  return json_optional_number(json, key).value_or(std::nan(""));
}

TEST(LoadTest, RobotsClientsAndObserversRunWithoutAnyErrorAndTheServerSurvives) {
  const ProcessResult run =
      run_process({binary("clients/load/occgeo-load").string(), "--robots", "3", "--clients", "16", "--depth", "4",
                   "--observers", "4", "--mix",
                   "collision=4,clearance=4,ptem=1,status=1,grid=1,collision_batch=1,clearance_batch=1,raycast=1,"
                   "raycast_batch=1,occupancy=1,occupancy_batch=1,swept=1,swept_batch=1,grid_window=1,octree_window=1",
                   "--batch", "50", "--duration", "25", "--warmup-scans", "50", "--json"},
                  std::chrono::seconds(120));
  std::cout << run.out << '\n';
  ASSERT_FALSE(run.timed_out) << run.err;
  EXPECT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(json_value(run.out, "errors"), 0.0) << run.out;
  EXPECT_NE(run.out.find("\"server_alive\":true"), std::string::npos) << run.out;
  EXPECT_GT(json_value(run.out, "queries"), 1000.0) << run.out;
  EXPECT_GT(json_value(run.out, "scans"), 50.0) << "the robots streamed hardly any scans: " << run.out;
  EXPECT_GT(json_value(run.out, "observer_polls"), 100.0) << run.out;
  EXPECT_GT(json_value(run.out, "p99_us"), 0.0) << run.out;
  // Every robot steers from its scans: the control loop is measured, command by command.
  EXPECT_GT(json_value(run.out, "commands"), 20.0) << "hardly any MotionCommands answered the scans: " << run.out;
  EXPECT_GT(json_value(run.out, "command_p99_us"), 0.0) << run.out;
  EXPECT_LE(json_value(run.out, "command_p50_us"), json_value(run.out, "command_p99_us")) << run.out;
}

// A long-running server measured again and again. Each run's simulated robots send the previous run's scans again,
// which the server acknowledges as duplicates and answers with no command; the lockstep must go on, not stall.
TEST(LoadTest, RunsAgainAgainstTheSameServerWithoutErrors) {
  TempDir dir;
  ServerProcess server(dir.path());
  for (int run = 0; run < 3; ++run) {
    const ProcessResult result =
        run_process({binary("clients/load/occgeo-load").string(), "--server", server.address(), "--robots", "1",
                     "--robot-pace", "lockstep", "--clients", "2", "--mix", "collision", "--warmup-scans", "10",
                     "--duration", "1", "--json", "--quiet"},
                    std::chrono::seconds(60));
    ASSERT_FALSE(result.timed_out) << "run " << run << ": " << result.err;
    EXPECT_EQ(result.exit_code, 0) << "run " << run << ": " << result.out << result.err;
    EXPECT_EQ(json_value(result.out, "errors"), 0.0) << "run " << run << ": " << result.out;
    EXPECT_GT(json_value(result.out, "scans"), 10.0) << "run " << run << ": " << result.out;
  }
}

// --robot-sched fifo runs the simulated robots' threads at SCHED_FIFO, so that the command latency leaves out the load
// tool's own scheduling; where the process may not, the run says so as an error instead of timing something else.
TEST(LoadTest, RobotsRunAtTheRealtimePolicyWhenAskedAndThePlatformAllowsIt) {
  const bool allowed = may_run_realtime(10);  // the priority the tool asks for
  const ProcessResult run =
      run_process({binary("clients/load/occgeo-load").string(), "--robots", "1", "--clients", "2", "--mix", "collision",
                   "--warmup-scans", "10", "--duration", "2", "--robot-sched", "fifo", "--json", "--quiet"},
                  std::chrono::seconds(60));
  ASSERT_FALSE(run.timed_out) << run.err;
  EXPECT_NE(run.out.find("\"robot_sched\":\"fifo\""), std::string::npos) << run.out;
  if (allowed) {
    EXPECT_EQ(run.exit_code, 0) << run.out << run.err;
    EXPECT_EQ(json_value(run.out, "errors"), 0.0) << run.out;
    EXPECT_GT(json_value(run.out, "commands"), 5.0) << run.out;
  } else {
    EXPECT_EQ(run.exit_code, 1) << run.out;
    EXPECT_NE(run.out.find("--robot-sched fifo"), std::string::npos) << run.out;
  }
  const ProcessResult bad =
      run_process({binary("clients/load/occgeo-load").string(), "--robot-sched", "realtime", "--duration", "1"},
                  std::chrono::seconds(20));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--robot-sched"), std::string::npos) << bad.err;
}

TEST(LoadTest, RefusesServersOffThisMachine) {
  const ProcessResult run =
      run_process({binary("clients/load/occgeo-load").string(), "--server", "192.0.2.7:7700", "--duration", "1"},
                  std::chrono::seconds(20));
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.err.find("--server"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("loopback"), std::string::npos) << run.err;
}

}  // namespace
}  // namespace occgeo::testing
