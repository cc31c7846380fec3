#pragma once

#include <bit>
#include <cstdint>
#include <functional>
#include <vector>

#include "occgeo/geometry/cell.h"
#include "occgeo/mapfile/certainty_image.h"

namespace occgeo::mapping {

// A cell value meaning "never observed"; observed cells hold a certainty in [0, HimmParams::max_certainty].
inline constexpr std::uint8_t kUnobserved = mapfile::kUnobservedCertainty;

// An axis-aligned box of cells, both corners inclusive.
struct CellBox {
  geometry::CellIndex min;
  geometry::CellIndex max;
  friend bool operator==(const CellBox&, const CellBox&) = default;
};

// Index of a square storage tile: tile (tx, ty) holds the cells ix in [tx*n, (tx+1)*n), iy in [ty*n, (ty+1)*n) for
// n cells per tile side.
struct TileIndex {
  std::int32_t tx = 0;
  std::int32_t ty = 0;
  friend bool operator==(const TileIndex&, const TileIndex&) = default;
};

struct TileIndexHash {
  std::size_t operator()(const TileIndex& t) const noexcept {
    return std::hash<std::uint64_t>{}((static_cast<std::uint64_t>(static_cast<std::uint32_t>(t.tx)) << 32) |
                                      static_cast<std::uint32_t>(t.ty));
  }
};

// Keys a grid's tiles in a ChunkedTable: row by row (south to north, then west to east), in chunks of 8 x 8 tiles.
struct TileIndexTraits {
  static constexpr std::uint64_t biased(std::int32_t v) { return static_cast<std::uint32_t>(v) ^ 0x80000000U; }
  static constexpr std::uint64_t code(const TileIndex& t) { return biased(t.ty) << 32U | biased(t.tx); }
  static constexpr std::uint64_t chunk(const TileIndex& t) { return biased(t.ty >> 3) << 32U | biased(t.tx >> 3); }
};

// One tile of cell values, row-major (offset = local_iy * n + local_ix), shared between a grid and its snapshots
// until the grid writes to it.
struct Tile {
  // n*n cell values: kUnobserved or a certainty.
  std::vector<std::uint8_t> cells;
  // Number of cells whose certainty is at least the grid's occupied threshold.
  std::int32_t occupied_cells = 0;
  // The grid version of the latest insert that may have written the tile (0: loaded or never written), so that
  // readers can tell which tiles changed after a version they hold.
  std::uint64_t version = 0;
};

// Cell <-> tile arithmetic for tiles of a power-of-two side; works for negative indices (floor division).
class TileLayout {
 public:
  // Precondition: tile_cells is a power of two in [2, 1024] (HimmParams::validate checks it).
  explicit TileLayout(int tile_cells)
      : tile_cells_(tile_cells), shift_(std::countr_zero(static_cast<unsigned>(tile_cells))), mask_(tile_cells - 1) {}

  // Cells per tile side.
  [[nodiscard]] std::int32_t tile_cells() const { return tile_cells_; }
  // Cells per tile.
  [[nodiscard]] std::size_t cells_per_tile() const {
    return static_cast<std::size_t>(tile_cells_) * static_cast<std::size_t>(tile_cells_);
  }
  // The tile holding cell c.
  [[nodiscard]] TileIndex tile_of(const geometry::CellIndex& c) const { return {c.ix >> shift_, c.iy >> shift_}; }
  // Offset of cell c in its tile's cells.
  [[nodiscard]] std::int32_t offset_in_tile(const geometry::CellIndex& c) const {
    return offset_of_local(local(c.ix), local(c.iy));
  }
  // Offset in its tile's cells of the cell at column local_x, row local_y of the tile.
  [[nodiscard]] std::int32_t offset_of_local(std::int32_t local_x, std::int32_t local_y) const {
    return (local_y << shift_) | local_x;
  }
  // Column (0 = west) or row (0 = south) of a cell index inside its tile.
  [[nodiscard]] std::int32_t local(std::int32_t cell_index) const { return cell_index & mask_; }
  // The tile holding the cell at column local_x, row local_y of tile t, where the local indices may be one step off
  // t (-1 or tile_cells()).
  [[nodiscard]] TileIndex tile_of_local(const TileIndex& t, std::int32_t local_x, std::int32_t local_y) const {
    return {t.tx + (local_x >> shift_), t.ty + (local_y >> shift_)};
  }
  // The south-west cell of tile t.
  [[nodiscard]] geometry::CellIndex first_cell_of(const TileIndex& t) const {
    return {t.tx * tile_cells_, t.ty * tile_cells_};
  }

 private:
  std::int32_t tile_cells_;
  std::int32_t shift_;
  std::int32_t mask_;
};

}  // namespace occgeo::mapping
