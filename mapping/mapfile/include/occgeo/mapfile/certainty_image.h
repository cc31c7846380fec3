#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "occgeo/mapfile/map_file.h"

namespace occgeo::mapfile {

// Cell value of a HIMM cell never observed.
inline constexpr std::uint8_t kUnobservedCertainty = 255;
// Grey level of unobserved cells: map_server reads it as unknown with its default thresholds (p = 50/255 between
// free_thresh 0.196 and occupied_thresh 0.65), and no certainty maps onto it.
inline constexpr std::uint8_t kUnobservedGrey = 205;

// The lossless mapping between HIMM certainties (0..max_certainty, or unobserved) and PGM grey levels, with the
// map_server thresholds that read exactly the certainties >= occupied_threshold as occupied. Free certainties (below
// the threshold T) descend from 254 and occupied ones ascend from 0 to 254 * (1 - T / max) in steps of 254 / max, so
// the default parameters give round(254 * (1 - c / 15)); where that would put a free certainty at or below 205, or
// an occupied one at or above it, that side's step shrinks to fit between 254 and 206, or 204 and 0. Every step
// stays above one grey level, so rounding keeps certainties apart.
class CertaintyGreyLevels {
 public:
  // Preconditions: 1 <= occupied_threshold <= max_certainty <= 15.
  CertaintyGreyLevels(int max_certainty, int occupied_threshold);

  // Grey level of a cell value (a certainty or kUnobservedCertainty).
  [[nodiscard]] std::uint8_t grey_of(std::uint8_t value) const {
    return value == kUnobservedCertainty ? kUnobservedGrey : grey_of_certainty_[value];
  }
  // The cell value whose grey level is grey, if any.
  [[nodiscard]] std::optional<std::uint8_t> value_of(std::uint8_t grey) const { return value_of_grey_[grey]; }
  // occupied_thresh that makes map_server read exactly the occupied certainties as occupied.
  [[nodiscard]] double occupied_thresh() const { return occupied_thresh_; }
  // free_thresh that makes map_server read exactly the free certainties as free, and unobserved cells as unknown.
  [[nodiscard]] double free_thresh() const { return free_thresh_; }

 private:
  std::array<std::uint8_t, 16> grey_of_certainty_{};
  std::array<std::optional<std::uint8_t>, 256> value_of_grey_{};
  double occupied_thresh_ = 0.0;
  double free_thresh_ = 0.0;
};

// A rectangle of HIMM cell values: row-major, row 0 at min_iy (the lowest y), cell (ix, iy) covering
// [ix*s, (ix+1)*s) x [iy*s, (iy+1)*s) for cell size s in metres.
struct CertaintyWindow {
  double cell_size_m = 0.1;
  std::int32_t min_ix = 0;
  std::int32_t min_iy = 0;
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  int max_certainty = 15;
  int occupied_threshold = 3;
  std::vector<std::uint8_t> cells;
};

// The window as a map_server image (row 0 at the top, origin at the window's lower-left corner); throws
// MapFileError when the cell count or the certainty parameters are inconsistent.
OccupancyImage image_from_certainty(const CertaintyWindow& window);

}  // namespace occgeo::mapfile
