#include "occgeo/mapfile/certainty_image.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace occgeo::mapfile {

namespace {
double occupancy_probability(std::uint8_t grey) { return (255.0 - grey) / 255.0; }
}  // namespace

CertaintyGreyLevels::CertaintyGreyLevels(int max_certainty, int occupied_threshold) {
  const int max = max_certainty;
  const int threshold = occupied_threshold;
  const double uniform_step = 254.0 / max;
  const double free_step = threshold > 1 ? std::min(uniform_step, (254.0 - 206.0) / (threshold - 1)) : uniform_step;
  const double occupied_step = max > threshold ? std::min(uniform_step, 204.0 / (max - threshold)) : uniform_step;
  value_of_grey_.fill(std::nullopt);
  for (int c = 0; c <= max; ++c) {
    const double grey = c < threshold ? 254.0 - c * free_step : (max - c) * occupied_step;
    grey_of_certainty_[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(std::lround(grey));
    value_of_grey_[grey_of_certainty_[static_cast<std::size_t>(c)]] = static_cast<std::uint8_t>(c);
  }
  value_of_grey_[kUnobservedGrey] = kUnobservedCertainty;
  const double p_unobserved = occupancy_probability(kUnobservedGrey);
  free_thresh_ =
      0.5 * (occupancy_probability(grey_of_certainty_[static_cast<std::size_t>(threshold - 1)]) + p_unobserved);
  occupied_thresh_ =
      0.5 * (p_unobserved + occupancy_probability(grey_of_certainty_[static_cast<std::size_t>(threshold)]));
}

OccupancyImage image_from_certainty(const CertaintyWindow& window) {
  if (window.max_certainty < 1 || window.max_certainty > 15 || window.occupied_threshold < 1 ||
      window.occupied_threshold > window.max_certainty) {
    throw MapFileError("certainty window: occupied_threshold " + std::to_string(window.occupied_threshold) +
                       " and max_certainty " + std::to_string(window.max_certainty) +
                       " must satisfy 1 <= threshold <= max <= 15");
  }
  if (window.cells.size() != static_cast<std::size_t>(window.width) * window.height) {
    throw MapFileError("certainty window: " + std::to_string(window.cells.size()) + " cells for " +
                       std::to_string(window.width) + " x " + std::to_string(window.height));
  }
  const CertaintyGreyLevels grey_levels(window.max_certainty, window.occupied_threshold);
  OccupancyImage image;
  image.width = window.width;
  image.height = window.height;
  image.resolution = window.cell_size_m;
  image.origin_x = window.min_ix * window.cell_size_m;
  image.origin_y = window.min_iy * window.cell_size_m;
  image.occupied_thresh = grey_levels.occupied_thresh();
  image.free_thresh = grey_levels.free_thresh();
  image.pixels.resize(window.cells.size());
  for (std::uint32_t row = 0; row < window.height; ++row) {
    // Image row 0 is the top (largest y); window row 0 is the bottom.
    const std::size_t window_row = window.height - 1 - row;
    for (std::uint32_t col = 0; col < window.width; ++col) {
      std::uint8_t value = window.cells[window_row * window.width + col];
      if (value != kUnobservedCertainty && value > window.max_certainty)
        value = static_cast<std::uint8_t>(window.max_certainty);
      image.pixels[static_cast<std::size_t>(row) * window.width + col] = grey_levels.grey_of(value);
    }
  }
  return image;
}

}  // namespace occgeo::mapfile
