#pragma once

// The terrain rule: how the readers of an octree tell the floor and drivable surfaces from obstacles. Each world's
// octree carries its own (OctoMapParams::terrain), so two servers, or two worlds, may differ.
namespace occgeo::mapping {

// Tuning of the terrain estimate (config section `terrain:`).
struct TerrainParams {
  bool enabled = true;
  // Returns less than this above z = 0 are the floor itself (noise on a flat floor), not obstacles, metres.
  double ground_band_m = 0.05;
  // Steepest drivable slope, radians (0.25 rad is about 14°).
  double max_slope_rad = 0.25;
  // Largest drivable height change between neighbouring cells beyond what max_slope_rad explains, metres. Surface
  // heights are voxel tops, so this should be at least one octree resolution: 0.08 m drives a 0.2 m/m ramp mapped
  // at 5 cm and refuses a 0.15 m kerb.
  double max_step_m = 0.08;
  // Throws std::invalid_argument naming the first field out of range.
  void validate() const;
};

}  // namespace occgeo::mapping
