#include "map_score.h"

#include <fstream>
#include <sstream>

namespace occgeo::testing {

CellSet read_visible_cells(const std::filesystem::path& file, const WorldTruth& truth) {
  CellSet cells;
  std::ifstream in(file);
  std::uint32_t col = 0;
  std::uint32_t row = 0;
  while (in >> col >> row) cells.insert(truth.cell_of_pixel(col, row));
  return cells;
}

bool marked_within_one_cell(const CellSet& marked, const std::pair<int, int>& cell) {
  for (int dx = -1; dx <= 1; ++dx) {
    for (int dy = -1; dy <= 1; ++dy) {
      if (marked.contains({cell.first + dx, cell.second + dy})) return true;
    }
  }
  return false;
}

MapScore score_map(const CellSet& visible, const mapfile::OccupancyImage& map, const WorldTruth& truth) {
  MapScore score;
  const CellSet marked = occupied_cells(map);
  score.visible = visible.size();
  for (const auto& cell : visible) score.found += marked_within_one_cell(marked, cell) ? 1 : 0;
  for (const auto& cell : marked) {
    if (!truth.free_cells().contains(cell)) continue;
    ++score.false_marks;
    if (!marked_within_one_cell(truth.obstacles(), cell)) ++score.false_marks_beyond_one_cell;
  }
  score.free_cells = truth.free_cells().size();
  for (const auto& cell : observed_cells(map)) score.observed_free += truth.free_cells().contains(cell) ? 1 : 0;
  return score;
}

std::string MapScore::describe() const {
  std::ostringstream out;
  out << visible << " obstacle cells seen, " << found << " marked within one cell (" << 100.0 * recall() << "%); "
      << false_marks << " of " << free_cells << " free cells marked occupied (" << 100.0 * false_rate() << "%; "
      << 100.0 * observed_false_rate() << "% of the " << observed_free << " free cells observed); "
      << false_marks_beyond_one_cell << " of them more than one cell from any obstacle ("
      << 100.0 * false_rate_beyond_one_cell() << "%)";
  return out.str();
}

}  // namespace occgeo::testing
