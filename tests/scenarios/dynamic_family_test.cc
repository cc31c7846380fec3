// People and carts the robot has never seen, over a family of worlds generated from seed numbers (dynamic_family.h):
// each world is driven twice per robot preset, to the far end with goto, in lockstep: once without its moving
// obstacles (the reference: the layout alone must be passable) and once with them. Judged on the simulator's truth:
// collisions split into the robot moving into something, something running into the robot at rest, and something
// running into the robot while it moved (already inside the footprint where the robot stood, as when a faster walker
// catches up with a robot backing away), and the goal reached within twice the reference run's time.
//
// CI drives the first OCCGEO_DYNAMIC_WORLDS worlds (default 6, a few minutes); the family of 50 runs with
//   OCCGEO_DYNAMIC_WORLDS=50 dynamic_family_test
// and the run's rates are printed either way; OCCGEO_DYNAMIC_FIRST=N starts the family at seed N. OCCGEO_DYNAMIC_CONFIG
// is YAML added to the server's configuration, e.g. "guard: {predict_horizon_s: 0}" for the same worlds without the
// prediction of moving obstacles. OCCGEO_DYNAMIC_WORLD_DIR=DIR keeps each world's file there, to drive it by hand.
// OCCGEO_DYNAMIC_DRIVE_AFTER_S=S sets each run's goal S seconds after the simulator started (held at sim time 0 until
// then) instead of before it connected; the rows must not change (the second test checks that on a few worlds).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "dynamic_family.h"
#include "scenario_runner.h"
#include "temp_dir.h"

