#pragma once

// The catalogue's shared vocabulary: what each scenario must show, how a group of scenarios is run and judged (one
// printed table per group), and the constructors every catalogue file uses.

#include <optional>
#include <string>
#include <vector>

#include "scenario_runner.h"

namespace occgeo::testing {

// What a scenario must show.
enum class Expect {
  kFullStack,         // reaches its goal (if any) with 0 collisions and a path ratio <= 1.25
  kNoCollisions,      // 0 collisions (no goal, e.g. wander)
  kStopsInTrap,       // seed-faithful: the Bearcat ends in deadlock (seed 000 Fig 5.3)
  kCollides,          // seed-faithful or guard-less: the run shows the failure as collisions
  kNotReached,        // seed-faithful: the goal is not reached (no path, deadlock, or what a sensor cannot tell)
  kFailsToDriveWell,  // seed-faithful: collides, misses the goal or detours (path ratio above 1.25)
  kReported,          // measured and printed only
};

struct Entry {
  Scenario scenario;
  Expect expect;
};

inline constexpr const char* kNoGuard = "guard:\n  enabled: false\n";

// Runs every entry (trajectory pictures into scenario-runs/), prints one table, and checks each entry's expectation
// with GoogleTest assertions. Returns the results in the entries' order.
std::vector<ScenarioResult> run_all(const std::vector<Entry>& entries);

// A scenario from the start pose (0, 0, 0) with the full stack; a goal for goto, or the one waypoint for waypoints.
Scenario make(std::string name, std::string world, std::string preset, std::string behaviour, double duration_s,
              std::optional<Eigen::Vector2d> goal = std::nullopt);

// The seed's behaviour alone: no deadlock escape (and, with kNoGuard in extra_config, no guard).
Scenario seed_only(Scenario s, std::string note, std::string extra_config = {});

Scenario noted(Scenario s, std::string note);

}  // namespace occgeo::testing
