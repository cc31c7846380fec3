// The scenario catalogue: each seed experiment or failure case as a world, a robot preset, a behaviour, a goal and
// pass criteria, run against the real server in lockstep. Each test prints one table of everything measured.
#include <gtest/gtest.h>

#include <iostream>
#include <vector>

#include "scenario_runner.h"

namespace occgeo::testing {
namespace {

// What a scenario must show.
enum class Expect {
  kFullStack,     // reaches its goal (if any) with 0 collisions and a path ratio <= 1.25
  kNoCollisions,  // 0 collisions (no goal, e.g. wander)
  kStopsInTrap,   // seed-faithful: the Bearcat ends in deadlock (seed 000 Fig 5.3)
  kCollides,      // seed-faithful or guard-less: the run shows the failure as collisions
  kReported,      // measured and printed only
};

struct Entry {
  Scenario scenario;
  Expect expect;
};

constexpr const char* kNoGuard = "guard:\n  enabled: false\n";
const std::optional<std::string> kPictures = std::string("scenario-runs");

std::vector<ScenarioResult> run_all(const std::vector<Entry>& entries) {
  std::vector<Scenario> scenarios;
  std::vector<ScenarioResult> results;
  for (const Entry& entry : entries) {
    scenarios.push_back(entry.scenario);
    results.push_back(run_scenario(entry.scenario, kPictures));
  }
  std::cout << results_table(scenarios, results) << std::flush;
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const ScenarioResult& r = results[i];
    SCOPED_TRACE(r.name);
    EXPECT_TRUE(r.ran) << r.failure;
    if (!r.ran) continue;
    switch (entries[i].expect) {
      case Expect::kFullStack:
        EXPECT_EQ(r.collisions, 0);
        if (entries[i].scenario.goal) {
          EXPECT_TRUE(r.reached.value_or(false)) << "ended at " << r.final_pose.transpose() << ", " << r.last_state;
          EXPECT_TRUE(r.ratio());
          if (r.ratio()) {
            EXPECT_LE(*r.ratio(), 1.25);
          }
        }
        break;
      case Expect::kNoCollisions:
        EXPECT_EQ(r.collisions, 0);
        break;
      case Expect::kStopsInTrap:
        EXPECT_EQ(r.last_state, "deadlock");
        EXPECT_EQ(r.collisions, 0);
        break;
      case Expect::kCollides:
        EXPECT_GT(r.collisions, 0);
        break;
      case Expect::kReported:
        break;
    }
  }
  return results;
}

// Acceptance: a robot told to drive straight at a wall at full speed stops short of it with 0 collisions, whatever
// the behaviour; the same drive without the guard hits the wall. The room's inside wall is at x = 5 m, straight
// ahead of the start; the Bearcat's front is 0.5 m ahead of base_link.
TEST(GuardScenarios, FullSpeedAtAWallStopsShortWhateverTheBehaviour) {
  const auto at_wall = [](std::string name, std::string behaviour, std::string config = {}) {
    Scenario s;
    s.name = std::move(name);
    s.world = "room.yaml";
    s.preset = "bearcat";
    s.start = "0,0,0";
    s.behaviour = std::move(behaviour);
    s.teleop_linear_mps = 1.2;
    s.duration_s = 10.0;
    s.extra_config = std::move(config);
    return s;
  };
  Scenario go_beyond = at_wall("guard_goto_beyond_wall", "goto");
  go_beyond.goal = Eigen::Vector2d(7.0, 0.0);
  go_beyond.note = "goal outside the room";
  Scenario bare = at_wall("teleop_wall_without_guard", "teleop", kNoGuard);
  bare.note = "guard disabled: the failure the guard prevents";
  const std::vector<ScenarioResult> results = run_all({
      {at_wall("guard_teleop_wall", "teleop"), Expect::kNoCollisions},
      {at_wall("guard_bearcat_wall", "bearcat"), Expect::kNoCollisions},
      {at_wall("guard_wander_wall", "wander"), Expect::kNoCollisions},
      {go_beyond, Expect::kNoCollisions},
      {bare, Expect::kCollides},
  });
  ASSERT_TRUE(results[0].ran);
  EXPECT_LT(results[0].final_pose.x() + 0.5, 5.0) << "the teleop robot stops short of the wall";
  EXPECT_GT(results[0].final_pose.x() + 0.5, 4.0) << "... but not far short: it drove at the wall";
}

Scenario make(std::string name, std::string world, std::string preset, std::string behaviour, double duration_s,
              std::optional<Eigen::Vector2d> goal = std::nullopt) {
  Scenario s;
  s.name = std::move(name);
  s.world = std::move(world);
  s.preset = std::move(preset);
  s.start = "0,0,0";
  s.behaviour = std::move(behaviour);
  s.duration_s = duration_s;
  s.goal = goal;
  if (goal && s.behaviour == "waypoints") s.waypoints = {*goal};
  return s;
}

Scenario seed_only(Scenario s, std::string note) {
  s.name += "_seed";
  s.escape = false;
  s.note = std::move(note);
  return s;
}

// The catalogue of DESIGN.md §8 with what is wired: each seed's experiment, its failure case as the seed's behaviour
// alone, and the full stack (behaviour + guard + deadlock escape).
// About two minutes of wall time on 2 cores. Printed, not asserted: the U-trap goal beyond the trap is not reached
// yet (PointBug reports no_path inside the trap and the global path over the remembered grid finds no way out), and
// the obstacle approaching head-on is sometimes avoided, sometimes touched (the OctoMap's and PTEM's publication is
// rate-limited in wall time, so lockstep runs differ).
TEST(ScenarioCatalogue, SeedExperimentsAndFailureCases) {
  const Eigen::Vector2d beyond_u(7.0, 0.0);
  const Eigen::Vector2d past_obstacle(3.5, 0.0);
  Scenario cumulative_approach = make("ptem_approaching_waypoints_cumulative", "ptem_approaching.yaml", "ugv",
                                      "waypoints", 40.0, Eigen::Vector2d(4.5, 0.0));
  cumulative_approach.extra_config = "ptem:\n  construction: cumulative\n";
  cumulative_approach.note = "seed 004 §6.3: cumulative PTEM around a moving obstacle";
  run_all({
      {make("open_field_wander_10min", "open_field.yaml", "bearcat", "wander", 600.0), Expect::kNoCollisions},
      {make("open_field_bearcat", "open_field.yaml", "bearcat", "bearcat", 120.0), Expect::kNoCollisions},
      {seed_only(make("u_trap_bearcat", "u_deadlock.yaml", "bearcat", "bearcat", 40.0), "seed 000 Fig 5.3"),
       Expect::kStopsInTrap},
      {seed_only(make("u_trap_goto", "u_deadlock.yaml", "bearcat", "goto", 90.0, beyond_u), "PointBug alone"),
       Expect::kReported},
      {make("u_trap_goto_escape", "u_deadlock.yaml", "bearcat", "goto", 120.0, beyond_u), Expect::kReported},
      {make("room_goto", "room.yaml", "bearcat", "goto", 60.0, Eigen::Vector2d(3.0, 3.2)), Expect::kFullStack},
      {make("corridor_goto", "corridor.yaml", "bearcat", "goto", 90.0, Eigen::Vector2d(20.0, 0.0)), Expect::kFullStack},
      {make("ptem_thin_goto", "ptem_thin.yaml", "ugv", "goto", 40.0, past_obstacle), Expect::kFullStack},
      {make("ptem_cone_goto", "ptem_cone.yaml", "ugv", "goto", 40.0, past_obstacle), Expect::kFullStack},
      {make("ptem_thin_waypoints", "ptem_thin.yaml", "ugv", "waypoints", 40.0, past_obstacle), Expect::kFullStack},
      {make("ptem_cone_waypoints", "ptem_cone.yaml", "ugv", "waypoints", 40.0, past_obstacle), Expect::kFullStack},
      {make("ptem_crossing_waypoints", "ptem_crossing.yaml", "ugv", "waypoints", 40.0, past_obstacle),
       Expect::kFullStack},
      {make("ptem_approaching_waypoints", "ptem_approaching.yaml", "ugv", "waypoints", 40.0, Eigen::Vector2d(4.5, 0.0)),
       Expect::kReported},
      {cumulative_approach, Expect::kCollides},
      {seed_only(make("short_and_overhang_bearcat", "short_and_overhang.yaml", "bearcat", "bearcat", 20.0),
                 "seed 000 Fig 5.2: invisible to the laser"),
       Expect::kCollides},
  });
}

}  // namespace
}  // namespace occgeo::testing
