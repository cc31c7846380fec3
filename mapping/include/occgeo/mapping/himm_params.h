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
  // Certainty a whole laser scan (HimmGrid::insert_scan) removes, on top of the per-beam decrements, from each cell
  // that its returning beams pass through when none of them ends within two cells of it: the sensor saw through the
  // cell, so what was there (a person who walked on) is gone. In [0, 255]; 0 keeps plain HIMM. Default 7: with the
  // beam's own decrement a full cell (15) is at 7 after one such scan and free after the second. Cells near a hit are
  // spared so that a wall that beams graze (crossing some of its cells to end on it further along) keeps its cells;
  // beams without a return do not count (they may have passed glass or a gap the pose is off by).
  int seen_through_decrement = 7;
  // Certainty from which a cell counts as occupied; in [1, max_certainty].
  int occupied_threshold = 3;
  // Cells per side of a storage tile; a power of two in [2, 1024].
  int tile_cells = 64;

  // Throws std::invalid_argument naming the first field that breaks its documented range.
  void validate() const;
};

}  // namespace occgeo::mapping
