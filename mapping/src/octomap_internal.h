#pragma once

// Private to the occgeo_octomap library: the pieces of OctoMapModel / OctoMapSnapshot that name OctoMap types, and the
// seams to the PCL and FCL translation units (each heavy header is included by one .cc only).

#include <octomap/OcTree.h>

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

#include "occgeo/mapping/octomap_model.h"

namespace occgeo::mapping {

// An FCL octree wrapping a snapshot's tree; defined in octomap_collide.cc so that FCL stays there.
struct FclOctreeView;

// Wraps tree for FCL (~10 µs, the first one in a process ~5 ms); tree must outlive nothing: the view shares it.
std::shared_ptr<const FclOctreeView> make_fcl_view(const std::shared_ptr<const octomap::OcTree>& tree);

// A conservative 2-D summary of a tree's occupied leaves, built once per snapshot so that collision checks in free
// space skip FCL's octree walk (which dominates a collision query's cost). The x-y key plane is cut into square cells
// of 2^cell_shift voxels; each cell keeps the lowest and highest z key of any occupied leaf overlapping it (a pruned
// leaf marks every cell it covers; z is rounded outwards to 4 voxels). Keys are OctoMap's (voxel index + 32768 per
// axis).
struct OccupiedColumns {
  int cell_shift = 2;
  // Cell index range covered, inclusive; empty (no occupied leaf) when cells_x == 0.
  int cell_min_x = 0, cell_min_y = 0, cells_x = 0, cells_y = 0;
  // Per cell (row-major, x fastest): the occupied z key range, z_low > z_high when the cell has none.
  std::vector<std::uint16_t> z_low, z_high;
  double resolution_m = 0.0;

  // Summarises tree's occupied leaves (occupied as FCL and OctoMap judge them: log-odds at or above the threshold).
  static OccupiedColumns build(const octomap::OcTree& tree);
  // True only when no occupied leaf can overlap the world-frame box [min_W, max_W] grown by 1% of a voxel (the growth
  // absorbs rounding at key boundaries and FCL's contact tolerance).
  [[nodiscard]] bool provably_free(const Eigen::Vector3d& min_W, const Eigen::Vector3d& max_W) const;
};

// Collides footprint at X_WB with the occupied voxels of view's tree. When columns is given, a pose whose footprint's
// bounding box misses every occupied column returns "no collision" without FCL (the answer is the same). Throws
// std::invalid_argument for a footprint dimension that is not finite and positive.
OctoCollision collide_footprint(const FclOctreeView& view, const OccupiedColumns* columns,
                                const geometry::Footprint& footprint, const geometry::Pose3& X_WB);

// A snapshot is cut into tiles: cubes of 2^kTileKeyBits voxels a side (the subtrees at depth 16 - kTileKeyBits), each
// in a tree of its own with its FCL view and column summary. A publish rebuilds only the tiles whose voxels changed
// and shares the others with the previous snapshot, so its cost follows what the scans changed, not the map's size.
// 64 voxels (3.2 m at the default 0.05 m): a scan's changes are copied in tiles about as wide as a robot's
// neighbourhood, not in 12.8 m blocks holding several rooms.
inline constexpr int kTileKeyBits = 6;
inline constexpr int kTileDepth = 16 - kTileKeyBits;
// Bits of a tile index per axis, and their mask.
inline constexpr unsigned kTileAxisBits = 16U - kTileKeyBits;
inline constexpr std::uint32_t kTileAxisMask = (std::uint32_t{1} << kTileAxisBits) - 1U;
static_assert(3 * kTileAxisBits <= 32, "a tile index must pack into 32 bits");

// A tile's index: each key component's top kTileAxisBits bits, packed x | y << kTileAxisBits | z << 2 kTileAxisBits.
using OctoTileId = std::uint32_t;
constexpr OctoTileId pack_tile(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
  return x | y << kTileAxisBits | z << (2U * kTileAxisBits);
}
// Component axis (0 x, 1 y, 2 z) of a packed tile index, or of a prefix packed the same way.
constexpr std::uint32_t tile_axis(OctoTileId id, unsigned axis) {
  return (id >> (kTileAxisBits * axis)) & kTileAxisMask;
}
// The tile's ancestor `shift` levels up, packed the same way.
constexpr OctoTileId tile_prefix(OctoTileId id, unsigned shift) {
  return pack_tile(tile_axis(id, 0) >> shift, tile_axis(id, 1) >> shift, tile_axis(id, 2) >> shift);
}
inline OctoTileId tile_id_of(const octomap::OcTreeKey& key) {
  return pack_tile(key[0] >> kTileKeyBits, key[1] >> kTileKeyBits, key[2] >> kTileKeyBits);
}

// One tile of a snapshot: a full-depth tree holding only this tile's voxels (the same key space as the model's tree),
// its FCL view and its column summary. Immutable; shared by every snapshot it did not change in.
struct OctoTile {
  std::shared_ptr<const octomap::OcTree> tree;
  std::shared_ptr<const FclOctreeView> fcl_view;
  OccupiedColumns columns;
  std::size_t leaf_count = 0;
  std::size_t node_count = 0;
};

// A snapshot's tiles by id, in two levels: a directory of chunks, each holding the tiles of one cube of 2^kChunkBits
// tiles a side (25.6 m at the default 0.05 m) in id order, immutable and shared by every snapshot it did not change in.
// Copying the table copies the directory (a pointer per chunk, a few hundred on a map of 300 x 300 m); a publish
// copies the chunks its changed tiles lie in. With one ordered map of every tile, copying it was a tenth of a scan's
// cost on that map and grew with it.
class OctoTileTable {
 public:
  using TilePtr = std::shared_ptr<const OctoTile>;

