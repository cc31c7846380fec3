// The default Bearcat never parks: the behaviour a robot gets while nobody chose one ("bearcat") turns out of every
// deadlock over the map it built (seed 000 §5.2) instead of stopping for good, as the thesis's robot does
// (bearcat_seed, the catalogue's UTrap row). Each run is driven in lockstep and judged on the simulator's truth: no
// collision, never standing still for more than 10 s in a row, and in the open field the distance driven.
//
// Thirty simulated minutes in each of the four worlds (20-45 s of wall time each), then the room from start poses drawn
// from seed numbers (next to the furniture, facing anywhere), where a robot wedged between a box and the wall used to
// stand for good: every escape path began with a turn the safety guard stopped.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <string>
#include <vector>

#include "../support/sim_trace.h"
#include "../support/world_truth.h"
#include "catalogue.h"
#include "occgeo/mapfile/map_file.h"

namespace occgeo::testing {
namespace {

Scenario never_parks(const std::string& name, const std::string& world, double duration_s) {
  Scenario s = make(name, world + ".yaml", "bearcat", "bearcat", duration_s);
  // The open field is large, and out of the U the way is open for ever: octrees that size publish every 20 s.
  s.octomap_publish_every_messages = world == "open_field" || world == "u_deadlock" ? 200 : 10;
  s.max_wall_s = 40.0 + duration_s / 4.0;  // lockstep runs 40-80 sim seconds per wall second here
  s.note = "default Bearcat: map-based escape";
  return s;
}

// Asserts every run's standstill and state, and returns the results.
std::vector<ScenarioResult> drive(const std::vector<Entry>& entries) {
  const std::vector<ScenarioResult> results = run_all(entries);
  for (const ScenarioResult& r : results) {
    SCOPED_TRACE(r.name);
    if (!r.ran) continue;
    const double standstill_s = longest_standstill_s(r.trace);
    std::cout << r.name << ": " << r.path_m << " m in " << r.sim_s << " s, longest standstill " << standstill_s
              << " s, last state " << r.last_state << '\n';
    EXPECT_LE(standstill_s, 10.0);
    EXPECT_NE(r.last_state, "deadlock");
  }
  return results;
}

// Measured: open field 883 m, room 385 m, corridor 822 m, U 898 m; longest standstills 0-6.1 s, 0 collisions.
TEST(BearcatNeverParks, ThirtyMinutesInEachWorld) {
  std::vector<Entry> entries;
  for (const std::string world : {"open_field", "room", "corridor", "u_deadlock"}) {
    entries.push_back({never_parks("never_parks_" + world, world, 1800.0), Expect::kNoCollisions});
  }
  const std::vector<ScenarioResult> results = drive(entries);
  ASSERT_TRUE(results[0].ran);
  EXPECT_GE(results[0].path_m, 600.0) << "open field";
}

// Measured over seeds 1-8 (10 minutes each): 0 collisions, 125-237 m each, longest standstill at most 6.1 s.
TEST(BearcatNeverParks, TenMinutesInTheRoomFromSeededStarts) {
  const WorldTruth truth(mapfile::read_map_yaml(world_path("room.yaml")));
  std::vector<Entry> entries;
  for (std::uint32_t seed = 1; seed <= 8; ++seed) {
    Scenario s = never_parks("never_parks_room_seed_" + std::to_string(seed), "room", 600.0);
    s.start = seeded_start_poses(truth, seed, 1, 1.0, 0.8, 0.15).front();
    s.note = "default Bearcat from " + s.start;
    entries.push_back({s, Expect::kNoCollisions});
  }
  double total_m = 0.0;
  for (const ScenarioResult& r : drive(entries)) {
    EXPECT_GE(r.path_m, 50.0) << r.name;
    total_m += r.path_m;
  }
  std::cout << "room from 8 seeded starts: " << total_m << " m in all\n";
}

}  // namespace
}  // namespace occgeo::testing
