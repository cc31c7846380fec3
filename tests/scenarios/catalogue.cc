#include "catalogue.h"

#include <gtest/gtest.h>

#include <iostream>
#include <utility>

namespace occgeo::testing {
namespace {
const std::optional<std::string> kPictures = std::string("scenario-runs");
}  // namespace

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
      case Expect::kNotReached:
        EXPECT_FALSE(r.reached.value_or(true)) << "ended at " << r.final_pose.transpose() << ", " << r.last_state;
        break;
      case Expect::kFailsToDriveWell:
        EXPECT_TRUE(r.collisions > 0 || !r.reached.value_or(false) || r.ratio().value_or(0.0) > 1.25)
            << "collisions " << r.collisions << ", ratio " << r.ratio().value_or(0.0);
        break;
      case Expect::kReported:
        break;
    }
  }
  return results;
}

Scenario make(std::string name, std::string world, std::string preset, std::string behaviour, double duration_s,
              std::optional<Eigen::Vector2d> goal) {
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

Scenario seed_only(Scenario s, std::string note, std::string extra_config) {
  s.name += "_seed";
  s.escape = false;
  s.note = std::move(note);
  s.extra_config = std::move(extra_config);
  return s;
}

Scenario noted(Scenario s, std::string note) {
  s.note = std::move(note);
  return s;
}

}  // namespace occgeo::testing
