// The catalogue's PointBug layouts (seed 003 §2.2 and §2.2.2, Fig 2.8-2.11): PointBug alone, which must show the
// seed's own failures, next to the full stack (map look-ahead, loop detector and global path). One table per test.
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "catalogue.h"

namespace occgeo::testing {
namespace {

double lowest_y(const ScenarioResult& result) {
  double y = result.trace.empty() ? 0.0 : result.trace.front()(2);
  for (const Eigen::Vector4d& row : result.trace) y = std::min(y, row(2));
  return y;
}

double highest_y(const ScenarioResult& result) {
  double y = result.trace.empty() ? 0.0 : result.trace.front()(2);
  for (const Eigen::Vector4d& row : result.trace) y = std::max(y, row(2));
  return y;
}

// Seed 003 Fig 2.8 and Table 1: three staggered plates between start and target; PointBug goes from sudden point to
// sudden point (B above the first, C below the second, D above the third) and reaches the target, as the seed shows.
TEST(ScenarioCatalogue, PointBugLocalMinimum) {
  const Eigen::Vector2d target(11.0, 0.0);
  const std::vector<ScenarioResult> results = run_all({
      {seed_only(make("pointbug_local_minimum_goto", "pointbug_local_minimum.yaml", "ugv", "goto", 90.0, target),
                 "seed 003 Fig 2.8: PointBug alone, A-B-C-D-target"),
       Expect::kNoCollisions},
      {noted(make("pointbug_local_minimum_goto_escape", "pointbug_local_minimum.yaml", "ugv", "goto", 60.0, target),
             "map look-ahead + global path"),
       Expect::kFullStack},
  });
  const ScenarioResult& alone = results[0];
  ASSERT_TRUE(alone.ran);
  EXPECT_TRUE(alone.reached.value_or(false)) << "ended at " << alone.final_pose.transpose() << ", " << alone.last_state;
  // The zigzag: above the first plate's top end (y 0.7) and below the second's bottom end (y -0.2).
  EXPECT_GT(highest_y(alone), 0.7);
  EXPECT_LT(lowest_y(alone), -0.2);
}

// Seed 003 Fig 2.9: PointBug meets a long wall at a glancing angle; the sudden point on the side where the wall recedes
// along its way needs the smaller turn, so it follows the wall's direction away from the target (towards the far end
// C) instead of passing the near end D just beside it, and does not come back within the run. The full stack's global
// path goes round D.
TEST(ScenarioCatalogue, PointBugFollowsItsTravelDirection) {
  const Eigen::Vector2d target(4.5, 0.0);
  const std::vector<ScenarioResult> results = run_all({
      {seed_only(make("pointbug_travel_direction_goto", "pointbug_travel_direction.yaml", "ugv", "goto", 90.0, target),
                 "seed 003 Fig 2.9: PointBug alone, off towards C"),
       Expect::kFailsToDriveWell},
      {noted(
           make("pointbug_travel_direction_goto_escape", "pointbug_travel_direction.yaml", "ugv", "goto", 60.0, target),
           "map look-ahead + global path"),
       Expect::kFullStack},
  });
  const ScenarioResult& alone = results[0];
  ASSERT_TRUE(alone.ran);
  EXPECT_GT(highest_y(alone), 1.5) << "out along the wall towards its far end C (y 2.0)";
  EXPECT_GT(lowest_y(alone), -0.4) << "never round D, the near end (y -0.4)";
}

// Seed 003 Fig 2.11: the smaller angular deviation (B, 6 degrees from S) is not the shorter way (A, 24.4 degrees:
// 9 against 9.246 units). PointBug, turning as little as it can, heads for B, then zigzags below B's end without
// getting round it to the target behind the wall (printed); the optimum and the full stack's path are printed beside.
TEST(ScenarioCatalogue, PointBugMinimumDeviationIsNotShortest) {
  const Eigen::Vector2d target(12.0, 0.0);
  const std::vector<ScenarioResult> results = run_all({
      {seed_only(make("pointbug_min_angle_goto", "pointbug_min_angle.yaml", "ugv", "goto", 90.0, target),
                 "seed 003 Fig 2.11: PointBug alone, to B"),
       Expect::kReported},
      {noted(make("pointbug_min_angle_goto_escape", "pointbug_min_angle.yaml", "ugv", "goto", 90.0, target),
             "map look-ahead + global path"),
       Expect::kFullStack},
  });
  const ScenarioResult& alone = results[0];
  ASSERT_TRUE(alone.ran && alone.optimal_m);
  EXPECT_LT(lowest_y(alone), -1.0) << "to B, the wall's end 6 degrees off the line (y -1.29)";
  EXPECT_LT(highest_y(alone), 3.1) << "never round A (y 3.1)";
  EXPECT_GT(alone.path_m, *alone.optimal_m);
}

// Seed 003 Fig 2.10: a goal inside a cup whose opening faces away, driven by the Bearcat. PointBug alone is measured
// and printed only: its corrections, scaled to the 0.8 m wide Bearcat, carry it round the cup's corner, so it reaches
// the goal (the endless loop shows with the smaller UGV, PointBugEndlessLoop below). The full stack's global path keeps
// the way round the cup it has started on as the cup's arms come into view (re-planning hysteresis, global_path.h).
TEST(ScenarioCatalogue, PointBugCup) {
  const Eigen::Vector2d in_the_cup(4.4, 0.0);
  run_all({
      {seed_only(make("pointbug_cup_goto", "pointbug_cup.yaml", "bearcat", "goto", 90.0, in_the_cup),
                 "seed 003 Fig 2.10: PointBug alone"),
       Expect::kReported},
      {noted(make("pointbug_cup_goto_escape", "pointbug_cup.yaml", "bearcat", "goto", 90.0, in_the_cup),
             "map look-ahead + global path"),
       Expect::kFullStack},
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
