#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "occgeo/geometry/grid_ray.h"
#include "occgeo/mapping/himm_grid.h"

namespace occgeo::mapping {

// Writes cells of a HimmGrid within one insert or conversion call (the grid takes no snapshot meanwhile, so tiles made
// writable stay so). It remembers the tiles it has made writable and collects the change of occupied cells of the tile
// it is on until it moves to another tile or goes out of scope.
class HimmGrid::TileWriter {
 public:
  explicit TileWriter(HimmGrid& grid)
      : grid_(grid),
        layout_(grid.layout_),
        decrement_(static_cast<std::uint8_t>(grid.params_.decrement)),
        occupied_threshold_(static_cast<std::uint8_t>(grid.params_.occupied_threshold)) {}
  TileWriter(const TileWriter&) = delete;
  TileWriter& operator=(const TileWriter&) = delete;
  ~TileWriter() { flush_occupied_change(cursor_); }

  // Applies one beam from sensor_origin_W to end_point_W (metres, checked to be traversable): clears every cell before
  // the end cell, then hits the end cell when is_hit and clears it otherwise.
  // When lowered_cells is given, every cell before the end cell that held a certainty above 0 is appended to it.
  void trace_beam(const Eigen::Vector2d& sensor_origin_W, const Eigen::Vector2d& end_point_W, bool is_hit,
                  std::vector<geometry::CellIndex>* lowered_cells = nullptr) {
    const geometry::GridRayTraversal start(grid_.geometry_, sensor_origin_W, end_point_W);
    cursor_ = on_tile_of(cursor_, start.cell());
    // The walk keeps its state in locals, which the optimiser holds in registers; it would have to reload members,
    // or any object whose address a call has seen, after every cell store (an unsigned char store may alias anything).
    geometry::GridRayTraversal ray = start;
    const TileLayout layout = layout_;
    const std::int32_t outside_tile = ~(layout.tile_cells() - 1);  // Bits set only in local indices off the tile.
    const std::uint8_t decrement = decrement_;
    const std::uint8_t occupied_threshold = occupied_threshold_;
    std::uint8_t* cells = cursor_.cells;
    int occupied_change = cursor_.occupied_change;
    std::int32_t local_x = layout.local(start.cell().ix);
    std::int32_t local_y = layout.local(start.cell().iy);
    while (!ray.done()) {
      std::uint8_t& value = cells[layout.offset_of_local(local_x, local_y)];
      if (lowered_cells != nullptr && value != 0 && value != kUnobserved) {
        const geometry::CellIndex first = layout.first_cell_of(cursor_.tile_index);
        lowered_cells->push_back({first.ix + local_x, first.iy + local_y});
      }
      if (lowering_leaves_occupied(value, decrement, occupied_threshold)) {
        --occupied_change;
        const geometry::CellIndex first = layout.first_cell_of(cursor_.tile_index);
        grid_.note_occupancy_change({first.ix + local_x, first.iy + local_y});
      }
      value = lowered(value, decrement);
      const geometry::CellStep step = ray.advance();
      local_x += step.dx;
      local_y += step.dy;
      if (((local_x | local_y) & outside_tile) != 0) {
        cursor_.occupied_change = occupied_change;
        cursor_ = on_tile(cursor_, layout.tile_of_local(cursor_.tile_index, local_x, local_y));
        cells = cursor_.cells;
        occupied_change = 0;
        local_x = layout.local(local_x);
        local_y = layout.local(local_y);
      }
    }
    cursor_.occupied_change = occupied_change;
    if (is_hit) {
      hit(ray.end_cell());
    } else {
      clear(ray.end_cell());
    }
  }

  // Lowers the certainty of cell c by decrement, not below 0.
  void lower(const geometry::CellIndex& c, std::uint8_t decrement) {
    std::uint8_t& value = cell(c);
    store(c, value, lowered(value, decrement));
  }
  // Sets cell c to new_value, a certainty or kUnobserved.
  void set(const geometry::CellIndex& c, std::uint8_t new_value) { store(c, cell(c), new_value); }

 private:
  // The tile being written and its change of occupied cells not yet added to the tile and the grid.
  struct Cursor {
    TileIndex tile_index;
    Tile* tile = nullptr;
    std::uint8_t* cells = nullptr;
    int occupied_change = 0;
  };

  // A tile made writable by this writer.
  struct WritableTile {
    TileIndex index;
    Tile* tile = nullptr;
  };

  // Side of the square of tiles that the cache of writable tiles holds without collisions.
  static constexpr std::int32_t kCachedTilesSide = 8;

  static int certainty_of(std::uint8_t value) { return value == kUnobserved ? 0 : value; }

  [[nodiscard]] bool is_occupied(std::uint8_t value) const {
    return value >= occupied_threshold_ && value != kUnobserved;
  }

  // A cell value lowered by decrement: certainty - decrement, not below 0; 0 for an unobserved cell.
  static std::uint8_t lowered(std::uint8_t value, std::uint8_t decrement) {
    return value == kUnobserved || value <= decrement ? std::uint8_t{0} : static_cast<std::uint8_t>(value - decrement);
  }

  // True when lowering a cell value by decrement turns an occupied cell into a free one.
  static bool lowering_leaves_occupied(std::uint8_t value, std::uint8_t decrement, std::uint8_t occupied_threshold) {
    // value in [threshold, threshold + decrement), in one comparison; kUnobserved is far above that range.
    return static_cast<unsigned>(value - occupied_threshold) < decrement;
  }

