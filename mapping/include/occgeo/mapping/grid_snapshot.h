#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "occgeo/geometry/cell.h"
#include "occgeo/geometry/collision.h"
#include "occgeo/mapping/chunked_table.h"
#include "occgeo/mapping/tiles.h"

namespace occgeo::mapping {

class HimmGrid;

// An immutable view of a HimmGrid at one version. It shares the grid's tiles (the grid copies a tile before writing to
// a shared one), so taking it costs one pointer copy per tile, and any number of threads may read it, without locks,
// while the grid goes on ingesting.
class GridSnapshot final : public geometry::OccupiedCellSource {
 public:
  // Side of a cell, metres.
  [[nodiscard]] double cell_size() const override { return cell_size_m_; }
  // Calls visit for each occupied cell c with min <= c <= max on both axes, tile by tile (in no particular order),
  // until visit returns false; costs one look-up per tile overlapping the box, or one pass over the tiles when the box
  // overlaps more tiles than exist.
  void for_each_occupied(geometry::CellIndex min, geometry::CellIndex max,
                         const std::function<bool(const geometry::CellIndex&)>& visit) const override;

  // Certainty of cell c; 0 when c was never observed.
  [[nodiscard]] std::uint8_t certainty(const geometry::CellIndex& c) const;
  // True when a reading has updated cell c.
  [[nodiscard]] bool observed(const geometry::CellIndex& c) const;
  // True when the certainty of cell c is at least occupied_threshold().
  [[nodiscard]] bool occupied(const geometry::CellIndex& c) const;

  // Cell values of the width x height cells from min, row-major, row 0 at min.iy (y grows with the row), each a
  // certainty or kUnobserved; width * height bytes, so callers bound the size. Throws std::invalid_argument for a
  // negative size or a window beyond int32 cell indices.
  [[nodiscard]] std::vector<std::uint8_t> window(geometry::CellIndex min, int width, int height) const;

  // The parts of box (clipped to storage tiles) that inserts after `version` may have written: every allocated tile
  // overlapping box whose latest write came at a later grid version, clipped to box, in no particular order. A reader
  // holding the window's cells as of `version` gets this snapshot's cells by copying these parts over.
  [[nodiscard]] std::vector<CellBox> changed_since(std::uint64_t version, const CellBox& box) const;

  // The grid's version when the snapshot was taken.
  [[nodiscard]] std::uint64_t version() const { return version_; }
  // Certainty from which a cell counts as occupied.
  [[nodiscard]] int occupied_threshold() const { return occupied_threshold_; }
  // Number of allocated tiles.
  [[nodiscard]] std::size_t tile_count() const { return tiles_.size(); }
  // The box covered by the allocated tiles; nullopt when nothing was observed.
  [[nodiscard]] std::optional<CellBox> tile_bounds() const { return tile_bounds_; }
  // Number of cells at or above the occupied threshold.
  [[nodiscard]] std::size_t occupied_cell_count() const { return occupied_cells_; }
  // Largest certainty a cell can hold (HimmParams::max_certainty).
  [[nodiscard]] int max_certainty() const { return max_certainty_; }
  // Heap bytes of the tiles this snapshot holds (cells, tile records, their shared pointers and the index), counted;
  // the live grid shares these tiles, so this is the grid's memory too.
  [[nodiscard]] std::size_t memory_bytes() const;

 private:
  friend class HimmGrid;
  // Shared with the grid's later snapshots chunk by chunk: the grid keeps it in step with the tiles it writes.
  using SharedTiles = ChunkedTable<TileIndex, Tile, TileIndexTraits>;

  GridSnapshot(SharedTiles tiles, TileLayout layout, double cell_size_m, int occupied_threshold, int max_certainty,
               std::optional<CellBox> tile_bounds, std::uint64_t version, std::size_t occupied_cells);

  // The tile holding cell c, or nullptr when it is not allocated.
  [[nodiscard]] const Tile* find_tile(const geometry::CellIndex& c) const;
  // Calls visit on the occupied cells of tile t inside box; returns false when visit asked to stop.
  bool visit_occupied_in_tile(const TileIndex& t, const Tile& tile, const CellBox& box,
                              const std::function<bool(const geometry::CellIndex&)>& visit) const;

  SharedTiles tiles_;
  TileLayout layout_;
  double cell_size_m_;
  int occupied_threshold_;
  int max_certainty_;
  std::optional<CellBox> tile_bounds_;
  std::uint64_t version_;
  std::size_t occupied_cells_;
};

}  // namespace occgeo::mapping
