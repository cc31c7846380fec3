// Seed 003 end to end: the ActivityBot steered by the server with PointBug on its servo-swept LIDAR-Lite (sweeps
// assembled from one reading per servo step, dead reckoning from its encoder ticks, commands in drive_speed /
// drive_goto ticks). Each world prints the seed-faithful row (PointBug alone, as the seed describes it) beside the
// full stack's (map look-ahead, loop detector and global path), which must reach the goal with 0 collisions and a
// path at most 1.25 times the optimum.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "catalogue.h"

namespace occgeo::testing {
namespace {

struct ActivityBotWorld {
  std::string name;
  std::string world;
  Eigen::Vector2d goal;
  double seed_s = 0.0;  // sim seconds of PointBug alone; the seed's robot cruises at 4 ticks/s (13 mm/s)
  // Sim seconds of the full stack, which follows its global path at up to 0.4 m/s (123 ticks/s) once the map shows
  // the straight way blocked.
  double full_stack_s = 0.0;
  std::string seed_outcome;
};

void PrintTo(const ActivityBotWorld& world, std::ostream* out) { *out << world.name; }

class ActivityBotPointBug : public ::testing::TestWithParam<ActivityBotWorld> {};

TEST_P(ActivityBotPointBug, SeedRowPrintedAndFullStackReachesTheGoal) {
  const ActivityBotWorld& w = GetParam();
  Scenario seed =
      seed_only(make("activitybot_" + w.name, w.world, "activitybot", "goto", w.seed_s, w.goal), w.seed_outcome);
  Scenario full =
      noted(make("activitybot_" + w.name + "_escape", w.world, "activitybot", "goto", w.full_stack_s, w.goal),
            "map look-ahead + global path");
  for (Scenario* s : {&seed, &full}) {
    s->goal_tolerance_m = 0.1;
    s->max_wall_s = 800.0;  // one reading per 0.02 s servo step, each answered in lockstep
  }
  const std::vector<ScenarioResult> results = run_all({{seed, Expect::kReported}, {full, Expect::kFullStack}});
  ASSERT_TRUE(results[0].ran) << results[0].failure;
}

// Measured: PointBug alone reaches the room's goal in 339 sim seconds, the full stack in 27 (both 4.29 m, ratio 1.00,
// 0 collisions).
INSTANTIATE_TEST_SUITE_P(
    Room, ActivityBotPointBug,
    ::testing::Values(ActivityBotWorld{"room", "room.yaml", {3.0, 3.2}, 600.0, 120.0, "PointBug alone in the room"}),
    [](const ::testing::TestParamInfo<ActivityBotWorld>& param_info) { return param_info.param.name; });

// The catalogue's PointBug layouts (seed 003 Fig 2.8-2.11). The seed rows run 13 to 25 sim minutes at the seed's
// 13 mm/s, 20 to 45 s of wall time each in lockstep. Measured (full stack, 0 collisions each): local minimum 12.29 m
// against 11.22 m optimal (1.10), travel direction 1.04, cup 1.09, min angle 1.04; PointBug alone reaches none of the
// four goals within its time (2.98, 3.30, 4.38 and 10.24 m driven; each stop at a sudden point costs a sweep).
INSTANTIATE_TEST_SUITE_P(
    Catalogue, ActivityBotPointBug,
    ::testing::Values(
        ActivityBotWorld{"local_minimum",
                         "pointbug_local_minimum.yaml",
                         {11.0, 0.0},
                         1400.0,
                         600.0,
                         "seed 003 Fig 2.8: A-B-C-D-target"},
        ActivityBotWorld{"travel_direction",
                         "pointbug_travel_direction.yaml",
                         {4.5, 0.0},
                         900.0,
                         600.0,
                         "seed 003 Fig 2.9: off along the wall towards C"},
        ActivityBotWorld{
            "cup", "pointbug_cup.yaml", {4.4, 0.0}, 800.0, 600.0, "seed 003 Fig 2.10: loops in front of the cup"},
        ActivityBotWorld{"min_angle",
                         "pointbug_min_angle.yaml",
                         {12.0, 0.0},
                         1500.0,
                         600.0,
                         "seed 003 Fig 2.11: to B, the smaller angle, not the shorter way"}),
    [](const ::testing::TestParamInfo<ActivityBotWorld>& param_info) { return param_info.param.name; });

}  // namespace
}  // namespace occgeo::testing