  // Lowers the certainty of cell c by the decrement, not below 0; an unobserved cell becomes observed at 0.
  void clear(const geometry::CellIndex& c) {
    std::uint8_t& value = cell(c);
    store(c, value, lowered(value, decrement_));
  }

  // Raises the certainty of cell c by the increment, up to the maximum, then applies the growth-rate operator: the
  // weighted sum of the 3x3 neighbourhood's certainties (unobserved cells count 0), rounded down, up to the maximum.
  void hit(const geometry::CellIndex& c) {
    const HimmParams& params = grid_.params_;
    std::uint8_t& value = cell(c);
    const int raised = std::min(params.max_certainty, certainty_of(value) + params.increment);
    const double grown = params.growth_center_weight * raised + params.growth_neighbour_weight * neighbour_sum(c);
    store(c, value, static_cast<std::uint8_t>(std::floor(std::min(grown, static_cast<double>(params.max_certainty)))));
  }

  // Cell c, after moving the cursor to its tile.
  std::uint8_t& cell(const geometry::CellIndex& c) {
    cursor_ = on_tile_of(cursor_, c);
    return cursor_.cells[layout_.offset_in_tile(c)];
  }

  // The cursor on the tile of cell c.
  [[nodiscard]] Cursor on_tile_of(const Cursor& cursor, const geometry::CellIndex& c) {
    return on_tile(cursor, layout_.tile_of(c));
  }

  // The cursor on tile t: cursor itself if it is there, else moved there (adding the occupied-cell change collected
  // on its previous tile).
  [[nodiscard]] Cursor on_tile(Cursor cursor, const TileIndex& t) {
    if (cursor.cells != nullptr && t == cursor.tile_index) return cursor;
    flush_occupied_change(cursor);
    WritableTile& cached = writable_tiles_[cache_slot(t)];
    if (cached.tile == nullptr || cached.index != t) cached = {t, &grid_.writable_tile(t)};
    return {t, cached.tile, cached.tile->cells.data(), 0};
  }

  // Sum of the certainties of the 8 neighbours of cell c, which is in the cursor's tile.
  [[nodiscard]] int neighbour_sum(const geometry::CellIndex& c) const {
    const std::int32_t last = layout_.tile_cells() - 1;
    const std::int32_t local_x = layout_.local(c.ix);
    const std::int32_t local_y = layout_.local(c.iy);
    int sum = 0;
    if (local_x > 0 && local_x < last && local_y > 0 && local_y < last) {
      const std::uint8_t* center = cursor_.cells + layout_.offset_in_tile(c);
      const std::ptrdiff_t row = layout_.tile_cells();
      for (const std::ptrdiff_t offset :
           {-row - 1, -row, -row + 1, std::ptrdiff_t{-1}, std::ptrdiff_t{1}, row - 1, row, row + 1}) {
        sum += certainty_of(center[offset]);
      }
      return sum;
    }
    for (std::int32_t dy = -1; dy <= 1; ++dy) {
      for (std::int32_t dx = -1; dx <= 1; ++dx) {
        if (dx == 0 && dy == 0) continue;
        const geometry::CellIndex neighbour{c.ix + dx, c.iy + dy};
        const Tile* tile = tile_for_reading(layout_.tile_of(neighbour));
        if (tile != nullptr)
          sum += certainty_of(tile->cells[static_cast<std::size_t>(layout_.offset_in_tile(neighbour))]);
      }
    }
    return sum;
  }

  // Tile t for reading, or nullptr when it is not allocated.
  [[nodiscard]] const Tile* tile_for_reading(const TileIndex& t) const {
    const WritableTile& cached = writable_tiles_[cache_slot(t)];
    return cached.tile != nullptr && cached.index == t ? cached.tile : grid_.find_tile(t);
  }

  // Slot of tile t in writable_tiles_.
  static std::size_t cache_slot(const TileIndex& t) {
    return static_cast<std::size_t>((t.ty & (kCachedTilesSide - 1)) * kCachedTilesSide +
                                    (t.tx & (kCachedTilesSide - 1)));
  }

  // Sets value, cell c's in the cursor's tile.
  void store(const geometry::CellIndex& c, std::uint8_t& value, std::uint8_t new_value) {
    const int change = static_cast<int>(is_occupied(new_value)) - static_cast<int>(is_occupied(value));
    if (change != 0) {
      cursor_.occupied_change += change;
      grid_.note_occupancy_change(c);
    }
    value = new_value;
  }

  void flush_occupied_change(Cursor& cursor) {
    if (cursor.occupied_change == 0) return;
    cursor.tile->occupied_cells += cursor.occupied_change;
    grid_.occupied_cells_ =
        static_cast<std::size_t>(static_cast<std::int64_t>(grid_.occupied_cells_) + cursor.occupied_change);
    cursor.occupied_change = 0;
  }

  HimmGrid& grid_;
  const TileLayout layout_;
  const std::uint8_t decrement_;
  const std::uint8_t occupied_threshold_;
  Cursor cursor_;
  // Tiles made writable so far, direct-mapped by the low bits of their indices: every beam of a scan starts in the
  // sensor's tile, and this spares the hash map look-up.
  std::array<WritableTile, kCachedTilesSide * kCachedTilesSide> writable_tiles_{};
};

}  // namespace occgeo::mapping
