// Lockstep runs are a pure function of their inputs: the same scenario against a fresh server gives the same true
// trajectory, the same collisions and the same path, however fast or slow the machine runs (the simulator waits for
// the command answering each scan; nothing on the way may depend on wall-clock time).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "scenario_runner.h"

namespace occgeo::testing {
namespace {

using Clock = std::chrono::steady_clock;

// Seed 004 §6: an obstacle coming head-on while the robot follows a waypoint past it with the full stack (PTEM
// guidance, the escape, the guard). The obstacle moves with sim time, so a command applied one scan late changes
// where the robot meets it.
Scenario approaching_obstacle() {
  Scenario s;
  s.name = "repeat_ptem_approaching_waypoints";
  s.world = "ptem_approaching.yaml";
  s.preset = "ugv";
  s.start = "0,0,0";
  s.behaviour = "waypoints";
  s.goal = Eigen::Vector2d(4.5, 0.0);
  s.waypoints = {*s.goal};
  s.duration_s = 20.0;
  return s;
}

// Keeps `threads` threads spinning until destroyed or until `limit` has passed, so the server, the simulator and the
// controller are preempted at other moments than in a quiet run.
class BusyCpu {
 public:
  BusyCpu(unsigned threads, std::chrono::seconds limit) {
    const Clock::time_point until = Clock::now() + limit;
    for (unsigned i = 0; i < threads; ++i) {
      workers_.emplace_back([this, until] {
        std::uint64_t spins = 0;
        while (!stop_.load(std::memory_order_relaxed) && ((++spins & 0xFFFFU) != 0 || Clock::now() < until)) {
        }
      });
    }
  }
  BusyCpu(const BusyCpu&) = delete;
  BusyCpu& operator=(const BusyCpu&) = delete;
  ~BusyCpu() {
    stop_ = true;
    for (std::thread& worker : workers_) worker.join();
  }

 private:
  std::atomic<bool> stop_{false};
  std::vector<std::thread> workers_;
};

int quiet_runs() {
  // OCCGEO_REPEAT_RUNS=N repeats the quiet run N times (at least 2) to look for rare divergences.
  const char* text = std::getenv("OCCGEO_REPEAT_RUNS");
  const int runs = text != nullptr ? std::atoi(text) : 2;
  return std::max(runs, 2);
}

std::string describe(const ScenarioResult& r) {
  char line[256];
  std::snprintf(line, sizeof line,
                "path %.12f m, collisions %d, final pose (%.9f, %.9f, %.9f), %zu rows, %s, %.1f s wall", r.path_m,
                r.collisions, r.final_pose.x(), r.final_pose.y(), r.final_pose.z(), r.trace.size(),
                r.last_state.c_str(), r.wall_s);
  return line;
}

TEST(Repeatability, MovingObstacleLockstepRunsRepeatExactly) {
  const Scenario scenario = approaching_obstacle();
  std::vector<ScenarioResult> results;
  std::vector<std::string> labels;
  for (int i = 0; i < quiet_runs(); ++i) {
    results.push_back(run_scenario(scenario, std::nullopt));
    labels.push_back("quiet run " + std::to_string(i + 1));
  }
  {
    const unsigned cores = std::max(2U, std::thread::hardware_concurrency());
    const BusyCpu busy(cores, std::chrono::seconds(120));
    results.push_back(run_scenario(scenario, std::nullopt));
    labels.push_back("busy run (" + std::to_string(cores) + " spinning threads)");
  }
  for (std::size_t i = 0; i < results.size(); ++i) {
    std::cout << labels[i] << ": " << (results[i].ran ? describe(results[i]) : "did not run: " + results[i].failure)
              << '\n';
  }
  std::cout << std::flush;
  for (const ScenarioResult& r : results) ASSERT_TRUE(r.ran) << r.failure;
  const ScenarioResult& first = results.front();
  EXPECT_GT(first.path_m, 1.0) << "the robot must drive for the comparison to mean anything";
  for (std::size_t i = 1; i < results.size(); ++i) {
    SCOPED_TRACE(labels[i]);
    const ScenarioResult& r = results[i];
    EXPECT_NEAR(r.path_m, first.path_m, 1e-9);
    EXPECT_EQ(r.collisions, first.collisions);
    EXPECT_EQ(r.reached, first.reached);
    EXPECT_EQ(r.last_state, first.last_state);
    EXPECT_NEAR((r.final_pose - first.final_pose).norm(), 0.0, 1e-9);
    if (const auto row = first_trace_difference(first, r)) {
      const auto show = [](const ScenarioResult& run, std::size_t at) {
        if (at >= run.trace.size()) return std::string("(ended)");
        const Eigen::Vector4d& p = run.trace[at];
        char text[160];
        std::snprintf(text, sizeof text, "t %.3f s (%.9f, %.9f, %.9f)", p[0], p[1], p[2], p[3]);
        return std::string(text);
      };
      ADD_FAILURE() << "the trajectories part at trace row " << *row << ": " << show(first, *row) << " vs "
                    << show(r, *row);
    }
  }
}

// A user starts the simulator, then types the goal: with --hold the robot stands at sim time 0 until the behaviour is
// set, so the run is the same however long that took, and the same as when the goal came first.
TEST(Repeatability, AGoalSetAfterTheSimulatorStartedGivesTheSameRun) {
  Scenario scenario = approaching_obstacle();
  const ScenarioResult goal_first = run_scenario(scenario, std::nullopt);
  std::vector<ScenarioResult> later;
  for (const double delay_s : {0.2, 1.5}) {
    scenario.drive_after_start_s = delay_s;
    later.push_back(run_scenario(scenario, std::nullopt));
  }
  ASSERT_TRUE(goal_first.ran) << goal_first.failure;
  std::cout << "goal first: " << describe(goal_first) << '\n';
  EXPECT_GT(goal_first.path_m, 1.0) << "the robot must drive for the comparison to mean anything";
  for (const ScenarioResult& r : later) {
    ASSERT_TRUE(r.ran) << r.failure;
    std::cout << "goal later: " << describe(r) << '\n';
    EXPECT_NEAR(r.path_m, goal_first.path_m, 1e-9);
    EXPECT_EQ(r.collisions, goal_first.collisions);
    EXPECT_EQ(first_trace_difference(goal_first, r), std::nullopt) << "the trajectories part";
  }
}

}  // namespace
}  // namespace occgeo::testing