  // The tile of id, or nullptr.
  [[nodiscard]] const OctoTile* find(OctoTileId id) const {
    const ChunkId chunk_id = chunk_of(id);
    const auto chunk = std::lower_bound(chunks_.begin(), chunks_.end(), chunk_id,
                                        [](const ChunkEntry& entry, ChunkId key) { return entry.first < key; });
    if (chunk == chunks_.end() || chunk->first != chunk_id) return nullptr;
    const auto& tiles = chunk->second->tiles;
    const auto tile = std::lower_bound(tiles.begin(), tiles.end(), id,
                                       [](const TileEntry& entry, OctoTileId key) { return entry.first < key; });
    return tile != tiles.end() && tile->first == id ? tile->second.get() : nullptr;
  }
  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] bool empty() const { return size_ == 0; }

  // visit(id, tile) for every tile, chunk by chunk, until it returns false; false when it did.
  template <typename Visit>
  bool visit_all(Visit&& visit) const {
    for (const auto& [chunk_id, chunk] : chunks_) {
      for (const auto& [id, tile] : chunk->tiles) {
        if (!visit(id, *tile)) return false;
      }
    }
    return true;
  }

  // Sets each (id, tile) of changes, a null tile removing id; calls replaced(id, old tile or nullptr, new tile or
  // nullptr) for each, for the caller's running sums. Each chunk changed is copied once.
  template <typename Replaced>
  void apply(std::vector<std::pair<OctoTileId, TilePtr>> changes, Replaced&& replaced) {
    std::sort(changes.begin(), changes.end(), [](const auto& a, const auto& b) {
      return std::pair(chunk_of(a.first), a.first) < std::pair(chunk_of(b.first), b.first);
    });
    std::vector<ChunkEntry> chunks;
    chunks.reserve(chunks_.size() + changes.size());
    auto old_chunk = chunks_.begin();
    auto change = changes.begin();
    while (change != changes.end()) {
      const ChunkId chunk_id = chunk_of(change->first);
      while (old_chunk != chunks_.end() && old_chunk->first < chunk_id) chunks.push_back(std::move(*old_chunk++));
      const bool existed = old_chunk != chunks_.end() && old_chunk->first == chunk_id;
      auto merged = std::make_shared<Chunk>();
      const std::vector<TileEntry> none;
      const std::vector<TileEntry>& before = existed ? old_chunk->second->tiles : none;
      merged->tiles.reserve(before.size() + 8);
      auto tile = before.begin();
      for (; change != changes.end() && chunk_of(change->first) == chunk_id; ++change) {
        while (tile != before.end() && tile->first < change->first) merged->tiles.push_back(*tile++);
        const bool had = tile != before.end() && tile->first == change->first;
        replaced(change->first, had ? tile->second.get() : nullptr, change->second.get());
        size_ = size_ - (had ? 1 : 0) + (change->second ? 1 : 0);
        if (change->second) merged->tiles.emplace_back(change->first, std::move(change->second));
        if (had) ++tile;
      }
      merged->tiles.insert(merged->tiles.end(), tile, before.end());
      if (existed) ++old_chunk;
      if (!merged->tiles.empty()) chunks.emplace_back(chunk_id, std::move(merged));
    }
    while (old_chunk != chunks_.end()) chunks.push_back(std::move(*old_chunk++));
    chunks_ = std::move(chunks);
  }

