#include "occgeo/mapping/grid_snapshot.h"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>

namespace occgeo::mapping {

namespace {

// Calls visit(index, tile) for each allocated tile overlapping box until visit returns false; looks each tile of the
// box up, or filters all allocated tiles when the box overlaps more tiles than are allocated.
template <typename Tiles, typename Visit>
void for_each_tile_in(const Tiles& tiles, const TileLayout& layout, const CellBox& box, Visit&& visit) {
  const TileIndex first = layout.tile_of(box.min);
  const TileIndex last = layout.tile_of(box.max);
  const auto box_tiles = static_cast<std::uint64_t>(std::int64_t{last.tx} - first.tx + 1) *
                         static_cast<std::uint64_t>(std::int64_t{last.ty} - first.ty + 1);
  if (box_tiles <= tiles.size()) {
    for (std::int32_t ty = first.ty; ty <= last.ty; ++ty) {
      for (std::int32_t tx = first.tx; tx <= last.tx; ++tx) {
        const TileIndex index{tx, ty};
        const Tile* tile = tiles.find(index);
        if (tile != nullptr && !visit(index, *tile)) return;
      }
    }
    return;
  }
  tiles.visit_all([&](const TileIndex& index, const Tile& tile) {
    const bool overlaps = index.tx >= first.tx && index.tx <= last.tx && index.ty >= first.ty && index.ty <= last.ty;
    return !overlaps || visit(index, tile);
  });
}

// The part of box inside tile t.
CellBox clip_to_tile(const CellBox& box, const TileLayout& layout, const TileIndex& t) {
  const geometry::CellIndex first = layout.first_cell_of(t);
  const std::int32_t last_offset = layout.tile_cells() - 1;
  return {{std::max(box.min.ix, first.ix), std::max(box.min.iy, first.iy)},
          {std::min(box.max.ix, first.ix + last_offset), std::min(box.max.iy, first.iy + last_offset)}};
}

}  // namespace

GridSnapshot::GridSnapshot(SharedTiles tiles, TileLayout layout, double cell_size_m, int occupied_threshold,
                           int max_certainty, std::optional<CellBox> tile_bounds, std::uint64_t version,
                           std::size_t occupied_cells)
    : tiles_(std::move(tiles)),
      layout_(layout),
      cell_size_m_(cell_size_m),
      occupied_threshold_(occupied_threshold),
      max_certainty_(max_certainty),
      tile_bounds_(tile_bounds),
      version_(version),
      occupied_cells_(occupied_cells) {}

void GridSnapshot::for_each_occupied(geometry::CellIndex min, geometry::CellIndex max,
                                     const std::function<bool(const geometry::CellIndex&)>& visit) const {
  if (min.ix > max.ix || min.iy > max.iy) return;
  const CellBox box{min, max};
  for_each_tile_in(tiles_, layout_, box, [&](const TileIndex& t, const Tile& tile) {
    return tile.occupied_cells == 0 || visit_occupied_in_tile(t, tile, box, visit);
  });
}

bool GridSnapshot::visit_occupied_in_tile(const TileIndex& t, const Tile& tile, const CellBox& box,
                                          const std::function<bool(const geometry::CellIndex&)>& visit) const {
  const CellBox part = clip_to_tile(box, layout_, t);
  for (std::int32_t iy = part.min.iy; iy <= part.max.iy; ++iy) {
    const std::uint8_t* row = &tile.cells[static_cast<std::size_t>(layout_.offset_in_tile({0, iy}))];
    for (std::int32_t ix = part.min.ix; ix <= part.max.ix; ++ix) {
      const std::uint8_t value = row[layout_.local(ix)];
      if (value >= occupied_threshold_ && value != kUnobserved && !visit({ix, iy})) return false;
    }
  }
  return true;
}

std::uint8_t GridSnapshot::certainty(const geometry::CellIndex& c) const {
  const Tile* tile = find_tile(c);
  if (tile == nullptr) return 0;
  const std::uint8_t value = tile->cells[static_cast<std::size_t>(layout_.offset_in_tile(c))];
  return value == kUnobserved ? 0 : value;
}

bool GridSnapshot::observed(const geometry::CellIndex& c) const {
  const Tile* tile = find_tile(c);
  return tile != nullptr && tile->cells[static_cast<std::size_t>(layout_.offset_in_tile(c))] != kUnobserved;
}

bool GridSnapshot::occupied(const geometry::CellIndex& c) const { return certainty(c) >= occupied_threshold_; }

std::vector<std::uint8_t> GridSnapshot::window(geometry::CellIndex min, int width, int height) const {
  if (width < 0 || height < 0) {
    throw std::invalid_argument("window: width and height must be >= 0, got " + std::to_string(width) + " x " +
                                std::to_string(height));
  }
  constexpr std::int64_t kMaxIndex = std::numeric_limits<std::int32_t>::max();
  if (std::int64_t{min.ix} + width - 1 > kMaxIndex || std::int64_t{min.iy} + height - 1 > kMaxIndex) {
    throw std::invalid_argument("window: the window reaches beyond the largest cell index");
  }
  std::vector<std::uint8_t> cells(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), kUnobserved);
  if (width == 0 || height == 0) return cells;
  const CellBox box{min, {min.ix + width - 1, min.iy + height - 1}};
  for_each_tile_in(tiles_, layout_, box, [&](const TileIndex& t, const Tile& tile) {
    const CellBox part = clip_to_tile(box, layout_, t);
    const auto run = static_cast<std::size_t>(part.max.ix - part.min.ix + 1);
    for (std::int32_t iy = part.min.iy; iy <= part.max.iy; ++iy) {
      const auto source = tile.cells.begin() + layout_.offset_in_tile({part.min.ix, iy});
      const auto target = cells.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(iy - min.iy) *
                                                                          static_cast<std::size_t>(width) +
                                                                      static_cast<std::size_t>(part.min.ix - min.ix));
      std::copy_n(source, run, target);
    }
    return true;
  });
  return cells;
}

std::vector<CellBox> GridSnapshot::changed_since(std::uint64_t version, const CellBox& box) const {
  std::vector<CellBox> parts;
  if (box.min.ix > box.max.ix || box.min.iy > box.max.iy) return parts;
  for_each_tile_in(tiles_, layout_, box, [&](const TileIndex& t, const Tile& tile) {
    if (tile.version > version) parts.push_back(clip_to_tile(box, layout_, t));
    return true;
  });
  return parts;
}

const Tile* GridSnapshot::find_tile(const geometry::CellIndex& c) const { return tiles_.find(layout_.tile_of(c)); }

std::size_t GridSnapshot::memory_bytes() const {
  // Per tile: its cells' array, the Tile in its shared pointer's control block, and the table's entry holding that
  // pointer; per chunk of the table, its directory entry and vector.
  constexpr std::size_t kMallocHeader = 8;
  constexpr std::size_t kControlBlock = 16;
  constexpr std::size_t kEntry = sizeof(TileIndex) + sizeof(std::shared_ptr<const Tile>);
  constexpr std::size_t kChunk = sizeof(std::uint64_t) + 2 * sizeof(std::shared_ptr<const Tile>) + kControlBlock +
                                 sizeof(std::vector<int>) + 2 * kMallocHeader;
  const std::size_t per_tile =
      layout_.cells_per_tile() + kMallocHeader + sizeof(Tile) + kControlBlock + kMallocHeader + kEntry;
  return tiles_.size() * per_tile + tiles_.chunk_count() * kChunk;
}

}  // namespace occgeo::mapping
