#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <optional>

#include "model_geometry.h"
#include "occgeo/mapping/grid_snapshot.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/service/control/global_path.h"

// What the OctoMap adds to planning on the 2D grid: the obstacles a robot of a given height would hit that one laser
// plane does not see (a kerb below it, an overhang above it; seed 000 Fig 5.2), and the surfaces it can drive on that
// the laser reads as walls (a ramp; seed 000 Fig 5.1). The octree's occupied voxels in the robot's height band are
// projected onto the ground: over the floor the band runs from just above it (octomap_ground_band_m: a depth
// sensor's floor returns are voxels below it) to the robot's top; over a drivable surface of the terrain estimate
// (mapping::TerrainMap under the octree's terrain rule) it is measured from that surface, so the surface is no obstacle
// and what stands on it is. The goto look-ahead and the global path read them beside the HIMM grid.
namespace occgeo::service::control {

class HeightBandLayer {
 public:
  // The band of octomap for a robot robot_height_m tall; octomap must outlive the layer. segment_clear estimates the
  // terrain in cells of terrain_cell_m (the HIMM grid's by default); mark_occupied in the window's.
  HeightBandLayer(const mapping::OctoMapSnapshot& octomap, double robot_height_m, double terrain_cell_m = 0.1);

  // Applies the octree to a window of the grid: an occupied cell whose drivable surface explains it (the laser
  // meeting a ramp) becomes free, then every cell an obstacle column of the band overlaps becomes occupied (a voxel
  // column is smaller than a grid cell, so the whole cell holding any part of it). robot_W is where the robot stands
  // (world frame; the surface there is reachable). Returns how many cells changed.
  std::size_t mark_occupied(PlanningWindow& window, const std::optional<Eigen::Vector2d>& robot_W = std::nullopt) const;

  // True when no obstacle column of the band comes within radius_m of the segment from a_W (where the robot stands)
  // to b_W (world frame), measured to the columns' squares, like segment_clear on the grid. Throws
  // std::invalid_argument naming the field when a point is not finite or radius_m is not in [0, 5].
  [[nodiscard]] bool segment_clear(const Eigen::Vector2d& a_W, const Eigen::Vector2d& b_W, double radius_m) const;

 private:
  const mapping::OctoMapSnapshot& octomap_;
  double robot_height_m_;
  double terrain_cell_m_;
};

// plan_global_path on the grid's window around start and goal (as the grid overload builds it) with the height band's
// obstacles marked in it; with no octree, exactly plan_global_path(grid, ...).
GlobalPathResult plan_global_path(const mapping::GridSnapshot& grid, const HeightBandLayer* band,
                                  const Eigen::Vector2d& start_W, const Eigen::Vector2d& goal_W,
                                  const GlobalPathParams& params);

}  // namespace occgeo::service::control