  void clear() {
    chunks_.clear();
    size_ = 0;
  }

 private:
  static constexpr unsigned kChunkBits = 3;
  using ChunkId = std::uint32_t;
  using TileEntry = std::pair<OctoTileId, TilePtr>;
  struct Chunk {
    std::vector<TileEntry> tiles;  // in id order
  };
  using ChunkEntry = std::pair<ChunkId, std::shared_ptr<const Chunk>>;
  static constexpr ChunkId chunk_of(OctoTileId id) { return tile_prefix(id, kChunkBits); }

  std::vector<ChunkEntry> chunks_;  // in chunk id order
  std::size_t size_ = 0;
};

struct OctoMapSnapshot::Impl {
  // An empty tree with the model's parameters: key arithmetic, thresholds, and the collide of an empty snapshot.
  std::shared_ptr<const OctoTile> empty;
  OctoTileTable tiles;
  // The nodes above the tiles' depth that the model's tree has (every tile's tree repeats its own path to the root).
  std::size_t nodes_above_tiles = 0;
  // Nodes of the model's live tree at publication (OcTree::size, kept by the tree as it changes).
  std::size_t live_tree_nodes = 0;
  // Sums over the tiles, taken once at publication so that a status request (node_count, leaf_count, memory_bytes)
  // costs the same at any map size: nodes, leaves, and heap bytes of the tiles' trees, summaries and records.
  std::size_t tile_nodes = 0;
  std::size_t tile_leaves = 0;
  std::size_t tile_bytes = 0;
  // See OctoMapSnapshot::changed_columns.
  std::optional<std::vector<OctoColumnRange>> changed_columns;
  std::uint64_t changed_since_version = 0;
};

// The x-y columns of the tiles ids, once per x-y (ids in any order).
template <typename Ids>
std::vector<OctoColumnRange> columns_of_tiles(const Ids& ids) {
  std::vector<std::uint32_t> xy;
  for (const OctoTileId id : ids) xy.push_back(id & (kTileAxisMask | kTileAxisMask << kTileAxisBits));
  std::sort(xy.begin(), xy.end());
  xy.erase(std::unique(xy.begin(), xy.end()), xy.end());
  std::vector<OctoColumnRange> out;
  out.reserve(xy.size());
  constexpr std::int32_t kSide = std::int32_t{1} << kTileKeyBits;
  for (const std::uint32_t packed : xy) {
    // A key k is the voxel [(k - 32768) r, (k - 32767) r).
    const std::int32_t x0 = static_cast<std::int32_t>(tile_axis(packed, 0)) * kSide - 32768;
    const std::int32_t y0 = static_cast<std::int32_t>(tile_axis(packed, 1)) * kSide - 32768;
    out.push_back({{x0, y0}, {x0 + kSide - 1, y0 + kSide - 1}});
  }
  return out;
}

// Runs the PCL filters params enables over points_W (all finite), in that order: voxel grid, then statistical outlier
// removal; defined in octomap_filters.cc.
std::vector<Eigen::Vector3f> filter_cloud(const std::vector<Eigen::Vector3f>& points_W, const OctoMapParams& params);

}  // namespace occgeo::mapping
