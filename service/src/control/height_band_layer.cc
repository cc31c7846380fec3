#include "height_band_layer.h"
#include "occgeo/geometry/checks.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace occgeo::service::control {

namespace {

constexpr double kSqrt2 = 1.4142135623730951;
// The longest unseen stretch the planner bridges between surfaces a drivable slope could join, metres.
constexpr double kUnseenGap_m = 2.0;

}  // namespace

HeightBandLayer::HeightBandLayer(const mapping::OctoMapSnapshot& octomap, double robot_height_m, double terrain_cell_m)
    : octomap_(octomap), robot_height_m_(robot_height_m), terrain_cell_m_(terrain_cell_m) {
  geometry::require(std::isfinite(terrain_cell_m) && terrain_cell_m >= 0.001 && terrain_cell_m <= 10.0,
                    "terrain_cell_m", "must be in [0.001, 10] metres", terrain_cell_m);
}

std::size_t HeightBandLayer::mark_occupied(PlanningWindow& window,
                                           const std::optional<Eigen::Vector2d>& robot_W) const {
  const double cell_m = window.cell_size_m;
  mapping::TerrainMap terrain(
      octomap_, cell_m, window.origin,
      {window.origin.ix + std::max(window.width, 1) - 1, window.origin.iy + std::max(window.height, 1) - 1},
      robot_height_m_, octomap_.terrain(), robot_W);
  // Plan as if the far stretch a depth camera has not resolved yet continues the slope it saw: the guard, reading
  // only what was seen, stops the robot should it turn out otherwise, and the next plan knows better.
  terrain.bridge_unseen_gaps(kUnseenGap_m);
  std::size_t marked = 0;
  for (int row = 0; row < window.height; ++row) {
    for (int col = 0; col < window.width; ++col) {
      PlanningCell& cell = window.cells[static_cast<std::size_t>(row) * window.width + col];
      const geometry::CellIndex index{window.origin.ix + col, window.origin.iy + row};
      if (cell != PlanningCell::kOccupied) continue;
      if (terrain.explains_returns(index)) {
        cell = PlanningCell::kFree;
        ++marked;
      } else if (terrain.may_explain_returns(index)) {
        cell = PlanningCell::kUnknown;  // as dear as unseen ground
        ++marked;
      }
    }
  }
  const OctoMapColumns columns(octomap_, robot_height_m_, &terrain, true);
  const double column_m = columns.cell_size();
  // The window's extent in columns, so the octree is walked only there.
  const geometry::CellIndex min{static_cast<std::int32_t>(std::floor(window.origin.ix * cell_m / column_m)),
                                static_cast<std::int32_t>(std::floor(window.origin.iy * cell_m / column_m))};
  const geometry::CellIndex max{
      static_cast<std::int32_t>(std::ceil((window.origin.ix + window.width) * cell_m / column_m)) - 1,
      static_cast<std::int32_t>(std::ceil((window.origin.iy + window.height) * cell_m / column_m)) - 1};
  columns.for_each_occupied(min, max, [&](const geometry::CellIndex& column) {
    // The grid cells the column's square [ix c, (ix + 1) c) overlaps; a hair inside its far edge so a column ending
    // on a cell boundary does not spill into the next cell.
    const double x0 = column.ix * column_m;
    const double y0 = column.iy * column_m;
    const double inset = column_m * 1e-6;
    const int col0 = static_cast<int>(std::floor(x0 / cell_m + 1e-9)) - window.origin.ix;
    const int col1 = static_cast<int>(std::floor((x0 + column_m - inset) / cell_m)) - window.origin.ix;
    const int row0 = static_cast<int>(std::floor(y0 / cell_m + 1e-9)) - window.origin.iy;
    const int row1 = static_cast<int>(std::floor((y0 + column_m - inset) / cell_m)) - window.origin.iy;
    for (int row = std::max(row0, 0); row <= std::min(row1, window.height - 1); ++row) {
      for (int col = std::max(col0, 0); col <= std::min(col1, window.width - 1); ++col) {
        PlanningCell& cell = window.cells[static_cast<std::size_t>(row) * window.width + col];
        if (cell != PlanningCell::kOccupied) {
          cell = PlanningCell::kOccupied;
          ++marked;
        }
      }
    }
    return true;
  });
  return marked;
}

