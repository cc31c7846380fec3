#pragma once

#include <cstdint>
#include <vector>

#include "occgeo/geometry/pose.h"
#include "occgeo/sim/noise.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/sim_world.h"
#include "occgeo/sim/world.h"

namespace occgeo::sim {

// One simulated sweep of a laser.
struct SimulatedScan {
  // One reading per beam, metres: the exact hit distance plus noise, clamped to [range_min, range_max], or exactly
  // range_max for a beam with no hit closer than that.
  std::vector<float> ranges_m;
  // The obstacle pixels the noise-free beams entered, in beam order (repeats possible).
  std::vector<Pixel> hit_pixels;
};

// Simulates a planar laser by exact ray casting through the world with seeded Gaussian range noise.
class LaserSimulator {
 public:
  // The noise stream is fixed by seed: one sample per beam per sweep, so a beam's noise does not depend on what the
  // other beams hit.
  LaserSimulator(const LaserPreset& laser, std::uint64_t seed);

  // Sweeps once from the robot's base_link pose X_WB.
  SimulatedScan scan(const World& world, const geometry::Pose2& X_WB);
  // Sweeps once from the robot's base_link pose X_WB at sim time time_s, in the scan plane at the preset's mount
  // height (obstacles not spanning that height are not seen).
  SimulatedScan scan(const SimWorld& world, const geometry::Pose2& X_WB, double time_s);

 private:
  // One sweep; cast(p_W, direction_W) gives the beam's std::optional<RayHit>.
  template <typename Cast>
  SimulatedScan sweep(const geometry::Pose2& X_WB, const Cast& cast);

  LaserPreset laser_;
  GaussianNoise noise_;
};

}  // namespace occgeo::sim
