// `occgeo goto` and `occgeo waypoints` as a user runs them: the real server, a simulated robot in lockstep and the
// CLI holding the lease until the robot reports reached. The simulator's ground truth checks the result.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../support/json_fields.h"
#include "../support/process.h"

namespace occgeo::testing {
namespace {

using namespace std::chrono_literals;

std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Waits (bounded) until the server lists the robot, i.e. the simulator's spec arrived; asks as a user would.
bool wait_until_registered(const std::string& address, const std::string& robot, BackgroundProcess& sim) {
  const auto started = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() - started < 20s && sim.running()) {
    const ProcessResult status = run_process(
        {binary("clients/occgeo").string(), "status", "--server", address, "--json"}, std::chrono::seconds(10));
    if (status.exit_code == 0 && status.out.find("\"" + robot + "\"") != std::string::npos) return true;
    std::this_thread::sleep_for(50ms);
  }
  return false;
}

struct CliRun {
  ProcessResult cli;
  std::string sim_out;  // the simulator's JSON summary (ground truth)
};

// Starts a server (robots stand still until told otherwise) and the simulator in lockstep, then runs the CLI
// command `words` against the robot and stops the simulator.
CliRun run_cli_against_sim(const std::string& world, const std::string& preset, const std::vector<std::string>& words) {
  TempDir dir;
  const auto config = dir.path() / "occgeod.yaml";
  std::ofstream(config) << "log_level: warn\ncontrol:\n  initial_behaviour: stop\n";
  ServerProcess server(dir.path(), {"--config", config.string()});
  const std::string robot = "cli-robot";
  BackgroundProcess sim({binary("clients/sim/occgeo-sim").string(), "--server", server.address(), "--robot", preset,
                         "--world", source("clients/sim/worlds/" + world).string(), "--start", "0,0,0", "--id", robot,
                         "--lockstep", "--duration", "600", "--json"},
                        dir.path() / "sim.out", dir.path() / "sim.err");
  CliRun run;
  if (!wait_until_registered(server.address(), robot, sim)) {
    run.cli.err = "the robot never registered: " + read_text(dir.path() / "sim.err");
    return run;
  }
  std::vector<std::string> argv = {binary("clients/occgeo").string()};
  argv.insert(argv.end(), words.begin(), words.end());
  argv.insert(argv.end(), {"--robot", robot, "--server", server.address(), "--limit", "90"});
  run.cli = run_process(argv, std::chrono::seconds(120));
  static_cast<void>(sim.stop(SIGTERM, std::chrono::seconds(10)));
  run.sim_out = read_text(dir.path() / "sim.out");
  return run;
}

TEST(GotoCli, GotoDrivesTheRobotToTheGoalAndSaysSo) {
  // The room's centre is clear; (2.5, -1.0) lies between the box at (3, 2) and the pillar at (3.2, -2.3).
  const CliRun run = run_cli_against_sim("room.yaml", "bearcat", {"goto", "2.5", "-1.0"});
  ASSERT_FALSE(run.cli.timed_out) << run.cli.out << run.cli.err;
  EXPECT_EQ(run.cli.exit_code, 0) << run.cli.out << run.cli.err;
  // Progress lines name the distance left and the behaviour's state; the last line the outcome and the lease.
  EXPECT_NE(run.cli.out.find("m to go"), std::string::npos) << run.cli.out;
  EXPECT_NE(run.cli.out.find("robot cli-robot: reached at ("), std::string::npos) << run.cli.out;
  EXPECT_NE(run.cli.out.find("lease returned"), std::string::npos) << run.cli.out;
  ASSERT_FALSE(run.sim_out.empty()) << run.cli.out;
  EXPECT_EQ(json_number(run.sim_out, "collisions"), 0) << run.sim_out;
}

TEST(GotoCli, WaypointsFollowsThemPastAThinPoleAndReportsJson) {
  // Seed 004 §5's thin pole at (1.75, 0) lies on the straight line to the last waypoint.
  const CliRun run = run_cli_against_sim("ptem_thin.yaml", "ugv", {"waypoints", "1.0,0.3", "3.5,0", "--json"});
  ASSERT_FALSE(run.cli.timed_out) << run.cli.out << run.cli.err;
  EXPECT_EQ(run.cli.exit_code, 0) << run.cli.out << run.cli.err;
  EXPECT_NE(run.cli.out.find("\"outcome\":\"reached\""), std::string::npos) << run.cli.out;
  EXPECT_TRUE(json_bool(run.cli.out, "returned")) << run.cli.out;
  EXPECT_LT(json_number(run.cli.out, "distance_to_goal_m"), 0.5) << run.cli.out;
  ASSERT_FALSE(run.sim_out.empty()) << run.cli.out;
  EXPECT_EQ(json_number(run.sim_out, "collisions"), 0) << run.sim_out;
}

TEST(GotoCli, MalformedGoalIsAUsageErrorNamingIt) {
  const ProcessResult run = run_process({binary("clients/occgeo").string(), "waypoints", "--robot", "r", "1.0;2.0"},
                                        std::chrono::seconds(20));
  EXPECT_EQ(run.exit_code, 2) << run.out << run.err;
  EXPECT_NE(run.err.find("waypoint '1.0;2.0' must be X,Y"), std::string::npos) << run.err;
}

}  // namespace
}  // namespace occgeo::testing
