#include "occgeo/sim/raycast.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

namespace occgeo::sim {

namespace {

constexpr double kNever = std::numeric_limits<double>::infinity();

// The normal of a column edge (vertical) entered by a ray with x-component dx: it faces back towards the ray.
Eigen::Vector2d column_edge_normal(double dx) { return {dx > 0.0 ? -1.0 : 1.0, 0.0}; }

// The normal of a row edge (horizontal) entered by a ray with y-component dy.
Eigen::Vector2d row_edge_normal(double dy) { return {0.0, dy > 0.0 ? -1.0 : 1.0}; }

// The axis normal the direction (dx, dy) most opposes, for entries through no single edge (a corner, or the start).
Eigen::Vector2d most_opposed_normal(double dx, double dy) {
  return std::abs(dx) >= std::abs(dy) ? column_edge_normal(dx) : row_edge_normal(dy);
}

// The column a ray at x moving with x-component dx is in: on a column edge, the one it moves into.
int start_column(const World& world, double x, double dx) {
  int col = world.column_of(x);
  if (dx < 0.0 && col >= 0 && col <= world.width() && x == world.x_of_column_edge(col)) --col;
  return std::clamp(col, 0, world.width() - 1);
}

// The row a ray at y moving with y-component dy is in: on a row edge, the one it moves into.
int start_row(const World& world, double y, double dy) {
  int row = world.row_of(y);
  if (dy < 0.0 && row >= -1 && row < world.height() && y == world.y_of_row_edge(row + 1)) ++row;
  return std::clamp(row, 0, world.height() - 1);
}

// Narrows [t_begin, t_end] to the part of the ray p + t*d (one axis) inside [lo, hi]; false when none is.
bool clip_axis(double p, double d, double lo, double hi, double& t_begin, double& t_end) {
  if (d == 0.0) return p >= lo && p <= hi;
  double t_lo = (lo - p) / d;
  double t_hi = (hi - p) / d;
  if (t_lo > t_hi) std::swap(t_lo, t_hi);
  t_begin = std::max(t_begin, t_lo);
  t_end = std::min(t_end, t_hi);
  return true;
}

// The index k of the row edge the horizontal line at y lies on exactly, if any (edge k lies between rows k-1 and k).
std::optional<int> row_edge_at(const World& world, double y) {
  const int row = world.row_of(y);
  if (row == -1) {
    return y == world.y_of_row_edge(0) ? std::optional<int>(0) : std::nullopt;
  }
  if (row < world.height() && y == world.y_of_row_edge(row + 1)) return row + 1;
  return std::nullopt;
}

// The index k of the column edge the vertical line at x lies on exactly, if any (edge k lies between columns k-1, k).
std::optional<int> column_edge_at(const World& world, double x) {
  const int col = world.column_of(x);
  if (col >= 0 && col <= world.width() && x == world.x_of_column_edge(col)) return col;
  return std::nullopt;
}

// A horizontal ray lying on row edge k: it enters the obstacles where the pixels on both sides of the edge are.
std::optional<RayHit> cast_along_row_edge(const World& world, const Eigen::Vector2d& p, double dx, double t_begin,
                                          double t_end, int k) {
  const int step = dx > 0.0 ? 1 : -1;
  int col = start_column(world, p.x() + t_begin * dx, dx);
  double t_entry = t_begin;
  while (col >= 0 && col < world.width()) {
    const Pixel above{col, k - 1};
    const Pixel below{col, k};
    if (world.is_obstacle(above) && world.is_obstacle(below)) {
      return RayHit{t_entry, {above, below}, column_edge_normal(dx)};
    }
    t_entry = (world.x_of_column_edge(step > 0 ? col + 1 : col) - p.x()) / dx;
    if (t_entry >= t_end) break;
    col += step;
  }
  return std::nullopt;
}

// A vertical ray lying on column edge k: it enters the obstacles where the pixels on both sides of the edge are.
std::optional<RayHit> cast_along_column_edge(const World& world, const Eigen::Vector2d& p, double dy, double t_begin,
                                             double t_end, int k) {
  const int step = dy > 0.0 ? -1 : 1;  // rows count downwards
  int row = start_row(world, p.y() + t_begin * dy, dy);
  double t_entry = t_begin;
  while (row >= 0 && row < world.height()) {
    const Pixel left{k - 1, row};
    const Pixel right{k, row};
    if (world.is_obstacle(left) && world.is_obstacle(right)) return RayHit{t_entry, {left, right}, row_edge_normal(dy)};
    t_entry = (world.y_of_row_edge(step < 0 ? row : row + 1) - p.y()) / dy;
    if (t_entry >= t_end) break;
    row += step;
  }
  return std::nullopt;
}

}  // namespace

std::optional<RayHit> cast_ray(const World& world, const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W,
                               double max_range_m) {
  if (!p_W.allFinite() || !direction_W.allFinite() || !std::isfinite(max_range_m) || max_range_m < 0.0) {
    throw std::invalid_argument("cast_ray: origin, direction and max range must be finite, max range >= 0");
  }
  const double dx = direction_W.x();
  const double dy = direction_W.y();
  double t_begin = 0.0;
  double t_end = max_range_m;
  if (!clip_axis(p_W.x(), dx, world.x_of_column_edge(0), world.x_of_column_edge(world.width()), t_begin, t_end) ||
      !clip_axis(p_W.y(), dy, world.y_of_row_edge(world.height()), world.y_of_row_edge(0), t_begin, t_end) ||
      t_begin >= t_end) {
    return std::nullopt;
  }
  if (dy == 0.0) {
    if (const auto k = row_edge_at(world, p_W.y())) return cast_along_row_edge(world, p_W, dx, t_begin, t_end, *k);
  }
  if (dx == 0.0) {
    if (const auto k = column_edge_at(world, p_W.x())) {
      return cast_along_column_edge(world, p_W, dy, t_begin, t_end, *k);
    }
  }

  // Amanatides & Woo traversal; each crossing distance is computed from the edge itself, so none accumulates error.
  const Eigen::Vector2d q = p_W + t_begin * direction_W;
  Pixel pixel{start_column(world, q.x(), dx), start_row(world, q.y(), dy)};
  const int col_step = dx > 0.0 ? 1 : -1;
  const int row_step = dy > 0.0 ? -1 : 1;  // rows count downwards
  double t_entry = t_begin;
  // The first pixel is entered through the image border when the ray starts outside the image (t_begin > 0): through a
  // column edge when the x clip set t_begin (later than the y clip), else a row edge; otherwise it is the start.
  Eigen::Vector2d entry_normal = most_opposed_normal(dx, dy);
  if (t_begin > 0.0) {
    const double t_x_border =
        dx == 0.0 ? -kNever : (world.x_of_column_edge(dx > 0.0 ? 0 : world.width()) - p_W.x()) / dx;
    const double t_y_border = dy == 0.0 ? -kNever : (world.y_of_row_edge(dy > 0.0 ? world.height() : 0) - p_W.y()) / dy;
    if (t_x_border > t_y_border) entry_normal = column_edge_normal(dx);
    if (t_y_border > t_x_border) entry_normal = row_edge_normal(dy);
  }
  while (true) {
    if (world.is_obstacle(pixel)) return RayHit{t_entry, {pixel}, entry_normal};
    const double t_x =
        dx == 0.0 ? kNever : (world.x_of_column_edge(dx > 0.0 ? pixel.col + 1 : pixel.col) - p_W.x()) / dx;
    const double t_y = dy == 0.0 ? kNever : (world.y_of_row_edge(dy > 0.0 ? pixel.row : pixel.row + 1) - p_W.y()) / dy;
    const double t_next = std::min(t_x, t_y);
    if (t_next >= t_end) return std::nullopt;
    // Through an exact corner the ray passes diagonally: the two pixels beside the corner are only touched.
    if (t_x <= t_y) pixel.col += col_step;
    if (t_y <= t_x) pixel.row += row_step;
    entry_normal = t_x < t_y ? column_edge_normal(dx) : t_y < t_x ? row_edge_normal(dy) : most_opposed_normal(dx, dy);
    if (pixel.col < 0 || pixel.col >= world.width() || pixel.row < 0 || pixel.row >= world.height()) {
      return std::nullopt;
    }
    t_entry = t_next;
  }
}

}  // namespace occgeo::sim
