// The catalogue's sensing and terrain cases (seed 000 Fig 5.1 and 5.2): what one laser plane cannot see or tell
// apart, and what a depth camera and the octree change. One table per test.
#include <gtest/gtest.h>

#include "catalogue.h"

namespace occgeo::testing {
namespace {
// Seed 000 Fig 5.1 and 5.2: what one laser plane cannot see or tell apart. With the Bearcat's one laser these are
// sensing limits no behaviour fixes: the short and the overhanging obstacle are hit with or without the guard (no
// model holds them), and the ramp reads as a wall, so nothing drives over it (the octree holds only the laser's
// returns, a band at 0.6 m no floor leads onto, so the terrain rule finds no surface there). With a depth camera
// (bearcat_3d) the octree holds both obstacles: the guard stops short of them, and goto's look-ahead and global path
// go round them (the kerb is a step, not a slope); and it holds the ramp's surface, which the terrain rule finds
// drivable, so the global path, the look-ahead and the guard let the robot up the ramp the laser reads as a wall.
TEST(ScenarioCatalogue, SensingLimitsOfOneLaserPlane) {
  const Eigen::Vector2d up_the_ramp(9.0, 0.0);
  const Eigen::Vector2d beyond_both(6.0, 0.0);
  run_all({
      {noted(make("short_and_overhang_bearcat_3d_guarded", "short_and_overhang.yaml", "bearcat_3d", "bearcat", 20.0),
             "depth camera: the guard stops short of the kerb"),
       Expect::kNoCollisions},
      {noted(make("short_and_overhang_goto_3d", "short_and_overhang.yaml", "bearcat_3d", "goto", 40.0, beyond_both),
             "depth camera: look-ahead and global path over the octree's height band"),
       Expect::kFullStack},
      {seed_only(make("short_and_overhang_bearcat", "short_and_overhang.yaml", "bearcat", "bearcat_seed", 20.0),
                 "seed 000 Fig 5.2: invisible to the laser", kNoGuard),
       Expect::kCollides},
      {noted(make("short_and_overhang_bearcat_guarded", "short_and_overhang.yaml", "bearcat", "bearcat", 20.0),
             "known limit: the guard cannot see them either"),
       Expect::kCollides},
      {seed_only(make("ramp_bearcat", "ramp.yaml", "bearcat", "bearcat_seed", 40.0, up_the_ramp),
                 "seed 000 Fig 5.1: the ramp reads as a wall"),
       Expect::kNotReached},
      {noted(make("ramp_goto_escape", "ramp.yaml", "bearcat", "goto", 60.0, up_the_ramp),
             "known limit: one laser plane shows no surface, the ramp stays a wall"),
       Expect::kNotReached},
      {noted(make("ramp_goto_3d", "ramp.yaml", "bearcat_3d", "goto", 40.0, up_the_ramp),
             "depth camera: the terrain rule finds the slope drivable, up the ramp"),
       Expect::kFullStack},
  });
}

}  // namespace
}  // namespace occgeo::testing
