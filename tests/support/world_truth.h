#pragma once

#include <Eigen/Core>
#include <set>
#include <utility>

#include "occgeo/mapfile/map_file.h"

namespace occgeo::testing {

// Ground truth of a simulator world, in the server grid's cell indices (cells of the image's
// resolution anchored at the world origin; the shipped worlds align their pixels with them).
class WorldTruth {
 public:
  explicit WorldTruth(const mapfile::OccupancyImage& image);

  [[nodiscard]] double cell_size() const { return cell_size_; }
  [[nodiscard]] const std::set<std::pair<int, int>>& obstacles() const { return obstacles_; }
  [[nodiscard]] const std::set<std::pair<int, int>>& free_cells() const { return free_; }
  // Grid cell of an image pixel.
  [[nodiscard]] std::pair<int, int> cell_of_pixel(std::uint32_t col, std::uint32_t row) const;
  // Exact distance from a box (length along the pose's heading, width across, centred at
  // (center_x, 0) in the pose's frame) to the nearest obstacle cell, by brute force; 0 on overlap.
  [[nodiscard]] double box_distance(double x, double y, double theta, double length, double width,
                                    double center_x) const;

 private:
  double cell_size_;
  double origin_x_;
  double origin_y_;
  std::uint32_t height_;
  std::set<std::pair<int, int>> obstacles_;
  std::set<std::pair<int, int>> free_;
};

// The occupied cells of a map_server image (e.g. an exported grid), as grid cell indices.
std::set<std::pair<int, int>> occupied_cells(const mapfile::OccupancyImage& image);
// The cells of a map_server image that are not unknown (free or occupied).
std::set<std::pair<int, int>> observed_cells(const mapfile::OccupancyImage& image);

}  // namespace occgeo::testing
