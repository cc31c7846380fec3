#pragma once

namespace occgeo::mapping {

// Parameters of a HIMM histogram grid (Borenstein & Koren 1991); the defaults are the published values.
struct HimmParams {
  // Side of a square cell, metres; > 0.
  double cell_size_m = 0.1;
  // Certainty added to the cell a reading hits, before the growth-rate operator; in [1, max_certainty].
  int increment = 3;
  // Certainty removed from each cell a beam passes through; in [1, max_certainty].
  int decrement = 1;
  // Largest certainty a cell holds; in [1, 15] (4-bit certainties, which also map losslessly onto PGM grey levels).
  int max_certainty = 15;
  // Weight of the hit cell itself in the growth-rate operator; finite, >= 0.
  double growth_center_weight = 1.0;
  // Weight of each of the 8 neighbours of the hit cell in the growth-rate operator; finite, >= 0.
  double growth_neighbour_weight = 0.5;
  // Certainty from which a cell counts as occupied; in [1, max_certainty].
  int occupied_threshold = 3;
  // Cells per side of a storage tile; a power of two in [2, 1024].
  int tile_cells = 64;

  // Throws std::invalid_argument naming the first field that breaks its documented range.
  void validate() const;
};

}  // namespace occgeo::mapping