namespace occgeo::testing {
namespace {

int family_size() {
  const char* text = std::getenv("OCCGEO_DYNAMIC_WORLDS");
  if (text == nullptr) return 6;
  const int n = std::atoi(text);
  return n > 0 && n <= 1000 ? n : 6;
}

// The seed of the first world driven (OCCGEO_DYNAMIC_FIRST, default 1): to look again at one world of the family.
int first_seed() {
  const char* text = std::getenv("OCCGEO_DYNAMIC_FIRST");
  if (text == nullptr) return 1;
  const int n = std::atoi(text);
  return n > 0 && n <= 1000 ? n : 1;
}

struct Row {
  std::string world;
  std::string preset;
  ScenarioResult reference;
  ScenarioResult dynamic;
  [[nodiscard]] bool reached_in_time() const {
    return dynamic.reached.value_or(false) && reference.reached.value_or(false) &&
           dynamic.sim_s <= 2.0 * reference.sim_s;
  }
};

Scenario family_scenario(const std::string& name, const std::string& world_file, const std::string& preset,
                         const Eigen::Vector2d& goal) {
  Scenario s;
  s.name = name;
  s.world = world_file;
  s.preset = preset;
  s.start = "0,0,0";
  s.behaviour = "goto";
  s.goal = goal;
  s.duration_s = 120.0;
  s.max_wall_s = 120.0;
  if (const char* extra = std::getenv("OCCGEO_DYNAMIC_CONFIG")) s.extra_config = std::string(extra) + "\n";
  if (const char* after = std::getenv("OCCGEO_DYNAMIC_DRIVE_AFTER_S")) s.drive_after_start_s = std::atof(after);
  return s;
}

TEST(DynamicFamily, PeopleAndCartsInGeneratedWorlds) {
  const int worlds = family_size();
  TempDir dir;
  std::vector<Row> rows;
  for (int seed = first_seed(); seed < first_seed() + worlds; ++seed) {
    const DynamicWorld world = make_dynamic_world(static_cast<std::uint32_t>(seed));
    const auto dynamic_file = dir.path() / (world.name + ".yaml");
    const auto static_file = dir.path() / (world.name + "-static.yaml");
    std::ofstream(dynamic_file) << world.yaml;
    std::ofstream(static_file) << world.yaml_static;
    if (const char* keep = std::getenv("OCCGEO_DYNAMIC_WORLD_DIR")) {
      // To drive a world of the family by hand (occgeo-sim --world FILE), outside this test.
      std::filesystem::create_directories(keep);
      std::ofstream(std::filesystem::path(keep) / (world.name + ".yaml")) << world.yaml;
    }
    std::cout << world.name << ": " << world.description << '\n';
    for (const std::string preset : {"ugv", "bearcat"}) {
      Row row{world.name, preset, {}, {}};
      row.reference = run_scenario(
          family_scenario(world.name + "/" + preset + "/static", static_file.string(), preset, world.goal_W),
          std::nullopt);
      // Trajectory pictures of the runs with people and carts, for a person to look at.
      row.dynamic =
          run_scenario(family_scenario(world.name + "-" + preset, dynamic_file.string(), preset, world.goal_W),
                       std::string("scenario-runs/dynamic"));
      rows.push_back(row);
    }
  }

  int runs = 0;
  int moving_into = 0;
  int runs_hit_at_rest = 0;
  int runs_hit = 0;  // an obstacle ran into the robot, standing or moving
  int reached_in_time = 0;
  std::ostringstream table;
  table << std::fixed << std::setprecision(1) << std::left << std::setw(16) << "world" << std::setw(9) << "robot"
        << std::setw(10) << "ref_s" << std::setw(10) << "sim_s" << std::setw(9) << "reached" << std::setw(8) << "moving"
        << std::setw(8) << "at_rest" << std::setw(9) << "hit_mov"
        << "last state\n";
  for (const Row& row : rows) {
    SCOPED_TRACE(row.world + " " + row.preset);
    ASSERT_TRUE(row.reference.ran) << row.reference.failure;
    ASSERT_TRUE(row.dynamic.ran) << row.dynamic.failure;
    // The layout alone is passable: otherwise the generator made a world that proves nothing.
    EXPECT_TRUE(row.reference.reached.value_or(false)) << "reference run did not reach the goal";
    EXPECT_EQ(row.reference.collisions, 0) << "reference run collided";
    ++runs;
    moving_into += row.dynamic.collisions_moving;
    runs_hit_at_rest += row.dynamic.collisions_at_rest > 0 ? 1 : 0;
    runs_hit += row.dynamic.collisions_at_rest + row.dynamic.collisions_hit_moving > 0 ? 1 : 0;
    reached_in_time += row.reached_in_time() ? 1 : 0;
    table << std::setw(16) << row.world << std::setw(9) << row.preset << std::setw(10) << row.reference.sim_s
          << std::setw(10) << row.dynamic.sim_s << std::setw(9)
          << (row.dynamic.reached.value_or(false) ? (row.reached_in_time() ? "yes" : "late") : "no") << std::setw(8)
          << row.dynamic.collisions_moving << std::setw(8) << row.dynamic.collisions_at_rest << std::setw(9)
          << row.dynamic.collisions_hit_moving << row.dynamic.last_state << '\n';
  }
  std::cout << table.str();
  for (const Row& row : rows) {
    if (row.dynamic.collisions > 0) {
      std::cout << row.world << " " << row.preset << " contacts:\n" << row.dynamic.collision_events << '\n';
    }
  }
  std::cout << "dynamic family: " << runs << " runs over " << worlds
            << " worlds; robot moving into an obstacle: " << moving_into
            << " contacts; runs with an obstacle running into the robot at rest: " << runs_hit_at_rest << " ("
            << 100.0 * runs_hit_at_rest / std::max(runs, 1)
            << " %); runs with an obstacle running into the robot at rest or moving: " << runs_hit << " ("
            << 100.0 * runs_hit / std::max(runs, 1)
            << " %); goals reached within 2x the reference time: " << reached_in_time << " ("
            << 100.0 * reached_in_time / std::max(runs, 1) << " %)\n";
}

// Deterministic lockstep over generated worlds too: a goal set a while after the simulator started (held at sim time 0
// until then, as a user typing `occgeo goto` after starting `occgeo-sim --hold`) gives the same run, row for row and
// trace for trace, as the goal set before the simulator connected. The first OCCGEO_DYNAMIC_SAME_WORLDS worlds of the
// family (default 2), both robots, with people and carts.
TEST(DynamicFamily, AGoalSetAfterTheSimulatorStartedGivesTheSameRunInGeneratedWorlds) {
  int worlds = 2;
  if (const char* text = std::getenv("OCCGEO_DYNAMIC_SAME_WORLDS")) worlds = std::clamp(std::atoi(text), 1, 1000);
  TempDir dir;
  for (int seed = first_seed(); seed < first_seed() + worlds; ++seed) {
    const DynamicWorld world = make_dynamic_world(static_cast<std::uint32_t>(seed));
    const auto file = dir.path() / (world.name + ".yaml");
    std::ofstream(file) << world.yaml;
    for (const std::string preset : {"ugv", "bearcat"}) {
      SCOPED_TRACE(world.name + " " + preset);
      Scenario scenario = family_scenario(world.name + "-" + preset, file.string(), preset, world.goal_W);
      scenario.drive_after_start_s.reset();
      const ScenarioResult goal_first = run_scenario(scenario, std::nullopt);
      scenario.drive_after_start_s = 0.5;
      const ScenarioResult goal_later = run_scenario(scenario, std::nullopt);
      ASSERT_TRUE(goal_first.ran) << goal_first.failure;
      ASSERT_TRUE(goal_later.ran) << goal_later.failure;
      EXPECT_GT(goal_first.path_m, 1.0) << "the robot must drive for the comparison to mean anything";
      EXPECT_EQ(goal_later.collisions_moving, goal_first.collisions_moving);
      EXPECT_EQ(goal_later.collisions_at_rest, goal_first.collisions_at_rest);
      EXPECT_EQ(goal_later.collisions_hit_moving, goal_first.collisions_hit_moving);
      EXPECT_EQ(goal_later.reached, goal_first.reached);
      EXPECT_EQ(goal_later.last_state, goal_first.last_state);
      EXPECT_EQ(goal_later.sim_s, goal_first.sim_s);
      const std::optional<std::size_t> parted_at = first_trace_difference(goal_first, goal_later);
      ASSERT_EQ(parted_at, std::nullopt) << "the trajectories part at trace row " << *parted_at;
      std::cout << world.name << " " << preset << ": the same run with the goal first and 0.5 s after the start ("
                << goal_first.trace.size() << " trace rows, " << goal_first.sim_s << " s)\n";
    }
  }
}

}  // namespace
}  // namespace occgeo::testing
