#include "occgeo/geometry/grid_ray.h"

#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>

namespace occgeo::geometry {

namespace {

// One axis of a traversal from coordinate u0 to u1 (cell units), whose cells are first and last: index step, cell
// sides to cross, and the segment parameter t of the first crossing and between crossings.
struct AxisWalk {
  std::int32_t step = 0;
  std::int32_t sides = 0;
  double t_next = std::numeric_limits<double>::infinity();
  double t_delta = 0.0;
};

AxisWalk walk_axis(double u0, double u1, std::int32_t first, std::int32_t last) {
  AxisWalk walk;
  walk.sides = std::abs(last - first);
  if (walk.sides == 0) return walk;
  // The cells differ only if the coordinate moves, so the length is not zero.
  walk.step = last > first ? 1 : -1;
  const double length = std::abs(u1 - u0);
  const double to_first_side = last > first ? static_cast<double>(first) + 1.0 - u0 : u0 - static_cast<double>(first);
  walk.t_delta = 1.0 / length;
  walk.t_next = to_first_side * walk.t_delta;
  return walk;
}

// True when u, a point in cell units, is finite and within kMaxRayCellCoordinate of the origin on both axes.
bool is_traversable_in_cells(const Eigen::Vector2d& u) {
  return std::isfinite(u.x()) && std::isfinite(u.y()) && std::abs(u.x()) < kMaxRayCellCoordinate &&
         std::abs(u.y()) < kMaxRayCellCoordinate;
}

// The cell holding u, a traversable point in cell units.
CellIndex cell_containing(const Eigen::Vector2d& u) {
  return {static_cast<std::int32_t>(std::floor(u.x())), static_cast<std::int32_t>(std::floor(u.y()))};
}

}  // namespace

bool is_traversable_point(const GridGeometry& grid, const Eigen::Vector2d& p) {
  return is_traversable_in_cells(p / grid.cell_size());
}

GridRayTraversal::GridRayTraversal(const GridGeometry& grid, const Eigen::Vector2d& p_start,
                                   const Eigen::Vector2d& p_end) {
  // Same division and rounding as GridGeometry::cell_of, so the cells found here are the ones it gives.
  const Eigen::Vector2d u_start = p_start / grid.cell_size();
  const Eigen::Vector2d u_end = p_end / grid.cell_size();
  if (!is_traversable_in_cells(u_start)) {
    throw std::invalid_argument("grid ray: start point is not finite or too far from the origin");
  }
  if (!is_traversable_in_cells(u_end)) {
    throw std::invalid_argument("grid ray: end point is not finite or too far from the origin");
  }
  cell_ = cell_containing(u_start);
  end_cell_ = cell_containing(u_end);
  const AxisWalk x = walk_axis(u_start.x(), u_end.x(), cell_.ix, end_cell_.ix);
  const AxisWalk y = walk_axis(u_start.y(), u_end.y(), cell_.iy, end_cell_.iy);
  step_x_ = x.step;
  step_y_ = y.step;
  remaining_x_ = x.sides;
  remaining_y_ = y.sides;
  t_next_x_ = x.t_next;
  t_next_y_ = y.t_next;
  t_delta_x_ = x.t_delta;
  t_delta_y_ = y.t_delta;
}

}  // namespace occgeo::geometry
