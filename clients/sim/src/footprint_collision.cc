#include "occgeo/sim/footprint_collision.h"

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>

#include "separating_axis.h"

namespace occgeo::sim {

namespace {

using detail::Interval;
using detail::overlaps;
using detail::project;

}  // namespace

std::optional<Pixel> find_collision(const World& world, const geometry::BoxFootprint& footprint,
                                    const geometry::Pose2& X_WB) {
  const double half_length = footprint.length / 2.0;
  const double half_width = footprint.width / 2.0;
  const std::array<Eigen::Vector2d, 4> box_corners_W = {
      X_WB.transform({footprint.center_x + half_length, half_width}),
      X_WB.transform({footprint.center_x - half_length, half_width}),
      X_WB.transform({footprint.center_x - half_length, -half_width}),
      X_WB.transform({footprint.center_x + half_length, -half_width})};
  const Eigen::Vector2d box_x_axis(std::cos(X_WB.theta), std::sin(X_WB.theta));
  const Eigen::Vector2d box_y_axis(-box_x_axis.y(), box_x_axis.x());
  const Interval box_on_x = project(box_corners_W, Eigen::Vector2d::UnitX());
  const Interval box_on_y = project(box_corners_W, Eigen::Vector2d::UnitY());
  const Interval box_on_box_x = project(box_corners_W, box_x_axis);
  const Interval box_on_box_y = project(box_corners_W, box_y_axis);

  // Pixels whose squares can overlap the box's bounding box (rows count downwards, so the top y gives the first row).
  const int first_col = std::max(world.column_of(box_on_x.lo), 0);
  const int last_col = std::min(world.column_of(box_on_x.hi), world.width() - 1);
  const int first_row = std::max(world.row_of(box_on_y.hi), 0);
  const int last_row = std::min(world.row_of(box_on_y.lo), world.height() - 1);
  for (int row = first_row; row <= last_row; ++row) {
    const Interval pixel_on_y{world.y_of_row_edge(row + 1), world.y_of_row_edge(row)};
    if (!overlaps(box_on_y, pixel_on_y)) continue;
    for (int col = first_col; col <= last_col; ++col) {
      const Pixel pixel{col, row};
      if (!world.is_obstacle(pixel)) continue;
      const Interval pixel_on_x{world.x_of_column_edge(col), world.x_of_column_edge(col + 1)};
      if (!overlaps(box_on_x, pixel_on_x)) continue;
      const std::array<Eigen::Vector2d, 4> pixel_corners_W = {
          Eigen::Vector2d(pixel_on_x.lo, pixel_on_y.lo), Eigen::Vector2d(pixel_on_x.hi, pixel_on_y.lo),
          Eigen::Vector2d(pixel_on_x.hi, pixel_on_y.hi), Eigen::Vector2d(pixel_on_x.lo, pixel_on_y.hi)};
      if (overlaps(box_on_box_x, project(pixel_corners_W, box_x_axis)) &&
          overlaps(box_on_box_y, project(pixel_corners_W, box_y_axis))) {
        return pixel;
      }
    }
  }
  return std::nullopt;
}

}  // namespace occgeo::sim
