// The default Bearcat never parks: the behaviour a robot gets while nobody chose one ("bearcat") turns out of every
// deadlock over the map it built (seed 000 §5.2) instead of stopping for good, as the thesis's robot does
// (bearcat_seed, the catalogue's UTrap row). Each world is driven in lockstep and judged on the simulator's truth:
// no collision, never standing still for more than 10 s in a row, and in the open field the distance driven.
//
// CI runs 5 simulated minutes per world; the full 30 minutes per world (1-4 minutes of wall time each) runs with
//   bearcat_never_parks_test --gtest_also_run_disabled_tests --gtest_filter='*ThirtyMinutes*'
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <string>
#include <vector>

#include "catalogue.h"

namespace occgeo::testing {
namespace {

// The longest stretch of sim time over which the true pose did not change at all (neither moved nor turned).
double longest_standstill_s(const ScenarioResult& result) {
  double longest = 0.0;
  double since = result.trace.empty() ? 0.0 : result.trace.front()(0);
  for (std::size_t i = 1; i < result.trace.size(); ++i) {
    const Eigen::Vector4d& a = result.trace[i - 1];
    const Eigen::Vector4d& b = result.trace[i];
    if ((b.tail<3>() - a.tail<3>()).cwiseAbs().maxCoeff() > 1e-6) {
      since = b(0);
    } else {
      longest = std::max(longest, b(0) - since);
    }
  }
  return longest;
}

void drive_every_world(double duration_s, double open_field_min_m) {
  std::vector<Entry> entries;
  for (const std::string world : {"open_field", "room", "corridor", "u_deadlock"}) {
    Scenario s = make("never_parks_" + world, world + ".yaml", "bearcat", "bearcat", duration_s);
    // The open field is large, and out of the U the way is open for ever: octrees that size publish every 20 s.
    s.octomap_publish_every_messages = world == "open_field" || world == "u_deadlock" ? 200 : 10;
    s.max_wall_s = 40.0 + duration_s / 4.0;  // lockstep runs about 25 sim seconds per wall second here
    s.note = "default Bearcat: map-based escape";
    entries.push_back({s, Expect::kNoCollisions});
  }
  const std::vector<ScenarioResult> results = run_all(entries);
  for (const ScenarioResult& r : results) {
    SCOPED_TRACE(r.name);
    if (!r.ran) continue;
    const double standstill_s = longest_standstill_s(r);
    std::cout << r.name << ": " << r.path_m << " m in " << r.sim_s << " s, longest standstill " << standstill_s
              << " s, last state " << r.last_state << '\n';
    EXPECT_LE(standstill_s, 10.0);
    EXPECT_NE(r.last_state, "deadlock");
  }
  ASSERT_TRUE(results[0].ran);
  EXPECT_GE(results[0].path_m, open_field_min_m) << "open field";
}

TEST(BearcatNeverParks, FiveMinutesInEachWorld) { drive_every_world(300.0, 100.0); }

TEST(BearcatNeverParks, DISABLED_ThirtyMinutesInEachWorld) { drive_every_world(1800.0, 600.0); }

}  // namespace
}  // namespace occgeo::testing
