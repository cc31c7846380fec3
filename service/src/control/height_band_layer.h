#pragma once

#include <Eigen/Core>
#include <cstddef>

#include "../handlers/model_geometry.h"
#include "occgeo/mapping/grid_snapshot.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/service/control/global_path.h"

// What the OctoMap adds to planning on the 2D grid: the obstacles a robot of a given height would hit that one laser
// plane does not see (a kerb below it, an overhang above it; seed 000 Fig 5.2). The octree's occupied voxels in the
// robot's height band, from just above the floor (octomap_ground_band_m: a depth sensor's floor returns are voxels
// below it) to the robot's top, are projected onto the ground; the goto look-ahead and the global path read them
// beside the HIMM grid.
namespace occgeo::service::control {

class HeightBandLayer {
 public:
  // The band [octomap_ground_band_m(resolution), robot_height_m] of octomap, which must outlive the layer.
  HeightBandLayer(const mapping::OctoMapSnapshot& octomap, double robot_height_m);

  // Marks every cell of the window that an obstacle column of the band overlaps as occupied (a voxel column is
  // smaller than a grid cell, so the whole cell holding any part of it); returns how many cells changed.
  std::size_t mark_occupied(PlanningWindow& window) const;

  // True when no obstacle column of the band comes within radius_m of the segment from a_W to b_W (world frame),
  // measured to the columns' squares, like segment_clear on the grid. Throws std::invalid_argument naming the field
  // when a point is not finite or radius_m is not in [0, 5].
  [[nodiscard]] bool segment_clear(const Eigen::Vector2d& a_W, const Eigen::Vector2d& b_W, double radius_m) const;

 private:
  OctoMapColumns columns_;
};

// plan_global_path on the grid's window around start and goal (as the grid overload builds it) with the height band's
// obstacles marked in it; with no octree, exactly plan_global_path(grid, ...).
GlobalPathResult plan_global_path(const mapping::GridSnapshot& grid, const HeightBandLayer* band,
                                  const Eigen::Vector2d& start_W, const Eigen::Vector2d& goal_W,
                                  const GlobalPathParams& params);

}  // namespace occgeo::service::control
