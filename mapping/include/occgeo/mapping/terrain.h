#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "occgeo/geometry/cell.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/mapping/terrain_params.h"

// A terrain estimate from the octree: which ground cells hold a surface a robot can drive on (a floor, a ramp, a
// platform reached by one), so that what a range sensor returns from that surface is not taken for an obstacle
// (seed 000 Fig 5.1: one laser plane reads a ramp as a wall). Everything else (unseen cells, steps, steep slopes,
// anything standing on a surface) stays an obstacle wherever the models say so.
namespace occgeo::mapping {

// The estimate for one ground cell.
struct TerrainCell {
  bool known = false;      // some occupied voxel in the column forms a surface
  double surface_m = 0.0;  // world z of the surface's top, metres (when known)
  double slope_rad = 0.0;  // of a plane fitted to the surface around the cell (when drivable)
  double step_m = 0.0;     // largest height change to a neighbour beyond what the slope limit explains
  bool drivable = false;   // slope and step within the limits (enough neighbours seen), reachable (see TerrainMap)
  // Not drivable as seen, but the unseen stretch between it and a drivable cell could be a drivable slope (see
  // TerrainMap::bridge_unseen_gaps): a planner may hope to drive there, a guard must not.
  bool plausible = false;
};

// The terrain of the cells [min, max] (indices of a grid of cell_size_m: cell (ix, iy) covers [ix c, (ix + 1) c) x
// [iy c, (iy + 1) c), as the HIMM grid's) from the occupied voxels of an octree snapshot.
//
// Per cell, the occupied voxels of its column are joined into runs (a gap of at most one voxel is noise, not air).
// The surface is the top of the lowest run with room for the robot above it (the gap to the next run at least
// robot_height_m), else the top of the highest run: a floor under a table the robot passes beneath stays the floor,
// a floor under something lower than the robot is not a surface it can use (its column reads as tall), and a
// stray voxel under a platform's top (a sensor inside the platform, noise) does not hide the platform. Whatever
// stands on a surface and touches it joins its run and raises the surface, so a box on a ramp is a step. The slope
// is fitted (least squares) to the surface heights within two cells that a drivable surface could reach, so one
// voxel of quantisation does not read as a slope and a wall beside a floor does not tilt it; the step is checked
// against the cells within two cells (far ground is sampled about every other cell).
class TerrainMap {
 public:
  // Estimates the cells [min, max] (inclusive; at most 4096 x 4096) plus a margin of two cells the slope needs.
  // robot_height_m > 0. A cell is drivable when its surface is locally drivable and connected through such cells to
  // the floor (a surface within the ground band) or to the cell of robot_W (world frame, where the robot stands, so
  // a platform is drivable while its ramp lies outside the region). With params.enabled false every cell is unknown.
  // Throws std::invalid_argument naming the field for an invalid argument.
  TerrainMap(const OctoMapSnapshot& octomap, double cell_size_m, geometry::CellIndex min, geometry::CellIndex max,
             double robot_height_m, const TerrainParams& params,
             const std::optional<Eigen::Vector2d>& robot_W = std::nullopt);

  [[nodiscard]] double cell_size() const { return cell_size_m_; }
  [[nodiscard]] const TerrainParams& params() const { return params_; }

  // The cell's estimate; an unknown cell outside the estimated region.
  [[nodiscard]] TerrainCell cell(geometry::CellIndex index) const;
  // The cell holding p_W (world frame, metres).
  [[nodiscard]] geometry::CellIndex cell_index(const Eigen::Vector2d& p_W) const;
  [[nodiscard]] bool drivable(geometry::CellIndex index) const { return cell(index).drivable; }

  // True when the cell is drivable and its surface lies above the ground band: a range return there (a laser plane
  // meeting a ramp, a depth camera's points on it) may be the surface itself rather than an obstacle.
  [[nodiscard]] bool explains_returns(geometry::CellIndex index) const;

  // For planning: may the cell be a drivable surface? Drivable or plausible; or unseen, or seen too thinly for a
  // slope (but not a step), within 1.5 m of a drivable or plausible surface above the floor (a depth camera's
  // lone far points are filtered out of the octree, not out of the grid).
  [[nodiscard]] bool may_be_surface(geometry::CellIndex index) const;
  // explains_returns for a cell that may_be_surface (an unseen one included).
  [[nodiscard]] bool may_explain_returns(geometry::CellIndex index) const;

  // A depth camera maps far ground sparsely (and its far, lone points are filtered out as outliers), so a ramp seen
  // from its foot has an unseen stretch between the slope seen near and the line where a laser plane meets it. Marks
  // plausible every cell that is drivable where it was seen but not connected, when a straight stretch of unseen
  // cells at most max_gap_m long leads to it from a drivable cell whose height a slope within the limits reaches (and
  // the cells connected to it likewise). Nothing is plausible without a drivable cell, so a map of one laser plane's
  // returns gains nothing.
  void bridge_unseen_gaps(double max_gap_m);

  // The world z range an occupied voxel over the cell must overlap to be an obstacle to a robot of height_m: over a
  // drivable surface (or one that may_be_surface, when plausible_too), from just above it to height_m above it;
  // elsewhere [floor_band_m, height_m] as over a flat floor.
  [[nodiscard]] std::pair<double, double> obstacle_band(geometry::CellIndex index, double floor_band_m, double height_m,
                                                        bool plausible_too = false) const;

  // The lowest and highest surface of a drivable or plausible cell (both 0 when there is none), metres: bounds of the
  // z range obstacle_band can ask for.
  [[nodiscard]] double lowest_drivable_surface_m() const { return lowest_surface_m_; }
  [[nodiscard]] double highest_drivable_surface_m() const { return highest_surface_m_; }

 private:
  [[nodiscard]] const TerrainCell* find(geometry::CellIndex index) const;

  TerrainParams params_;
  double cell_size_m_;
  double voxel_m_ = 0.0;              // the octree's resolution
  geometry::CellIndex origin_{0, 0};  // the first cell of the estimated region (margin included)
  int width_ = 0;
  int height_ = 0;
  std::vector<TerrainCell> cells_;
  std::vector<std::uint8_t> locally_drivable_;  // slope and step within the limits, reachable or not
  bool any_drivable_ = false;
  double lowest_surface_m_ = 0.0;
  double highest_surface_m_ = 0.0;
};

}  // namespace occgeo::mapping
