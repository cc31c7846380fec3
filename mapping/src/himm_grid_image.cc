// Conversion between a HimmGrid and a map_server occupancy image.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

#include "himm_tile_writer.h"
#include "occgeo/geometry/checks.h"
#include "occgeo/geometry/grid_ray.h"
#include "occgeo/mapfile/certainty_image.h"
#include "occgeo/mapping/himm_grid.h"

namespace occgeo::mapping {

namespace {

void check_convertible(const mapfile::OccupancyImage& image, const HimmParams& params) {
  if (!(std::abs(image.resolution - params.cell_size_m) <= 1e-9 * params.cell_size_m)) {
    throw std::invalid_argument("from_image: image resolution " + geometry::number_text(image.resolution) +
                                " differs from cell_size_m " + geometry::number_text(params.cell_size_m));
  }
  if (image.origin_yaw != 0.0) {
    throw std::invalid_argument("from_image: origin_yaw " + geometry::number_text(image.origin_yaw) +
                                " is not supported (only 0)");
  }
  if (image.pixels.size() != static_cast<std::size_t>(image.width) * image.height) {
    throw std::invalid_argument("from_image: pixels holds " + std::to_string(image.pixels.size()) +
                                " values, width * height is " +
                                std::to_string(static_cast<std::uint64_t>(image.width) * image.height));
  }
  const geometry::GridGeometry grid(params.cell_size_m);
  const Eigen::Vector2d far_corner(image.origin_x + image.width * image.resolution,
                                   image.origin_y + image.height * image.resolution);
  if (!geometry::is_traversable_point(grid, {image.origin_x, image.origin_y}) ||
      !geometry::is_traversable_point(grid, far_corner)) {
    throw std::invalid_argument("from_image: the image is not finite or lies too far from the origin");
  }
}

// Cell value of pixel (col, row): the value of its grey level if it has one (image not negated), else by the trinary
// reading occupied -> max_certainty, free -> 0, unknown -> kUnobserved.
std::uint8_t cell_value_of_pixel(const mapfile::OccupancyImage& image, std::uint32_t col, std::uint32_t row,
                                 const mapfile::CertaintyGreyLevels& grey_levels, const HimmParams& params) {
  if (!image.negate) {
    if (const std::optional<std::uint8_t> exact = grey_levels.value_of(image.pixel(col, row))) return *exact;
  }
  switch (image.state(col, row)) {
    case mapfile::OccupancyImage::CellState::occupied:
      return static_cast<std::uint8_t>(params.max_certainty);
    case mapfile::OccupancyImage::CellState::free:
      return 0;
    case mapfile::OccupancyImage::CellState::unknown:
      break;
  }
  return kUnobserved;
}

}  // namespace

HimmGrid HimmGrid::from_image(const mapfile::OccupancyImage& image, const HimmParams& params) {
  params.validate();
  check_convertible(image, params);
  HimmGrid grid(params);
  const mapfile::CertaintyGreyLevels grey_levels(params.max_certainty, params.occupied_threshold);
  // Cell of the image's bottom-left pixel: its origin snapped to the nearest cell corner.
  const auto first_ix = static_cast<std::int32_t>(std::lround(image.origin_x / params.cell_size_m));
  const auto first_iy = static_cast<std::int32_t>(std::lround(image.origin_y / params.cell_size_m));
  TileWriter writer(grid);
  for (std::uint32_t row = 0; row < image.height; ++row) {
    const auto iy = static_cast<std::int32_t>(first_iy + std::int64_t{image.height - 1 - row});
    for (std::uint32_t col = 0; col < image.width; ++col) {
      const std::uint8_t value = cell_value_of_pixel(image, col, row, grey_levels, params);
      if (value != kUnobserved) writer.set({static_cast<std::int32_t>(first_ix + std::int64_t{col}), iy}, value);
    }
  }
  return grid;
}

mapfile::OccupancyImage HimmGrid::to_image() const {
  const mapfile::CertaintyGreyLevels grey_levels(params_.max_certainty, params_.occupied_threshold);
  mapfile::OccupancyImage image;
  image.resolution = params_.cell_size_m;
  image.occupied_thresh = grey_levels.occupied_thresh();
  image.free_thresh = grey_levels.free_thresh();
  if (!tile_bounds_) return image;
  const CellBox& bounds = *tile_bounds_;
  image.width = static_cast<std::uint32_t>(bounds.max.ix - bounds.min.ix + 1);
  image.height = static_cast<std::uint32_t>(bounds.max.iy - bounds.min.iy + 1);
  const Eigen::Vector2d origin = geometry_.min_corner_of(bounds.min);
  image.origin_x = origin.x();
  image.origin_y = origin.y();
  image.pixels.assign(static_cast<std::size_t>(image.width) * image.height, mapfile::kUnobservedGrey);
  for (const auto& [index, tile] : tiles_) {
    const geometry::CellIndex first = layout_.first_cell_of(index);
    for (std::int32_t local_y = 0; local_y < layout_.tile_cells(); ++local_y) {
      const auto row = static_cast<std::size_t>(bounds.max.iy - (first.iy + local_y));
      for (std::int32_t local_x = 0; local_x < layout_.tile_cells(); ++local_x) {
        const auto col = static_cast<std::size_t>(first.ix + local_x - bounds.min.ix);
        image.pixels[row * image.width + col] =
            grey_levels.grey_of(tile->cells[static_cast<std::size_t>(local_y * layout_.tile_cells() + local_x)]);
      }
    }
  }
  return image;
}

}  // namespace occgeo::mapping
