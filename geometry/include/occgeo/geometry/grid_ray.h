#pragma once

#include <Eigen/Core>
#include <concepts>
#include <cstdint>
#include <limits>

#include "occgeo/geometry/cell.h"

namespace occgeo::geometry {

// Largest |coordinate| of a ray endpoint, in cells, that a traversal accepts: keeps cell indices (and tile arithmetic
// done on them) far from int32 overflow.
inline constexpr double kMaxRayCellCoordinate = 1 << 30;

// True when p (metres) is finite and within kMaxRayCellCoordinate cells of the origin on both axes.
[[nodiscard]] bool is_traversable_point(const GridGeometry& grid, const Eigen::Vector2d& p);

// Change of cell index between two consecutive cells of a traversal.
struct CellStep {
  std::int32_t dx = 0;
  std::int32_t dy = 0;
};

// Exact traversal (Amanatides & Woo 1987) of the cells a segment passes through, from the cell of its start point to
// the cell of its end point, each cell once and in order; consecutive cells share a side. Where the segment passes
// exactly through a cell corner, the cell across the x side comes first. The end cell is always the one
// GridGeometry::cell_of gives for the end point, whatever the rounding on the way.
class GridRayTraversal {
 public:
  // Starts at the cell of p_start; throws std::invalid_argument unless both points are traversable (metres, any
  // frame the grid is anchored in).
  GridRayTraversal(const GridGeometry& grid, const Eigen::Vector2d& p_start, const Eigen::Vector2d& p_end);

  // The current cell.
  [[nodiscard]] CellIndex cell() const { return cell_; }
  // The cell of the end point.
  [[nodiscard]] CellIndex end_cell() const { return end_cell_; }
  // True once the current cell is the end cell.
  [[nodiscard]] bool done() const { return (remaining_x_ | remaining_y_) == 0; }
  // Number of cells still ahead of the current cell.
  [[nodiscard]] std::int32_t remaining_cells() const { return remaining_x_ + remaining_y_; }

  // Moves to the next cell along the segment and returns the index change, (+-1, 0) or (0, +-1); precondition:
  // !done().
  CellStep advance() {
    if (t_next_x_ <= t_next_y_) {
      cell_.ix += step_x_;
      t_next_x_ = --remaining_x_ == 0 ? kNever : t_next_x_ + t_delta_x_;
      return {step_x_, 0};
    }
    cell_.iy += step_y_;
    t_next_y_ = --remaining_y_ == 0 ? kNever : t_next_y_ + t_delta_y_;
    return {0, step_y_};
  }

 private:
  // Segment parameter of an axis with no cell side left to cross.
  static constexpr double kNever = std::numeric_limits<double>::infinity();

  CellIndex cell_;
  CellIndex end_cell_;
  std::int32_t step_x_ = 0;
  std::int32_t step_y_ = 0;
  // Cell sides still to cross along x / y.
  std::int32_t remaining_x_ = 0;
  std::int32_t remaining_y_ = 0;
  // Segment parameter t in [0, 1] at which the segment crosses the next vertical / horizontal cell side; kNever once
  // no side is left on that axis.
  double t_next_x_ = kNever;
  double t_next_y_ = kNever;
  // Increase of t between two consecutive vertical / horizontal cell sides.
  double t_delta_x_ = 0.0;
  double t_delta_y_ = 0.0;
};

// Calls visit(cell) for every cell of the segment from the start cell up to but excluding the end cell, in order, and
// returns the end cell (the start cell for a segment inside one cell, when nothing is visited). Throws like
// GridRayTraversal.
template <typename Visit>
requires std::invocable<Visit&, const CellIndex&> CellIndex for_each_cell_before_end(const GridGeometry& grid,
                                                                                     const Eigen::Vector2d& p_start,
                                                                                     const Eigen::Vector2d& p_end,
                                                                                     Visit&& visit) {
  const GridRayTraversal start(grid, p_start, p_end);
  // A copy whose address never leaves this function, so the optimiser can keep it in registers even when visit
  // stores through pointers that might alias it.
  GridRayTraversal traversal = start;
  while (!traversal.done()) {
    const CellIndex cell = traversal.cell();
    visit(cell);
    traversal.advance();
  }
  return traversal.cell();
}

// Calls visit(cell) for every cell of the segment from the start cell to the end cell inclusive, in order. Throws like
// GridRayTraversal.
template <typename Visit>
requires std::invocable<Visit&, const CellIndex&>
void for_each_ray_cell(const GridGeometry& grid, const Eigen::Vector2d& p_start, const Eigen::Vector2d& p_end,
                       Visit&& visit) {
  visit(for_each_cell_before_end(grid, p_start, p_end, visit));
}

}  // namespace occgeo::geometry
