#pragma once

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <vector>

namespace occgeo::mapfile {

// A file that cannot be read or written as a map_server map; the message names the file and the field or problem.
class MapFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A world point, metres.
struct MapPoint {
  double x = 0.0;
  double y = 0.0;
};

// A ROS map_server occupancy image (PGM grey levels plus the YAML metadata).
struct OccupancyImage {
  enum class CellState { free, occupied, unknown };

  std::uint32_t width = 0;
  std::uint32_t height = 0;
  // Side of a pixel, metres.
  double resolution = 0.0;
  // World pose of the south-west corner of the bottom-left pixel, metres and radians (only 0 is supported).
  double origin_x = 0.0;
  double origin_y = 0.0;
  double origin_yaw = 0.0;
  // width * height grey levels, row-major, row 0 = top of the image = largest y, as in PGM.
  std::vector<std::uint8_t> pixels;
  // Occupancy probability above which a pixel reads occupied, in [0, 1].
  double occupied_thresh = 0.65;
  // Occupancy probability below which a pixel reads free, in [0, 1].
  double free_thresh = 0.196;
  // When true a pixel's occupancy probability is pixel/255 instead of (255 - pixel)/255.
  bool negate = false;

  // Grey level of pixel (col, row); precondition: col < width, row < height.
  [[nodiscard]] std::uint8_t pixel(std::uint32_t col, std::uint32_t row) const {
    return pixels[static_cast<std::size_t>(row) * width + col];
  }
  // map_server's trinary reading of pixel (col, row): occupied if p > occupied_thresh, free if p < free_thresh, else
  // unknown, with p its occupancy probability; precondition: col < width, row < height.
  [[nodiscard]] CellState state(std::uint32_t col, std::uint32_t row) const;
  // World centre of pixel (col, row), metres: (origin_x + (col + 0.5) * resolution,
  // origin_y + (height - 1 - row + 0.5) * resolution).
  [[nodiscard]] MapPoint pixel_center(std::uint32_t col, std::uint32_t row) const;
};

// Reads a map_server YAML file and the PGM image it names (relative to the YAML file's folder; binary P5 or plain P2,
// at most 8 bits per pixel, scaled to 0..255). Throws MapFileError naming the file and the key or problem: a missing
// or malformed key, a key map_server does not define, origin yaw other than 0, mode "raw", an unreadable image.
[[nodiscard]] OccupancyImage read_map_yaml(const std::filesystem::path& yaml_file);

// Writes image as PREFIX.pgm (binary P5) and PREFIX.yaml (naming the image by its file name, mode trinary); throws
// MapFileError when a file cannot be written or the image is inconsistent (pixel count, resolution, yaw).
void write_map(const std::filesystem::path& prefix, const OccupancyImage& image);

}  // namespace occgeo::mapfile