bool HeightBandLayer::segment_clear(const Eigen::Vector2d& a_W, const Eigen::Vector2d& b_W, double radius_m) const {
  geometry::require(a_W.allFinite(), "a_W must be finite");
  geometry::require(b_W.allFinite(), "b_W must be finite");
  geometry::require(std::isfinite(radius_m) && radius_m >= 0.0 && radius_m <= 5.0, "radius_m",
                    "must be in [0, 5] metres", radius_m);
  const double column_m = octomap_.resolution();
  const Eigen::Vector2d lo = a_W.cwiseMin(b_W).array() - radius_m - column_m;
  const Eigen::Vector2d hi = a_W.cwiseMax(b_W).array() + radius_m + column_m;
  for (const double value : {lo.x(), lo.y(), hi.x(), hi.y()}) {
    geometry::require(std::abs(value / column_m) < geometry::GridGeometry::kMaxCellIndex,
                      "a_W must lie within 2^30 cells of the origin");
  }
  // A column's square reaches half a diagonal beyond its centre.
  const double reach_m = radius_m + column_m * kSqrt2 / 2.0;
  // The terrain is estimated piece by piece along the segment, so a long diagonal costs its corridor, not its box.
  constexpr double kPiece_m = 4.0;
  const int pieces = std::max(1, static_cast<int>(std::ceil((b_W - a_W).norm() / kPiece_m)));
  // Where the robot stands is reachable, and so is each piece's end that the piece before found drivable: a platform
  // whose ramp lies in an earlier piece stays reachable.
  std::optional<Eigen::Vector2d> reachable_W = a_W;
  for (int piece = 0; piece < pieces; ++piece) {
    const Eigen::Vector2d p_W = a_W + (b_W - a_W) * (static_cast<double>(piece) / pieces);
    const Eigen::Vector2d q_W = a_W + (b_W - a_W) * (static_cast<double>(piece + 1) / pieces);
    const Eigen::Vector2d piece_lo = p_W.cwiseMin(q_W).array() - radius_m - column_m;
    const Eigen::Vector2d piece_hi = p_W.cwiseMax(q_W).array() + radius_m + column_m;
    const mapping::TerrainMap terrain =
        terrain_around(octomap_, terrain_cell_m_, piece_lo, piece_hi, robot_height_m_, reachable_W);
    reachable_W = terrain.drivable(terrain.cell_index(q_W)) ? std::optional<Eigen::Vector2d>(q_W) : std::nullopt;
    const OctoMapColumns columns(octomap_, robot_height_m_, &terrain);
    const geometry::CellIndex min{static_cast<std::int32_t>(std::floor(piece_lo.x() / column_m)),
                                  static_cast<std::int32_t>(std::floor(piece_lo.y() / column_m))};
    const geometry::CellIndex max{static_cast<std::int32_t>(std::floor(piece_hi.x() / column_m)),
                                  static_cast<std::int32_t>(std::floor(piece_hi.y() / column_m))};
    const Eigen::Vector2d along = q_W - p_W;
    const double length_sq = along.squaredNorm();
    bool clear = true;
    columns.for_each_occupied(min, max, [&](const geometry::CellIndex& c) {
      const Eigen::Vector2d centre((c.ix + 0.5) * column_m, (c.iy + 0.5) * column_m);
      const double t = length_sq > 0.0 ? std::clamp((centre - p_W).dot(along) / length_sq, 0.0, 1.0) : 0.0;
      if ((p_W + t * along - centre).norm() < reach_m) clear = false;
      return clear;
    });
    if (!clear) return false;
  }
  return true;
}

GlobalPathResult plan_global_path(const mapping::GridSnapshot& grid, const HeightBandLayer* band,
                                  const Eigen::Vector2d& start_W, const Eigen::Vector2d& goal_W,
                                  const GlobalPathParams& params) {
  if (band == nullptr) return plan_global_path(grid, start_W, goal_W, params);
  // The same window as the grid overload (window_around checks params and both points).
  std::optional<PlanningWindow> window = window_around(grid, start_W, goal_W, params);
  if (!window) {
    GlobalPathResult result;
    result.status = GlobalPathStatus::kWindowTooLarge;
    return result;
  }
  band->mark_occupied(*window, start_W);
  return plan_global_path(*window, start_W, goal_W, params);
}

}  // namespace occgeo::service::control
