#include "occgeo/mapping/himm_params.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "format_number.h"

namespace occgeo::mapping {

namespace {

void require(bool condition, const std::string& field, const std::string& rule, const std::string& value) {
  if (!condition) throw std::invalid_argument("HimmParams." + field + " must be " + rule + ", got " + value);
}

void require_in_range(int value, int min, int max, const std::string& field) {
  require(value >= min && value <= max, field, "in [" + std::to_string(min) + ", " + std::to_string(max) + "]",
          std::to_string(value));
}

}  // namespace

void HimmParams::validate() const {
  require(std::isfinite(cell_size_m) && cell_size_m > 0.0, "cell_size_m", "a finite number > 0",
          format_number(cell_size_m));
  require_in_range(max_certainty, 1, 15, "max_certainty");
  require_in_range(increment, 1, max_certainty, "increment");
  require_in_range(decrement, 1, max_certainty, "decrement");
  // More than max_certainty simply empties the cell: a grid with a lower ceiling keeps the default.
  require_in_range(seen_through_decrement, 0, 255, "seen_through_decrement");
  require_in_range(occupied_threshold, 1, max_certainty, "occupied_threshold");
  require(std::isfinite(growth_center_weight) && growth_center_weight >= 0.0, "growth_center_weight",
          "a finite number >= 0", format_number(growth_center_weight));
  require(std::isfinite(growth_neighbour_weight) && growth_neighbour_weight >= 0.0, "growth_neighbour_weight",
          "a finite number >= 0", format_number(growth_neighbour_weight));
  const bool power_of_two = tile_cells > 0 && (tile_cells & (tile_cells - 1)) == 0;
  require(power_of_two && tile_cells >= 2 && tile_cells <= 1024, "tile_cells", "a power of two in [2, 1024]",
          std::to_string(tile_cells));
}

}  // namespace occgeo::mapping
