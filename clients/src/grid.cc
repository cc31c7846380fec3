#include "occgeo/client/grid.h"

namespace occgeo::client {

mapfile::CertaintyWindow certainty_window(const v1::GridReply& grid) {
  mapfile::CertaintyWindow window;
  window.cell_size_m = grid.cell_size_m();
  window.min_ix = grid.min_cell().ix();
  window.min_iy = grid.min_cell().iy();
  window.width = grid.width();
  window.height = grid.height();
  window.occupied_threshold = static_cast<int>(grid.occupied_threshold());
  window.max_certainty = static_cast<int>(grid.max_certainty());
  window.cells.assign(grid.cells().begin(), grid.cells().end());
  return window;
}

}  // namespace occgeo::client
