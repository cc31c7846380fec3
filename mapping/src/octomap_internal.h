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

#include "occgeo/mapping/chunked_table.h"
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

// A snapshot's tiles by id (ChunkedTable), in chunks of 8 x 8 x 8 tiles (25.6 m at the default 0.05 m): a publish
// copies a pointer per chunk (a few hundred on a map of 300 x 300 m) and the chunks its changed tiles lie in. With one
// ordered map of every tile, copying it was a tenth of a scan's cost on that map and grew with it.
struct OctoTileTableTraits {
  static constexpr std::uint64_t code(OctoTileId id) { return id; }
  static constexpr std::uint64_t chunk(OctoTileId id) { return tile_prefix(id, 3); }
};
using OctoTileTable = ChunkedTable<OctoTileId, OctoTile, OctoTileTableTraits>;

// Sums over a snapshot's tiles, kept by the model as tiles come and go, so that a status request (node_count,
// leaf_count, memory_bytes) costs the same at any map size: nodes, leaves, and heap bytes of the tiles' trees,
// summaries and records.
struct OctoTileSums {
  std::size_t nodes = 0;
  std::size_t leaves = 0;
  std::size_t bytes = 0;
};

struct OctoMapSnapshot::Impl {
  // An empty tree with the model's parameters: key arithmetic, thresholds, and the collide of an empty snapshot.
  std::shared_ptr<const OctoTile> empty;
  OctoTileTable tiles;
  // The nodes above the tiles' depth that the model's tree has (every tile's tree repeats its own path to the root).
  std::size_t nodes_above_tiles = 0;
  // Nodes of the model's live tree at publication (OcTree::size, kept by the tree as it changes).
  std::size_t live_tree_nodes = 0;
  OctoTileSums tile_sums;
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
