#include "occgeo/mapping/himm_params.h"
#include "occgeo/geometry/checks.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace occgeo::mapping {

namespace {

void require_in_range(int value, int min, int max, const std::string& field) {
  geometry::require(value >= min && value <= max, "HimmParams." + field,
                    "must be in [" + std::to_string(min) + ", " + std::to_string(max) + "]", std::to_string(value));
}

}  // namespace

void HimmParams::validate() const {
  geometry::require(std::isfinite(cell_size_m) && cell_size_m > 0.0, "HimmParams.cell_size_m",
                    "must be a finite number > 0", geometry::number_text(cell_size_m));
  require_in_range(max_certainty, 1, 15, "max_certainty");
  require_in_range(increment, 1, max_certainty, "increment");
  require_in_range(decrement, 1, max_certainty, "decrement");
  // More than max_certainty simply empties the cell: a grid with a lower ceiling keeps the default.
  require_in_range(seen_through_decrement, 0, 255, "seen_through_decrement");
  require_in_range(occupied_threshold, 1, max_certainty, "occupied_threshold");
  geometry::require(std::isfinite(growth_center_weight) && growth_center_weight >= 0.0,
                    "HimmParams.growth_center_weight", "must be a finite number >= 0",
                    geometry::number_text(growth_center_weight));
  geometry::require(std::isfinite(growth_neighbour_weight) && growth_neighbour_weight >= 0.0,
                    "HimmParams.growth_neighbour_weight", "must be a finite number >= 0",
                    geometry::number_text(growth_neighbour_weight));
  const bool power_of_two = tile_cells > 0 && (tile_cells & (tile_cells - 1)) == 0;
  geometry::require(power_of_two && tile_cells >= 2 && tile_cells <= 1024, "HimmParams.tile_cells",
                    "must be a power of two in [2, 1024]", std::to_string(tile_cells));
}

}  // namespace occgeo::mapping
