// The catalogue's PointBug layouts (seed 003 §2.2.2, Fig 2.8-2.11): PointBug alone, which must show the seed's own
// failures, next to the full stack (map look-ahead, loop detector and global path). One table per test.
#include <gtest/gtest.h>

#include "catalogue.h"

namespace occgeo::testing {
namespace {
// Seed 003 Fig 2.10: a goal inside a cup whose opening faces away, driven by the Bearcat. Measured and printed only:
// PointBug's corrections, scaled to the 0.8 m wide Bearcat, carry it round the cup's corner, so it reaches the goal
// (the endless loop shows with the smaller UGV, PointBugEndlessLoop below).
TEST(ScenarioCatalogue, PointBugCup) {
  const Eigen::Vector2d in_the_cup(4.4, 0.0);
  run_all({
      {seed_only(make("pointbug_cup_goto", "pointbug_cup.yaml", "bearcat", "goto", 90.0, in_the_cup),
                 "seed 003 Fig 2.10: PointBug alone"),
       Expect::kReported},
      {noted(make("pointbug_cup_goto_escape", "pointbug_cup.yaml", "bearcat", "goto", 90.0, in_the_cup),
             "map look-ahead + global path"),
       Expect::kReported},
  });
}

// Seed 003 Fig 2.10 ("the robot continues moving in infinite loops"): the cup of PointBugCup driven by the seed 004
// UGV, whose smaller size (PointBug's corrections scale with the width) leaves room for the whole loop: from every
// sudden point PointBug re-aims at the goal, meets the cup's closed back again and picks a sudden point on the other
// side, so it zigzags in front of the back for ever. The full stack sees the back in its map and follows the global
// path round the cup and in through the opening.
TEST(ScenarioCatalogue, PointBugEndlessLoop) {
  const Eigen::Vector2d in_the_cup(4.4, 0.0);
  const std::vector<ScenarioResult> results = run_all({
      {seed_only(make("pointbug_cup_ugv_goto", "pointbug_cup.yaml", "ugv", "goto", 60.0, in_the_cup),
                 "seed 003 Fig 2.10: PointBug alone loops"),
       Expect::kNotReached},
      {noted(make("pointbug_cup_ugv_goto_escape", "pointbug_cup.yaml", "ugv", "goto", 60.0, in_the_cup),
             "seed 003 Fig 2.10: map look-ahead + global path"),
       Expect::kFullStack},
  });
  // The loop is visible: far more driven than the whole way in, and still in front of the cup's closed back.
  const ScenarioResult& alone = results[0];
  ASSERT_TRUE(alone.ran && alone.optimal_m);
  EXPECT_GT(alone.path_m, 2.0 * *alone.optimal_m);
  EXPECT_LT(alone.final_pose.x(), 3.0);
}

}  // namespace
}  // namespace occgeo::testing
