#pragma once

// The true poses an `occgeo-sim --trace-out` CSV holds, and what the tests judge on them.

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "world_truth.h"

namespace occgeo::testing {

// One row per physics step: (sim time s, x m, y m, theta rad) in the world frame. Empty when the file is missing.
std::vector<Eigen::Vector4d> read_sim_trace(const std::filesystem::path& file);

// The longest stretch of sim time over which the true pose did not change at all (neither moved nor turned), seconds.
double longest_standstill_s(const std::vector<Eigen::Vector4d>& trace);

// `count` start poses ("x,y,theta" for occgeo-sim --start) drawn from `seed` over the free cells of a pixel world,
// each leaving a box footprint (length x width, centred on the pose) at least margin_m from every obstacle cell.
std::vector<std::string> seeded_start_poses(const WorldTruth& truth, std::uint32_t seed, int count, double length_m,
                                            double width_m, double margin_m);

}  // namespace occgeo::testing
