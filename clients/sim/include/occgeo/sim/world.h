#pragma once

#include <Eigen/Core>
#include <compare>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace occgeo::mapfile {
struct OccupancyImage;
}

namespace occgeo::sim {

// A pixel of a world image: column counted from the left, row from the top (row 0 holds the largest y).
struct Pixel {
  int col = 0;
  int row = 0;
  friend auto operator<=>(const Pixel&, const Pixel&) = default;
};

// Raised when a world cannot be built; the message names the file or the field at fault.
class WorldError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The simulator's ground truth: which pixels of an axis-aligned map image are obstacles. Pixel (col, row) is the closed
// square [x_of_column_edge(col), x_of_column_edge(col + 1)] x [y_of_row_edge(row + 1), y_of_row_edge(row)] in the
// world frame (metres); everything outside the image is free space.
class World {
 public:
  // Builds a world from rows of text, top row first: '#' marks an obstacle pixel, any other character free space.
  // origin is the world position of the image's lower-left corner, metres. Throws WorldError on ragged or empty rows
  // or a resolution that is not positive and finite.
  static World from_rows(const std::vector<std::string_view>& rows, double resolution_m, const Eigen::Vector2d& origin);

  // Obstacles are the image's occupied pixels; unknown pixels count as free space. Throws WorldError when the image's
  // origin is rotated (origin yaw != 0), which the simulator does not support.
  static World from_image(const mapfile::OccupancyImage& image);

  [[nodiscard]] int width() const { return width_; }
  [[nodiscard]] int height() const { return height_; }
  [[nodiscard]] double resolution_m() const { return resolution_m_; }
  // World position of the image's lower-left corner, metres.
  [[nodiscard]] const Eigen::Vector2d& origin() const { return origin_; }

  // True when the pixel is inside the image and an obstacle.
  [[nodiscard]] bool is_obstacle(const Pixel& pixel) const {
    return pixel.col >= 0 && pixel.col < width_ && pixel.row >= 0 && pixel.row < height_ &&
           obstacles_[static_cast<std::size_t>(pixel.row) * static_cast<std::size_t>(width_) +
                      static_cast<std::size_t>(pixel.col)] != 0;
  }
  // World x of the left edge of column k (k = width() gives the image's right edge), metres.
  [[nodiscard]] double x_of_column_edge(int k) const { return origin_.x() + k * resolution_m_; }
  // World y of the top edge of row k (k = height() gives the image's bottom edge), metres.
  [[nodiscard]] double y_of_row_edge(int k) const { return origin_.y() + (height_ - k) * resolution_m_; }
  // World position of a pixel's centre, metres.
  [[nodiscard]] Eigen::Vector2d center_of(const Pixel& pixel) const {
    return {x_of_column_edge(pixel.col) + 0.5 * resolution_m_, y_of_row_edge(pixel.row + 1) + 0.5 * resolution_m_};
  }

  // The column whose span [left edge, right edge) holds x, metres; -1 left of the image, width() right of it.
  [[nodiscard]] int column_of(double x) const;
  // The row whose span [bottom edge, top edge) holds y, metres; -1 above the image, height() below it.
  [[nodiscard]] int row_of(double y) const;

 private:
  World(int width, int height, double resolution_m, const Eigen::Vector2d& origin, std::vector<std::uint8_t> obstacles);

  int width_;
  int height_;
  double resolution_m_;
  Eigen::Vector2d origin_;
  std::vector<std::uint8_t> obstacles_;  // row-major, row 0 at the top; non-zero marks an obstacle
};

// Loads a ROS map_server world (YAML plus the image it names); throws WorldError naming the file and the problem.
World load_world(const std::filesystem::path& yaml_path);

}  // namespace occgeo::sim
