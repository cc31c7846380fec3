#include "occgeo/sim/world.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "occgeo/mapfile/map_file.h"

namespace occgeo::sim {

World::World(int width, int height, double resolution_m, const Eigen::Vector2d& origin,
             std::vector<std::uint8_t> obstacles)
    : width_(width), height_(height), resolution_m_(resolution_m), origin_(origin), obstacles_(std::move(obstacles)) {}

World World::from_rows(const std::vector<std::string_view>& rows, double resolution_m, const Eigen::Vector2d& origin) {
  if (!(std::isfinite(resolution_m) && resolution_m > 0.0)) {
    throw WorldError("world resolution must be positive and finite, got " + std::to_string(resolution_m));
  }
  if (!origin.allFinite()) throw WorldError("world origin must be finite");
  if (rows.empty() || rows.front().empty()) throw WorldError("world rows must not be empty");
  const std::size_t width = rows.front().size();
  std::vector<std::uint8_t> obstacles;
  obstacles.reserve(width * rows.size());
  for (const std::string_view row : rows) {
    if (row.size() != width) throw WorldError("world rows must all have " + std::to_string(width) + " characters");
    for (const char pixel : row) obstacles.push_back(pixel == '#' ? 1 : 0);
  }
  return World(static_cast<int>(width), static_cast<int>(rows.size()), resolution_m, origin, std::move(obstacles));
}

World World::from_image(const mapfile::OccupancyImage& image) {
  if (image.origin_yaw != 0.0) {
    throw WorldError("world origin yaw must be 0 (rotated map images are not supported), got " +
                     std::to_string(image.origin_yaw));
  }
  const int width = static_cast<int>(image.width);
  const int height = static_cast<int>(image.height);
  std::vector<std::uint8_t> obstacles(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), 0);
  for (int row = 0; row < height; ++row) {
    for (int col = 0; col < width; ++col) {
      if (image.state(static_cast<std::uint32_t>(col), static_cast<std::uint32_t>(row)) ==
          mapfile::OccupancyImage::CellState::occupied) {
        obstacles[static_cast<std::size_t>(row) * static_cast<std::size_t>(width) + static_cast<std::size_t>(col)] = 1;
      }
    }
  }
  return World(width, height, image.resolution, {image.origin_x, image.origin_y}, std::move(obstacles));
}

int World::column_of(double x) const {
  if (!(x >= x_of_column_edge(0))) return -1;
  if (x >= x_of_column_edge(width_)) return width_;
  // The division may round across an edge; the loops settle on the column whose computed edges hold x.
  int col = std::clamp(static_cast<int>(std::floor((x - origin_.x()) / resolution_m_)), 0, width_ - 1);
  while (x < x_of_column_edge(col)) --col;
  while (x >= x_of_column_edge(col + 1)) ++col;
  return col;
}

int World::row_of(double y) const {
  if (!(y < y_of_row_edge(0))) return -1;
  if (y < y_of_row_edge(height_)) return height_;
  int row = std::clamp(height_ - 1 - static_cast<int>(std::floor((y - origin_.y()) / resolution_m_)), 0, height_ - 1);
  while (y >= y_of_row_edge(row)) --row;
  while (y < y_of_row_edge(row + 1)) ++row;
  return row;
}

World load_world(const std::filesystem::path& yaml_path) {
  try {
    return World::from_image(mapfile::read_map_yaml(yaml_path));
  } catch (const mapfile::MapFileError& error) {
    throw WorldError(error.what());
  } catch (const WorldError& error) {
    throw WorldError(yaml_path.string() + ": " + error.what());
  }
}

}  // namespace occgeo::sim
