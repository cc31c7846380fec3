#pragma once

// How well a map the server exported matches what a simulated robot's sensors could see.

#include <cstddef>
#include <filesystem>
#include <set>
#include <string>
#include <utility>

#include "occgeo/mapfile/map_file.h"
#include "world_truth.h"

namespace occgeo::testing {

using CellSet = std::set<std::pair<int, int>>;

// The grid cells of the obstacle pixels listed in an `occgeo-sim --visible-out` file ("col row" per line).
CellSet read_visible_cells(const std::filesystem::path& file, const WorldTruth& truth);

// True when cell or one of its eight neighbours is in marked.
bool marked_within_one_cell(const CellSet& marked, const std::pair<int, int>& cell);

struct MapScore {
  std::size_t visible = 0;                      // obstacle cells some noise-free beam reached
  std::size_t found = 0;                        // of those, marked occupied within one cell
  std::size_t false_marks = 0;                  // free cells of the world marked occupied
  std::size_t false_marks_beyond_one_cell = 0;  // of those, not next to any obstacle cell
  std::size_t free_cells = 0;                   // free cells of the world
  std::size_t observed_free = 0;                // free cells of the world the map observed (free or occupied)

  [[nodiscard]] double recall() const { return visible == 0 ? 0.0 : double(found) / double(visible); }
  [[nodiscard]] double false_rate() const { return free_cells == 0 ? 0.0 : double(false_marks) / double(free_cells); }
  // False marks more than one cell from every obstacle, over all free cells: the same one-cell tolerance recall()
  // allows. A surface lying on a cell boundary puts about half of its noisy hits in the free cell in front of it.
  [[nodiscard]] double false_rate_beyond_one_cell() const {
    return free_cells == 0 ? 0.0 : double(false_marks_beyond_one_cell) / double(free_cells);
  }
  [[nodiscard]] double observed_false_rate() const {
    return observed_free == 0 ? 0.0 : double(false_marks) / double(observed_free);
  }
  // One line with every figure, for the test's output.
  [[nodiscard]] std::string describe() const;
};

// Scores an exported map against the world's truth and the cells the sensors saw.
MapScore score_map(const CellSet& visible, const mapfile::OccupancyImage& map, const WorldTruth& truth);

}  // namespace occgeo::testing
