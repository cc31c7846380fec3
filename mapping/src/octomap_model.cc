#include "occgeo/mapping/octomap_model.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <new>
#include <optional>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "octomap_internal.h"

namespace occgeo::mapping::detail {
struct NodeSurgeryTag {};
}  // namespace occgeo::mapping::detail

// octomap's nodes show their children only to OcTreeBaseImpl (every specialization is a friend). This one does what a
// snapshot tile needs and no tree does: hang under one of its nodes a subtree that it shares with other versions of the
// tile (and so must not delete), unhang it, and give a node of such a subtree its children from an array the subtree
// owns (a subtree is allocated in one piece, not node by node).
template <>
class octomap::OcTreeBaseImpl<occgeo::mapping::detail::NodeSurgeryTag, occgeo::mapping::detail::NodeSurgeryTag> {
 public:
  static void attach(octomap::OcTreeNode* parent, unsigned index, octomap::OcTreeNode* child) {
    octomap::OcTreeDataNode<float>& node = *parent;
    if (node.children == nullptr) node.children = new octomap::AbstractOcTreeNode*[8]();  // as allocChildren
    node.children[index] = child;
  }
  static void detach(octomap::OcTreeNode* parent, unsigned index) {
    static_cast<octomap::OcTreeDataNode<float>&>(*parent).children[index] = nullptr;
  }
  static void set_children(octomap::OcTreeNode* node, octomap::AbstractOcTreeNode** children) {
    static_cast<octomap::OcTreeDataNode<float>&>(*node).children = children;
  }
};

namespace occgeo::mapping {

namespace {

octomap::point3d to_octo(const Eigen::Vector3d& p) {
  return {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())};
}

Eigen::Vector3d to_eigen(const octomap::point3d& p) { return {p.x(), p.y(), p.z()}; }

bool finite_pose(const geometry::Pose3& X) { return X.transform.matrix().allFinite(); }

void require_finite_pose(const geometry::Pose3& X_WS, const char* what) {
  if (!finite_pose(X_WS)) throw std::invalid_argument(std::string(what) + ": X_WS must be finite");
}

void apply_params(octomap::OcTree& tree, const OctoMapParams& params) {
  tree.setProbHit(params.prob_hit);
  tree.setProbMiss(params.prob_miss);
  tree.setClampingThresMin(params.clamping_min);
  tree.setClampingThresMax(params.clamping_max);
  tree.setOccupancyThres(params.occupancy_threshold);
}

OctoVoxel voxel_of(const octomap::OcTree::leaf_iterator& it) {
  return {to_eigen(it.getCoordinate()), it.getSize(), it->getOccupancy()};
}

// The box [min_W, max_W] clamped to the coordinates OctoMap keys can address at resolution, so that the bounding-box
// iterator never sees an out-of-range corner.
std::pair<octomap::point3d, octomap::point3d> clamped_box(const octomap::OcTree& tree, const Eigen::Vector3d& min_W,
                                                          const Eigen::Vector3d& max_W) {
  const double limit = (32767.0 - 1.0) * tree.getResolution();
  const Eigen::Vector3d lo = min_W.cwiseMax(-limit).cwiseMin(limit);
  const Eigen::Vector3d hi = max_W.cwiseMax(-limit).cwiseMin(limit);
  return {to_octo(lo), to_octo(hi)};
}

std::optional<double> occupancy_in(const octomap::OcTree& tree, const Eigen::Vector3d& p_W) {
  if (!p_W.allFinite()) return std::nullopt;
  octomap::OcTreeKey key;
  // Checked first: OcTree::search(point3d) prints an error for coordinates beyond the key range.
  if (!tree.coordToKeyChecked(to_octo(p_W), key)) return std::nullopt;
  const octomap::OcTreeNode* node = tree.search(key);
  if (node == nullptr) return std::nullopt;
  return node->getOccupancy();
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------------
// Snapshot

OctoMapSnapshot::OctoMapSnapshot(std::unique_ptr<Impl> impl, std::uint64_t version, const TerrainParams& terrain)
    : impl_(std::move(impl)), version_(version), terrain_(terrain) {}

OctoMapSnapshot::~OctoMapSnapshot() = default;

namespace {

// The tiles of snapshot whose cubes overlap the key box [lo, hi], in id order.
template <typename Visit>
void for_tiles_in_keys(const OctoTileTable& tiles, const octomap::OcTreeKey& lo, const octomap::OcTreeKey& hi,
                       Visit&& visit) {
  const OctoTileId first = tile_id_of(lo), last = tile_id_of(hi);
  const auto part = tile_axis;
  const std::uint64_t span = std::uint64_t{part(last, 0) - part(first, 0) + 1} * (part(last, 1) - part(first, 1) + 1) *
                             (part(last, 2) - part(first, 2) + 1);
  if (span > tiles.size()) {
    // A box wider than the snapshot: walk the tiles rather than the box.
    tiles.visit_all([&](OctoTileId id, const OctoTile& tile) {
      bool inside = true;
      for (unsigned axis = 0; axis < 3; ++axis)
        inside = inside && part(id, axis) >= part(first, axis) && part(id, axis) <= part(last, axis);
      return !inside || visit(tile);
    });
    return;
  }
  for (OctoTileId z = part(first, 2); z <= part(last, 2); ++z) {
    for (OctoTileId y = part(first, 1); y <= part(last, 1); ++y) {
      for (OctoTileId x = part(first, 0); x <= part(last, 0); ++x) {
        const OctoTile* tile = tiles.find(pack_tile(x, y, z));
        if (tile != nullptr && !visit(*tile)) return;
      }
    }
  }
}

// The keys of the box [min_W, max_W], clamped to the key range.
std::pair<octomap::OcTreeKey, octomap::OcTreeKey> key_box(const octomap::OcTree& tree, const Eigen::Vector3d& min_W,
                                                          const Eigen::Vector3d& max_W) {
  const auto [lo, hi] = clamped_box(tree, min_W, max_W);
  return {tree.coordToKey(lo), tree.coordToKey(hi)};
}

}  // namespace

std::optional<double> OctoMapSnapshot::occupancy(const Eigen::Vector3d& p_W) const {
  const octomap::OcTree& keys = *impl_->empty->tree;
  octomap::OcTreeKey key;
  if (!p_W.allFinite() || !keys.coordToKeyChecked(to_octo(p_W), key)) return std::nullopt;
  const OctoTile* tile = impl_->tiles.find(tile_id_of(key));
  if (tile == nullptr) return std::nullopt;
  const octomap::OcTreeNode* node = tile->tree->search(key);
  if (node == nullptr) return std::nullopt;
  return node->getOccupancy();
}

bool OctoMapSnapshot::occupied(const Eigen::Vector3d& p_W) const {
  const std::optional<double> p = occupancy(p_W);
  return p.has_value() && *p >= impl_->empty->tree->getOccupancyThres();
}

void OctoMapSnapshot::for_each_occupied(const Eigen::Vector3d& min_W, const Eigen::Vector3d& max_W,
                                        const std::function<bool(const OctoVoxel&)>& visit) const {
  if (impl_->tiles.empty() || !min_W.allFinite() || !max_W.allFinite()) return;
  if ((min_W.array() > max_W.array()).any()) return;
  const auto [lo, hi] = clamped_box(*impl_->empty->tree, min_W, max_W);
  const auto [key_lo, key_hi] = key_box(*impl_->empty->tree, min_W, max_W);
  for_tiles_in_keys(impl_->tiles, key_lo, key_hi, [&](const OctoTile& tile) {
    // The tile's column summary skips its tree walk when no occupied leaf can overlap the box.
    if (tile.columns.provably_free(min_W, max_W)) return true;
    const octomap::OcTree& tree = *tile.tree;
    for (auto it = tree.begin_leafs_bbx(lo, hi), end = tree.end_leafs_bbx(); it != end; ++it) {
      if (!tree.isNodeOccupied(*it)) continue;
      if (!visit({to_eigen(it.getCoordinate()), it.getSize(), it->getOccupancy()})) return false;
    }
    return true;
  });
}

std::vector<OctoVoxel> OctoMapSnapshot::occupied_in_box(const Eigen::Vector3d& min_W,
                                                        const Eigen::Vector3d& max_W) const {
  std::vector<OctoVoxel> voxels;
  for_each_occupied(min_W, max_W, [&](const OctoVoxel& v) {
    voxels.push_back(v);
    return true;
  });
  return voxels;
}

void OctoMapSnapshot::for_each_leaf(const std::function<void(const OctoVoxel&)>& visit) const {
  impl_->tiles.visit_all([&](OctoTileId /*id*/, const OctoTile& tile) {
    const octomap::OcTree& tree = *tile.tree;
    for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) visit(voxel_of(it));
    return true;
  });
}

std::optional<OctoRayHit> OctoMapSnapshot::cast_ray(const Eigen::Vector3d& origin_W, const Eigen::Vector3d& direction_W,
                                                    double max_range_m) const {
  if (!direction_W.allFinite() || direction_W.norm() == 0.0) {
    throw std::invalid_argument("cast_ray: direction_W must be finite and non-zero");
  }
  if (!origin_W.allFinite() || !std::isfinite(max_range_m) || max_range_m <= 0.0) {
    throw std::invalid_argument("cast_ray: origin_W and max_range_m must be finite, max_range_m > 0");
  }
  const octomap::OcTree& keys = *impl_->empty->tree;
  octomap::OcTreeKey origin_key;
  if (impl_->tiles.empty() || !keys.coordToKeyChecked(to_octo(origin_W), origin_key)) return std::nullopt;
  // The voxels along the ray in order (OctoMap's 3D DDA, as castRay steps), the end voxel included, each looked up in
  // its tile: castRay with ignoreUnknown, across tiles.
  const Eigen::Vector3d end_W = origin_W + direction_W.normalized() * max_range_m;
  const auto [end_lo, end_hi] = clamped_box(keys, end_W, end_W);
  // A KeyRay holds 100,000 keys (600 KB, zeroed when made): one per thread, reused by every query.
  thread_local octomap::KeyRay ray;
  if (!keys.computeRayKeys(to_octo(origin_W), end_lo, ray)) return std::nullopt;
  const auto occupied_voxel = [&](const octomap::OcTreeKey& key) {
    const OctoTile* tile = impl_->tiles.find(tile_id_of(key));
    if (tile == nullptr) return false;
    const octomap::OcTreeNode* node = tile->tree->search(key);
    return node != nullptr && tile->tree->isNodeOccupied(node);
  };
  std::optional<octomap::OcTreeKey> hit;
  for (const octomap::OcTreeKey& key : ray) {
    if (occupied_voxel(key)) {
      hit = key;
      break;
    }
  }
  if (!hit) {
    const octomap::OcTreeKey end_key = keys.coordToKey(end_lo);
    if (occupied_voxel(end_key)) hit = end_key;
  }
  if (!hit) return std::nullopt;
  const Eigen::Vector3d center = to_eigen(keys.keyToCoord(*hit));
  return OctoRayHit{center, (center - origin_W).norm()};
}

namespace {

// Collides footprint with every tile its bounding sphere (about base_link's origin, height included) reaches; the
// first hit answers. With no tile in reach the empty tile answers, which still checks the footprint's dimensions.
OctoCollision collide_tiles(const OctoTileTable& tiles, const OctoTile& empty, const geometry::Footprint& footprint,
                            const geometry::Pose3& X_WB, bool with_columns) {
  const double height = geometry::footprint_height(footprint);
  const double radius = std::hypot(geometry::bounding_radius(footprint), height);
  if (!std::isfinite(radius) || !X_WB.transform.matrix().allFinite() || tiles.empty()) {
    return collide_footprint(*empty.fcl_view, with_columns ? &empty.columns : nullptr, footprint, X_WB);
  }
  // One voxel more on each side: FCL counts a voxel the footprint merely touches.
  const Eigen::Vector3d reach = Eigen::Vector3d::Constant(radius + empty.tree->getResolution());
  const auto [lo, hi] = key_box(*empty.tree, X_WB.translation() - reach, X_WB.translation() + reach);
  OctoCollision collision;
  bool checked = false;
  for_tiles_in_keys(tiles, lo, hi, [&](const OctoTile& tile) {
    checked = true;
    collision = collide_footprint(*tile.fcl_view, with_columns ? &tile.columns : nullptr, footprint, X_WB);
    return !collision.hit;
  });
  if (!checked) return collide_footprint(*empty.fcl_view, with_columns ? &empty.columns : nullptr, footprint, X_WB);
  return collision;
}

}  // namespace

OctoCollision OctoMapSnapshot::collide(const geometry::Footprint& footprint, const geometry::Pose3& X_WB) const {
  return collide_tiles(impl_->tiles, *impl_->empty, footprint, X_WB, true);
}

OctoCollision OctoMapSnapshot::collide_fcl_only(const geometry::Footprint& footprint,
                                                const geometry::Pose3& X_WB) const {
  return collide_tiles(impl_->tiles, *impl_->empty, footprint, X_WB, false);
}

double OctoMapSnapshot::resolution() const { return impl_->empty->tree->getResolution(); }

namespace {

// What glibc's malloc takes for `size` bytes: an 8-byte header, rounded up to 16, at least 32.
constexpr std::size_t heap_chunk(std::size_t size) { return std::max<std::size_t>(32, (size + 8 + 15) / 16 * 16); }

}  // namespace

const std::optional<std::vector<OctoColumnRange>>& OctoMapSnapshot::changed_columns() const {
  return impl_->changed_columns;
}

std::uint64_t OctoMapSnapshot::changed_since_version() const { return impl_->changed_since_version; }

std::vector<OctoColumnRange> OctoMapSnapshot::all_columns() const {
  std::vector<OctoTileId> ids;
  ids.reserve(impl_->tiles.size());
  impl_->tiles.visit_all([&ids](OctoTileId id, const OctoTile& /*tile*/) {
    ids.push_back(id);
    return true;
  });
  return columns_of_tiles(ids);
}

namespace {

std::size_t octree_node_bytes() { return heap_chunk(sizeof(octomap::OcTreeNode)); }
std::size_t octree_children_bytes() { return heap_chunk(8 * sizeof(octomap::AbstractOcTreeNode*)); }

// Heap bytes of one published tile: its tree's nodes and child arrays, its column summary and its records.
std::size_t tile_heap_bytes(const OctoTile& tile) {
  return tile.node_count * octree_node_bytes() + (tile.node_count - tile.leaf_count) * octree_children_bytes() +
         (tile.columns.z_low.capacity() + tile.columns.z_high.capacity()) * sizeof(std::uint16_t) +
         heap_chunk(sizeof(OctoTile)) + heap_chunk(sizeof(octomap::OcTree));
}

}  // namespace

std::size_t OctoMapSnapshot::memory_bytes() const {
  const std::size_t nodes = impl_->tile_sums.nodes;
  const std::size_t leaves = impl_->tile_sums.leaves;
  // The live tree holds the same leaves; its inner nodes are taken in the snapshot's proportion.
  const std::size_t live = impl_->live_tree_nodes;
  const double inner_share = nodes == 0 ? 0.0 : static_cast<double>(nodes - leaves) / static_cast<double>(nodes);
  return impl_->tile_sums.bytes + live * octree_node_bytes() +
         static_cast<std::size_t>(std::llround(static_cast<double>(live) * inner_share)) * octree_children_bytes();
}
std::size_t OctoMapSnapshot::leaf_count() const { return impl_->tile_sums.leaves; }
std::size_t OctoMapSnapshot::node_count() const {
  return impl_->nodes_above_tiles + impl_->tile_sums.nodes - impl_->tiles.size() * kTileDepth;
}

// ---------------------------------------------------------------------------------------------------------------------
// Model

struct OctoMapModel::Impl {
  explicit Impl(const OctoMapParams& params) : tree(std::make_unique<octomap::OcTree>(params.resolution_m)) {
    apply_params(*tree, params);
  }

  // One reading's ray: from the batch's origin to end, carving free space unless !carve; end is marked occupied only
  // when hit.
  struct Ray {
    octomap::point3d end;
    bool hit;
    bool carve = true;
  };

  // Applies one batch of rays from origin exactly as OccupancyOcTreeBase::insertPointCloud → computeUpdate does
  // (free keys of every ray, end keys of hits, occupied wins over free, one update per key), but with lazy_eval: the
  // inner nodes are brought up to date once, by refresh_inner(), before anything reads them. Each key gets the same
  // single update as in the plain path, so every leaf ends up with the same log-odds.
  //
  // The keys are deduplicated without hash sets: each ray's keys, as they are walked, are marked in a bitmap over the
  // batch's bounding box (or, when that box is too sparse, appended to one flat buffer, Morton-coded, sorted and
  // uniqued). Either way the updates run in an order where consecutive keys share most of their tree path, which
  // update() exploits. The order of the updates does not matter: each key gets exactly one, and a lazy update never
  // changes another key's leaf.
  // see_through: the batch is one laser scan, whose seen-through voxels are capped (OctoMapParams::
  // laser_see_through_clears); only in the bitmap path, which every planar scan takes.
  void apply(const octomap::point3d& origin, const std::vector<Ray>& batch, bool see_through = false) {
    ray_keys.clear();
    hit_keys.clear();
    // A ray's keys step monotonically along each axis (a 3D DDA) from the origin's key towards the end's, so those two
    // bound them all (but for one key past the end's, below); their difference, summed over the axes, is how many the
    // ray has (about: the walk may stop short).
    std::array<unsigned, 3> lo{0xFFFFU, 0xFFFFU, 0xFFFFU}, hi{0U, 0U, 0U};
    const auto extend = [&lo, &hi](const octomap::OcTreeKey& key) {
      for (int i = 0; i < 3; ++i) {
        lo[i] = std::min<unsigned>(lo[i], key[i]);
        hi[i] = std::max<unsigned>(hi[i], key[i]);
      }
    };
    octomap::OcTreeKey origin_key;
    const bool origin_on_tree = tree->coordToKeyChecked(origin, origin_key);
    std::uint64_t n_keys = 0;
    for (const Ray& ray : batch) {
      octomap::OcTreeKey end_key;
      const bool end_on_tree = tree->coordToKeyChecked(ray.end, end_key);
      if (ray.carve && origin_on_tree && end_on_tree && origin_key != end_key) {
        extend(origin_key);
        // Rounding can take the walk one key past the end's along any axis the ray moves on.
        octomap::OcTreeKey past_end = end_key;
        for (unsigned i = 0; i < 3; ++i) {
          n_keys += static_cast<std::uint64_t>(std::abs(int{origin_key[i]} - int{end_key[i]}));
          const float along = ray.end(i) - origin(i);
          if (along > 0.0F && past_end[i] < 0xFFFFU) ++past_end[i];
          if (along < 0.0F && past_end[i] > 0U) --past_end[i];
        }
        extend(past_end);
      }
      if (ray.hit && end_on_tree) {
        hit_keys.push_back(end_key);
        extend(end_key);
      }
    }
    n_keys += hit_keys.size();
    if (n_keys == 0) return;
    inner_stale = true;
    path_depth = -1;

    // x and y on the tree's 8-voxel blocks (apply_by_bitmap's layout).
    lo[0] &= ~7U;
    lo[1] &= ~7U;
    const std::uint64_t nx = ((hi[0] - lo[0]) | 7U) + 1, ny = ((hi[1] - lo[1]) | 7U) + 1, nz = hi[2] - lo[2] + 1;
    const std::uint64_t volume = nx * ny * nz;
    if (volume <= kMaxBitmapCells && volume <= 256 * n_keys) {
      apply_by_bitmap(origin, batch, lo, nx, ny, nz, volume, see_through);
    } else {
      for (const Ray& ray : batch) {
        if (ray.carve) {
          for_each_ray_key(origin, ray.end, [this](const octomap::OcTreeKey& key) { ray_keys.push_back(key); });
        }
      }
      apply_by_sorting();
    }
  }

  // Hands visit the free keys of the ray from origin to end, those OcTreeBaseImpl::computeRayKeys lists: the same 3D
  // DDA with the same arithmetic, so the same keys, without a KeyRay to fill and copy. Nothing for a ray with an end
  // off the tree or within the origin's voxel.
  template <typename Visit>
  void for_each_ray_key(const octomap::point3d& origin, const octomap::point3d& end, Visit&& visit) const {
    octomap::OcTreeKey key_origin, key_end;
    if (!tree->coordToKeyChecked(origin, key_origin) || !tree->coordToKeyChecked(end, key_end)) return;
    if (key_origin == key_end) return;
    visit(key_origin);
    octomap::point3d direction = end - origin;
    const auto length = static_cast<float>(direction.norm());
    direction /= length;
    const double resolution = tree->getResolution();
    std::array<int, 3> step{};
    std::array<double, 3> t_max{}, t_delta{};
    octomap::OcTreeKey key = key_origin;
    for (unsigned i = 0; i < 3; ++i) {
      const auto along = static_cast<double>(direction(i));
      step[i] = along > 0.0 ? 1 : (along < 0.0 ? -1 : 0);
      if (step[i] != 0) {
        double voxel_border = tree->keyToCoord(key[i]);
        voxel_border += static_cast<double>(static_cast<float>(step[i] * resolution * 0.5));
        t_max[i] = (voxel_border - static_cast<double>(origin(i))) / along;
        t_delta[i] = resolution / std::fabs(along);
      } else {
        t_max[i] = std::numeric_limits<double>::max();
        t_delta[i] = std::numeric_limits<double>::max();
      }
    }
    if (step[2] == 0) {
      // A level ray (every ray of a planar laser): the z axis is never chosen, as its t_max stays the largest double.
      while (true) {
        const unsigned dim = t_max[0] < t_max[1] ? 0U : 1U;
        key[dim] = static_cast<octomap::key_type>(key[dim] + step[dim]);
        t_max[dim] += t_delta[dim];
        if (key[0] == key_end[0] && key[1] == key_end[1]) return;
        if (std::min(t_max[0], t_max[1]) > static_cast<double>(length)) return;
        visit(key);
      }
    }
    while (true) {
      const unsigned dim = t_max[0] < t_max[1] ? (t_max[0] < t_max[2] ? 0U : 2U) : (t_max[1] < t_max[2] ? 1U : 2U);
      key[dim] = static_cast<octomap::key_type>(key[dim] + step[dim]);
      t_max[dim] += t_delta[dim];
      if (key == key_end) return;
      // Past the end's distance without reaching its voxel (rounding): computeRayKeys stops there too.
      if (std::min(std::min(t_max[0], t_max[1]), t_max[2]) > static_cast<double>(length)) return;
      visit(key);
    }
  }

  // apply's deduplication for a compact batch (a planar scan): one free and one hit bit per cell of the keys' bounding
  // box, x fastest. The bitmaps are all zero between calls (each word is cleared as it is read).
  void apply_by_bitmap(const octomap::point3d& origin, const std::vector<Ray>& batch, const std::array<unsigned, 3>& lo,
                       std::uint64_t nx, std::uint64_t ny, std::uint64_t nz, std::uint64_t volume, bool see_through) {
    const std::size_t n_words = static_cast<std::size_t>((volume + 63) / 64);
    if (free_bits.size() < n_words) {
      free_bits.resize(n_words, 0);
      hit_bits.resize(n_words, 0);
    }
    // One 64-bit word per 8 x 8 voxels of one layer of a tree block (lo[0], lo[1], nx and ny are multiples of 8), so
    // that the updates visit the tree block by block, in the order its nodes lie, rather than in rows across blocks.
    const std::uint64_t blocks_x = nx >> 3U, blocks_y = ny >> 3U;
    const auto local_index = [blocks_x, blocks_y](std::uint64_t x, std::uint64_t y, std::uint64_t z) {
      return ((z * blocks_y + (y >> 3U)) * blocks_x + (x >> 3U)) << 6U | (y & 7U) << 3U | (x & 7U);
    };
    const auto index = [&](const octomap::OcTreeKey& key) {
      return local_index(key[0] - lo[0], key[1] - lo[1], key[2] - lo[2]);
    };
    if (see_through) {
      if (near_hit_bits.size() < n_words) {
        near_hit_bits.resize(n_words, 0);
      }
      // Voxels within kSeeThroughSpare_m of a hit (one voxel up and down) were not seen through: where beams graze a
      // wall they cross some of its voxels to end on it further along, and the scan's other beams end close by.
      const auto spare = static_cast<std::int64_t>(std::ceil(kSeeThroughSpare_m / tree->getResolution() - 1e-9));
      for (const octomap::OcTreeKey& key : hit_keys) {
        const std::int64_t x = key[0] - lo[0], y = key[1] - lo[1], z = key[2] - lo[2];
        for (std::int64_t nzi = std::max<std::int64_t>(z - 1, 0); nzi <= std::min<std::int64_t>(z + 1, nz - 1); ++nzi) {
          for (std::int64_t nyi = std::max<std::int64_t>(y - spare, 0);
               nyi <= std::min<std::int64_t>(y + spare, static_cast<std::int64_t>(ny) - 1); ++nyi) {
            for (std::int64_t nxi = std::max<std::int64_t>(x - spare, 0);
                 nxi <= std::min<std::int64_t>(x + spare, static_cast<std::int64_t>(nx) - 1); ++nxi) {
              const std::uint64_t i = local_index(static_cast<std::uint64_t>(nxi), static_cast<std::uint64_t>(nyi),
                                                  static_cast<std::uint64_t>(nzi));
              std::uint64_t& word = near_hit_bits[i >> 6];
              if (word == 0) near_hit_words.push_back(i >> 6);
              word |= std::uint64_t{1} << (i & 63);
            }
          }
        }
      }
    }
    const float cap = tree->getOccupancyThresLog() - tree->getProbMissLog() / 2.0F;
    for (const Ray& ray : batch) {
      if (!ray.carve) continue;
      for_each_ray_key(origin, ray.end, [&](const octomap::OcTreeKey& key) {
        const std::uint64_t i = index(key);
        free_bits[i >> 6] |= std::uint64_t{1} << (i & 63);
      });
    }
    for (const octomap::OcTreeKey& key : hit_keys) {
      const std::uint64_t i = index(key);
      hit_bits[i >> 6] |= std::uint64_t{1} << (i & 63);
    }
    const float miss = tree->getProbMissLog(), hit = tree->getProbHitLog();
    for (std::size_t w = 0; w < n_words; ++w) {
      const std::uint64_t hits = hit_bits[w];
      std::uint64_t cells = free_bits[w] | hits;
      if (cells == 0) continue;
      // Seen through: crossed by a beam, hit by none, and not near a hit.
      const std::uint64_t seen_through = see_through ? free_bits[w] & ~hits & ~near_hit_bits[w] : 0;
      free_bits[w] = 0;
      hit_bits[w] = 0;
      const std::uint64_t block_row = w / blocks_x;
      const std::uint64_t x0 = lo[0] + ((w % blocks_x) << 3U), y0 = lo[1] + ((block_row % blocks_y) << 3U);
      const auto z = static_cast<octomap::key_type>(lo[2] + block_row / blocks_y);
      while (cells != 0) {
        const int b = std::countr_zero(cells);
        cells &= cells - 1;
        const octomap::OcTreeKey key(static_cast<octomap::key_type>(x0 + (static_cast<unsigned>(b) & 7U)),
                                     static_cast<octomap::key_type>(y0 + (static_cast<unsigned>(b) >> 3U)), z);
        const bool is_hit = ((hits >> b) & 1U) != 0;
        update(key, is_hit ? hit : miss);
        if (((seen_through >> b) & 1U) != 0 && path_depth == 16) {
          // At most half a miss above the threshold, so the next such scan leaves it free.
          octomap::OcTreeNode* leaf = path[16];
          if (leaf->getLogOdds() > cap) {
            leaf->setLogOdds(cap);
            mark_dirty(key);
          }
        }
      }
    }
    for (const std::uint64_t w : near_hit_words) near_hit_bits[w] = 0;
    near_hit_words.clear();
  }

  // apply's deduplication for a sparse batch (a 3D cloud): Morton codes, sorted and uniqued, merged in Z order (the
  // tree's depth-first order).
  void apply_by_sorting() {
    const auto encode_all = [](const std::vector<octomap::OcTreeKey>& keys, std::vector<std::uint64_t>& codes) {
      codes.clear();
      codes.reserve(keys.size());
      for (const octomap::OcTreeKey& key : keys) codes.push_back(morton(key));
      std::sort(codes.begin(), codes.end());
      codes.erase(std::unique(codes.begin(), codes.end()), codes.end());
    };
    encode_all(ray_keys, free_codes);
    encode_all(hit_keys, hit_codes);
    const float miss = tree->getProbMissLog(), hit = tree->getProbHitLog();
    auto f = free_codes.begin();
    auto h = hit_codes.begin();
    while (f != free_codes.end() || h != hit_codes.end()) {
      if (h == hit_codes.end() || (f != free_codes.end() && *f < *h)) {
        update(unmorton(*f++), miss);
      } else {
        if (f != free_codes.end() && *f == *h) ++f;  // occupied wins over free
        update(unmorton(*h++), hit);
      }
    }
  }

  // Z-order code of a key: bit 3 i + c holds bit i of key[c], so that code order is the tree's depth-first order.
  static std::uint64_t spread(std::uint64_t v) {
    v = (v | v << 32) & 0x001F00000000FFFFULL;
    v = (v | v << 16) & 0x001F0000FF0000FFULL;
    v = (v | v << 8) & 0x100F00F00F00F00FULL;
    v = (v | v << 4) & 0x10C30C30C30C30C3ULL;
    return (v | v << 2) & 0x1249249249249249ULL;
  }
  static std::uint64_t compact(std::uint64_t v) {
    v &= 0x1249249249249249ULL;
    v = (v ^ (v >> 2)) & 0x10C30C30C30C30C3ULL;
    v = (v ^ (v >> 4)) & 0x100F00F00F00F00FULL;
    v = (v ^ (v >> 8)) & 0x001F0000FF0000FFULL;
    v = (v ^ (v >> 16)) & 0x001F00000000FFFFULL;
    return (v ^ (v >> 32)) & 0x1FFFFFULL;
  }
  static std::uint64_t morton(const octomap::OcTreeKey& key) {
    return spread(key[0]) | spread(key[1]) << 1 | spread(key[2]) << 2;
  }
  static octomap::OcTreeKey unmorton(std::uint64_t code) {
    return {static_cast<octomap::key_type>(compact(code)), static_cast<octomap::key_type>(compact(code >> 1)),
            static_cast<octomap::key_type>(compact(code >> 2))};
  }

  // One update of key by log_odds, exactly as OccupancyOcTreeBase::updateNode(key, log_odds, lazy_eval = true): no
  // change when the deepest existing node on key's path is a leaf (a voxel or a pruned node) already clamped in the
  // update's direction; otherwise pruned nodes on the path are expanded, missing ones created, and log_odds is added to
  // the voxel's leaf, clamped. Unlike updateNode (a search, then a second descent from the root), it descends once,
  // from the deepest node key's path shares with the previous update's (path[0..path_depth], valid while nothing
  // prunes, i.e. within one apply).
  void update(const octomap::OcTreeKey& key, float log_odds) {
    octomap::OcTree& t = *tree;
    if (t.getRoot() == nullptr || t.isChangeDetectionEnabled()) {
      t.updateNode(key, log_odds, /*lazy_eval=*/true);
      mark_dirty(key);
      path_depth = -1;
      return;
    }
    int depth = 0;
    if (path_depth < 0) {
      path[0] = t.getRoot();
    } else {
      const auto diff =
          static_cast<std::uint16_t>((key[0] ^ path_key[0]) | (key[1] ^ path_key[1]) | (key[2] ^ path_key[2]));
      depth = std::min(std::countl_zero(diff), path_depth);
    }
    path_key = key;
    octomap::OcTreeNode* node = path[static_cast<std::size_t>(depth)];
    bool just_created = false;  // a resumed node either has children or is a pruned leaf, never a new one
    constexpr int kDepth = 16;
    for (; depth < kDepth; ++depth) {
      const unsigned pos = octomap::computeChildIdx(key, kDepth - 1 - depth);
      bool created = false;
      if (!t.nodeChildExists(node, pos)) {
        if (!t.nodeHasChildren(node) && !just_created) {
          // A pruned leaf: updateNode's search stops here, and gives up when it is clamped already.
          if (clamped(node, log_odds)) {
            path_depth = depth;
            return;
          }
          t.expandNode(node);
          mark_dirty(key);
        } else {
          t.createNodeChild(node, pos);
          mark_dirty(key);
          created = true;
        }
      }
      node = t.getNodeChild(node, pos);
      just_created = created;
      path[static_cast<std::size_t>(depth) + 1] = node;
    }
    path_depth = kDepth;
    if (!clamped(node, log_odds)) {
      t.updateNodeLogOdds(node, log_odds);
      mark_dirty(key);
    }
  }

  // The voxel of key changed: the next publish refreshes its block's inner nodes and rebuilds its tile.
  void mark_dirty(const octomap::OcTreeKey& key) {
    const BlockId block = block_id_of(key);
    if (block == last_dirty_block) return;
    last_dirty_block = block;
    dirty_blocks.insert(block);
  }

  // The tiles of the changed blocks, each once.
  [[nodiscard]] std::vector<OctoTileId> dirty_tile_ids() const {
    constexpr unsigned kShift = static_cast<unsigned>(kRefreshDepth - kTileDepth);
    std::vector<OctoTileId> ids;
    ids.reserve(dirty_blocks.size());
    for (const BlockId block : dirty_blocks) {
      ids.push_back(pack_tile(static_cast<std::uint32_t>(block & 0xFFFFU) >> kShift,
                              static_cast<std::uint32_t>((block >> 16U) & 0xFFFFU) >> kShift,
                              static_cast<std::uint32_t>(block >> 32U) >> kShift));
    }
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    return ids;
  }

  // The nodes at kRefreshDepth (cubes of 8 voxels a side) that a publish refreshes when a voxel in them changed; a
  // tile is 64 voxels a side, and one scan changes few of its 512 blocks.
  static constexpr int kRefreshDepth = 13;
  static_assert(kRefreshDepth >= kTileDepth && kRefreshDepth <= 16);
  using BlockId = std::uint64_t;  // a key prefix: x | y << 16 | z << 32
  static constexpr BlockId kNoBlock = ~BlockId{0};
  static constexpr BlockId pack_block(std::uint64_t x, std::uint64_t y, std::uint64_t z) {
    return x | y << 16U | z << 32U;
  }
  static BlockId block_id_of(const octomap::OcTreeKey& key) {
    constexpr unsigned kShift = 16U - kRefreshDepth;
    return pack_block(key[0] >> kShift, key[1] >> kShift, key[2] >> kShift);
  }

  bool clamped(const octomap::OcTreeNode* node, float log_odds) const {
    return (log_odds >= 0 && node->getLogOdds() >= tree->getClampingThresMaxLog()) ||
           (log_odds <= 0 && node->getLogOdds() <= tree->getClampingThresMinLog());
  }

  // Recomputes every inner node's occupancy (the max of its children) after lazy updates, and prunes, leaving the
  // tree as compact as the plain path would: O(nodes), so it runs once per publish or save, not per scan.
  void refresh_inner() {
    if (!inner_stale) return;
    tree->updateInnerOccupancy();
    tree->prune();
    inner_stale = false;
  }

  // refresh_inner for the changed blocks only: their subtrees and the nodes above them, bottom-up, as
  // updateInnerOccupancy then prune would (a node's occupancy is its children's maximum; a node whose eight children
  // are equal leaves is pruned). The other subtrees are up to date already: lazy updates stale only their own paths.
  void refresh_changed_tiles() {
    if (!inner_stale) return;
    if (all_tiles_dirty || tree->getRoot() == nullptr) {
      refresh_inner();
      return;
    }
    // The changed blocks' ancestors at each depth, as key prefixes packed like block ids.
    std::array<std::unordered_set<BlockId>, kRefreshDepth + 1> prefixes;
    for (const BlockId block : dirty_blocks) {
      const std::uint64_t bx = block & 0xFFFFU, by = (block >> 16U) & 0xFFFFU, bz = block >> 32U;
      for (int depth = kRefreshDepth; depth >= 0; --depth) {
        const unsigned shift = static_cast<unsigned>(kRefreshDepth - depth);
        const auto inserted =
            prefixes[static_cast<std::size_t>(depth)].insert(pack_block(bx >> shift, by >> shift, bz >> shift));
        if (!inserted.second) break;
      }
    }
    refresh_above(tree->getRoot(), 0, 0, 0, 0, prefixes);
    inner_stale = false;
  }

  void refresh_above(octomap::OcTreeNode* node, int depth, std::uint64_t x, std::uint64_t y, std::uint64_t z,
                     const std::array<std::unordered_set<BlockId>, kRefreshDepth + 1>& prefixes) {
    octomap::OcTree& t = *tree;
    if (depth == kRefreshDepth) {
      refresh_subtree(node, depth);
      return;
    }
    if (!t.nodeHasChildren(node)) return;
    for (unsigned i = 0; i < 8; ++i) {
      if (!t.nodeChildExists(node, i)) continue;
      const std::uint64_t cx = x << 1U | (i & 1U), cy = y << 1U | ((i >> 1U) & 1U), cz = z << 1U | ((i >> 2U) & 1U);
      if (prefixes[static_cast<std::size_t>(depth) + 1].contains(pack_block(cx, cy, cz))) {
        refresh_above(t.getNodeChild(node, i), depth + 1, cx, cy, cz, prefixes);
      }
    }
    node->updateOccupancyChildren();
    static_cast<void>(t.pruneNode(node));
  }

  void refresh_subtree(octomap::OcTreeNode* node, int depth) {
    octomap::OcTree& t = *tree;
    if (!t.nodeHasChildren(node)) return;
    for (unsigned i = 0; i < 8; ++i) {
      if (t.nodeChildExists(node, i)) refresh_subtree(t.getNodeChild(node, i), depth + 1);
    }
    node->updateOccupancyChildren();
    static_cast<void>(t.pruneNode(node));
  }

  using NodeSurgery = octomap::OcTreeBaseImpl<detail::NodeSurgeryTag, detail::NodeSurgeryTag>;

  // The copy of one block (a node at kRefreshDepth, 8 voxels a side, and its subtree) that successive versions of its
  // tile share until a voxel in it changes: a publish copies the blocks that changed, not the whole tile. Its nodes
  // and their child arrays are one allocation, not two per node: on a map of gigabytes each node allocated and freed
  // on its own cost a few cache misses, and a scan replaces thousands.
  struct SharedBlock {
    std::size_t node_count = 0;
    std::size_t leaves = 0;

    // A copy of the subtree under from_node (a node of tree): one pass over the live nodes, then the copy built from
    // that list in one allocation.
    SharedBlock(const octomap::OcTree& tree, const octomap::OcTreeNode* from_node) {
      thread_local std::vector<Visit> order;
      order.clear();
      visit(tree, from_node, -1, 0, order);
      node_count = order.size();
      std::size_t inner = 0;
      for (const Visit& v : order) inner += v.inner ? 1 : 0;
      leaves = node_count - inner;
      const std::size_t slot_bytes = 8 * inner * sizeof(octomap::AbstractOcTreeNode*);
      storage_ = std::make_unique_for_overwrite<std::byte[]>(node_count * sizeof(octomap::OcTreeNode) + slot_bytes);
      auto* nodes = reinterpret_cast<octomap::OcTreeNode*>(storage_.get());  // NOLINT: storage for them
      auto* slots = reinterpret_cast<octomap::AbstractOcTreeNode**>(         // NOLINT: after the nodes, same alignment
          storage_.get() + node_count * sizeof(octomap::OcTreeNode));
      std::memset(static_cast<void*>(slots), 0, slot_bytes);  // null: no child there
      std::size_t next_slot = 0;
      for (std::size_t k = 0; k < order.size(); ++k) {
        Visit& v = order[k];
        octomap::OcTreeNode* node = new (&nodes[k]) octomap::OcTreeNode();
        node->setLogOdds(v.log_odds);
        if (v.parent >= 0) slots[order[static_cast<std::size_t>(v.parent)].slot_base + v.index] = node;
        if (v.inner) {
          v.slot_base = next_slot;
          NodeSurgery::set_children(node, &slots[next_slot]);
          next_slot += 8;
        }
      }
      root_ = nodes;
    }
    SharedBlock(const SharedBlock&) = delete;
    SharedBlock& operator=(const SharedBlock&) = delete;
    // The nodes end with their storage: ~OcTreeDataNode does nothing (but assert, in a debug build, that the tree has
    // deleted the children, which these nodes do not own).
    ~SharedBlock() = default;
    [[nodiscard]] octomap::OcTreeNode* node() const { return root_; }

   private:
    struct Visit {
      float log_odds;
      std::int32_t parent;  // index in the list; -1 for the block's node
      std::uint32_t index;  // child index under the parent
      bool inner;
      std::size_t slot_base = 0;  // of its children's slots, once placed
    };
    static void visit(const octomap::OcTree& tree, const octomap::OcTreeNode* node, std::int32_t parent, unsigned index,
                      std::vector<Visit>& order) {
      const bool inner = tree.nodeHasChildren(node);
      const auto self = static_cast<std::int32_t>(order.size());
      order.push_back({node->getLogOdds(), parent, index, inner});
      if (!inner) return;
      for (unsigned i = 0; i < 8; ++i) {
        if (tree.nodeChildExists(node, i)) visit(tree, tree.getNodeChild(node, i), self, i, order);
      }
    }

    // The nodes, then 8 child slots per inner node (null where no child).
    std::unique_ptr<std::byte[]> storage_;
    octomap::OcTreeNode* root_ = nullptr;
  };
  // A block's place in its tile: the child indices on the path from the tile's node down to it, 3 bits a level, the
  // first in the high bits, so that places ascend in depth-first order.
  using BlockPlace = std::uint16_t;
  static constexpr unsigned kBlockPlaceBits = static_cast<unsigned>(kRefreshDepth - kTileDepth);
  static_assert(kRefreshDepth > kTileDepth && 3 * kBlockPlaceBits <= 16);

  // A tree that can be given a root (OcTree makes one only on the first update) and so be built node by node, and
  // that holds shared blocks under some of its nodes.
  class TileTree : public octomap::OcTree {
   public:
    // OcTreeBaseImpl gives every tree a ray buffer of 100,000 keys (600 KB, zeroed) for inserting rays; a tile is
    // never written through rays, so it drops it. Kept, it made each tile of a snapshot cost 600 KB, and every tile a
    // publish replaced a 600 KB free, each of which made glibc consolidate its fast bins.
    explicit TileTree(double resolution_m) : octomap::OcTree(resolution_m) {
      keyrays.clear();
      keyrays.shrink_to_fit();
    }
    TileTree(const TileTree&) = delete;
    TileTree& operator=(const TileTree&) = delete;
    // The shared blocks are unhung first, so that OcTree's destructor deletes only this version's own nodes.
    ~TileTree() override {
      for (const HungBlock& hung : hung_) NodeSurgery::detach(hung.parent, hung.index);
    }
    octomap::OcTreeNode* make_root() {
      if (root == nullptr) {
        root = new octomap::OcTreeNode();  // NOLINT(cppcoreguidelines-owning-memory): the tree owns and deletes it
        ++tree_size;
        size_changed = true;
      }
      return root;
    }
    // Hangs block as child index of parent; blocks are hung in depth-first order, so in ascending place.
    void hang(octomap::OcTreeNode* parent, unsigned index, BlockPlace place, std::shared_ptr<const SharedBlock> block) {
      NodeSurgery::attach(parent, index, block->node());
      hung_.push_back({place, index, parent, std::move(block)});
    }
    // The block this version holds at place, or nullptr.
    [[nodiscard]] std::shared_ptr<const SharedBlock> block_at(BlockPlace place) const {
      const auto it = std::lower_bound(hung_.begin(), hung_.end(), place,
                                       [](const HungBlock& hung, BlockPlace p) { return hung.place < p; });
      return it != hung_.end() && it->place == place ? it->block : nullptr;
    }
    // The nodes of the tree, its shared blocks' included (OcTree counts only those its own calls created).
    void set_node_count(std::size_t nodes) { tree_size = nodes; }

   private:
    struct HungBlock {
      BlockPlace place;
      unsigned index;               // under parent
      octomap::OcTreeNode* parent;  // a node of this tree
      std::shared_ptr<const SharedBlock> block;
    };
    std::vector<HungBlock> hung_;  // in ascending place
  };

  // Nodes and leaves of a tile under construction.
  struct NodeCounts {
    std::size_t nodes = 0;
    std::size_t leaves = 0;
  };

  // The tile's levels above its blocks, copied node by node; each block below them taken from the previous version
  // of the tile when no voxel in it changed since, else copied. (bx, by, bz): from_node's coordinates in the tile, in
  // nodes of its depth; place: the child indices down to it (BlockPlace).
  void copy_tile_levels(TileTree& to, octomap::OcTreeNode* to_node, const octomap::OcTreeNode* from_node, int depth,
                        OctoTileId id, std::uint32_t bx, std::uint32_t by, std::uint32_t bz, unsigned place,
                        const TileTree* previous, NodeCounts& counts) const {
    const octomap::OcTree& t = *tree;
    for (unsigned i = 0; i < 8; ++i) {
      if (!t.nodeChildExists(from_node, i)) continue;
      const octomap::OcTreeNode* child = t.getNodeChild(from_node, i);
      const std::uint32_t cx = bx << 1U | (i & 1U), cy = by << 1U | ((i >> 1U) & 1U), cz = bz << 1U | ((i >> 2U) & 1U);
      if (depth + 1 < kRefreshDepth) {
        octomap::OcTreeNode* copy = to.createNodeChild(to_node, i);
        copy->setLogOdds(child->getLogOdds());
        ++counts.nodes;
        if (t.nodeHasChildren(child)) {
          copy_tile_levels(to, copy, child, depth + 1, id, cx, cy, cz, place << 3U | i, previous, counts);
        } else {
          ++counts.leaves;
        }
        continue;
      }
      const auto block_place = static_cast<BlockPlace>(place << 3U | i);
      std::shared_ptr<const SharedBlock> block;
      if (previous != nullptr &&
          !dirty_blocks.contains(pack_block(std::uint64_t{tile_axis(id, 0)} << kBlockPlaceBits | cx,
                                            std::uint64_t{tile_axis(id, 1)} << kBlockPlaceBits | cy,
                                            std::uint64_t{tile_axis(id, 2)} << kBlockPlaceBits | cz))) {
        block = previous->block_at(block_place);
      }
      if (!block) block = std::make_shared<const SharedBlock>(t, child);
      counts.nodes += block->node_count;
      counts.leaves += block->leaves;
      to.hang(to_node, i, block_place, std::move(block));
    }
  }

  // Tile id cut out of the tree into a tree of its own: the path from the root (each node with the tile's occupancy,
  // the maximum within it), then a copy of the tile's subtree, which shares with `previous` (the tile's last published
  // version, when its blocks are known to be up to date but for dirty_blocks) the blocks no voxel changed in; a pruned
  // leaf above the tile's depth becomes one leaf of the tile's size. nullptr when the tree holds nothing there.
  [[nodiscard]] std::shared_ptr<const OctoTile> build_tile(OctoTileId id, const OctoMapParams& params,
                                                           const OctoTile* previous) const {
    const octomap::OcTree& t = *tree;
    const octomap::OcTreeNode* node = t.getRoot();
    if (node == nullptr) return nullptr;
    const auto child_index = [id](int depth) {
      const unsigned shift = static_cast<unsigned>(kTileDepth - 1 - depth);
      return ((tile_axis(id, 0) >> shift) & 1U) | ((tile_axis(id, 1) >> shift) & 1U) << 1U |
             ((tile_axis(id, 2) >> shift) & 1U) << 2U;
    };
    for (int depth = 0; depth < kTileDepth && t.nodeHasChildren(node); ++depth) {
      const unsigned pos = child_index(depth);
      if (!t.nodeChildExists(node, pos)) return nullptr;
      node = t.getNodeChild(node, pos);
    }
    auto tile_tree = std::make_shared<TileTree>(t.getResolution());
    apply_params(*tile_tree, params);
    octomap::OcTreeNode* copy = tile_tree->make_root();
    copy->setLogOdds(node->getLogOdds());
    for (int depth = 0; depth < kTileDepth; ++depth) {
      copy = tile_tree->createNodeChild(copy, child_index(depth));
      copy->setLogOdds(node->getLogOdds());
    }
    NodeCounts counts{kTileDepth + 1, 0};
    if (t.nodeHasChildren(node)) {
      const auto* previous_tree = previous != nullptr ? dynamic_cast<const TileTree*>(previous->tree.get()) : nullptr;
      copy_tile_levels(*tile_tree, copy, node, kTileDepth, id, 0, 0, 0, 0, previous_tree, counts);
    } else {
      counts.leaves = 1;
    }
    tile_tree->set_node_count(counts.nodes);
    return make_tile(std::move(tile_tree), counts.leaves);
  }

  static std::shared_ptr<const OctoTile> make_tile(std::shared_ptr<const octomap::OcTree> tile_tree,
                                                   std::size_t leaf_count) {
    auto tile = std::make_shared<OctoTile>();
    tile->fcl_view = make_fcl_view(tile_tree);
    tile->columns = OccupiedColumns::build(*tile_tree);
    tile->leaf_count = leaf_count;
    tile->node_count = tile_tree->size();
    tile->tree = std::move(tile_tree);
    return tile;
  }

  // Counts (delta +1) or uncounts (-1) tile id under each of its ancestors above the tiles' depth; those with a tile
  // under them are the tree's nodes above the tiles.
  void count_tile_ancestors(OctoTileId id, int delta) {
    for (unsigned shift = 1; shift <= kTileDepth; ++shift) {
      // Depth kTileDepth - shift, tagged with it so that prefixes of different depths stay apart.
      const std::uint64_t prefix = tile_prefix(id, shift) | std::uint64_t{shift} << 32U;
      if (delta > 0) {
        ++tiles_under[prefix];
      } else if (const auto it = tiles_under.find(prefix); it != tiles_under.end() && --it->second == 0) {
        tiles_under.erase(it);
      }
    }
  }

  // Every tile the tree holds something in (after a load: all of them change).
  [[nodiscard]] std::vector<OctoTileId> all_tile_ids() const {
    std::vector<OctoTileId> ids;
    if (tree->getRoot() != nullptr) collect_tile_ids(tree->getRoot(), 0, 0, 0, 0, ids);
    return ids;
  }
  void collect_tile_ids(const octomap::OcTreeNode* node, int depth, OctoTileId x, OctoTileId y, OctoTileId z,
                        std::vector<OctoTileId>& ids) const {
    const octomap::OcTree& t = *tree;
    if (depth == kTileDepth) {
      ids.push_back(pack_tile(x, y, z));
      return;
    }
    const bool leaf = !t.nodeHasChildren(node);
    for (unsigned i = 0; i < 8; ++i) {
      if (!leaf && !t.nodeChildExists(node, i)) continue;
      const OctoTileId cx = x << 1U | (i & 1U), cy = y << 1U | ((i >> 1U) & 1U), cz = z << 1U | ((i >> 2U) & 1U);
      collect_tile_ids(leaf ? node : t.getNodeChild(node, i), depth + 1, cx, cy, cz, ids);
    }
  }

  // Brings the published tiles in step with the tree: the changed ones rebuilt, the rest kept; and the sums over the
  // tiles with them, so that a publish costs what changed.
  void update_tiles(const OctoMapParams& params, const std::vector<OctoTileId>& dirty_tiles) {
    refresh_changed_tiles();
    std::vector<std::pair<OctoTileId, OctoTileTable::ValuePtr>> changes;
    if (all_tiles_dirty) {
      tiles.clear();
      sums = {};
      tiles_under.clear();
      for (const OctoTileId id : all_tile_ids()) {
        if (auto tile = build_tile(id, params, nullptr)) changes.emplace_back(id, std::move(tile));
      }
    } else {
      changes.reserve(dirty_tiles.size());
      for (const OctoTileId id : dirty_tiles) changes.emplace_back(id, build_tile(id, params, tiles.find(id)));
    }
    tiles.apply(std::move(changes), [&](OctoTileId id, const OctoTile* before, const OctoTile* after) {
      if (before != nullptr) {
        sums.nodes -= before->node_count;
        sums.leaves -= before->leaf_count;
        sums.bytes -= tile_heap_bytes(*before);
      }
      if (after != nullptr) {
        sums.nodes += after->node_count;
        sums.leaves += after->leaf_count;
        sums.bytes += tile_heap_bytes(*after);
      }
      if ((before == nullptr) != (after == nullptr)) count_tile_ancestors(id, after != nullptr ? 1 : -1);
    });
    dirty_blocks.clear();
    last_dirty_block = kNoBlock;
    all_tiles_dirty = false;
  }

  std::unique_ptr<octomap::OcTree> tree;
  bool inner_stale = false;
  // The blocks changed since the last publish (last_dirty_block: the latest one marked, which spares most set
  // look-ups); their tiles are the ones the next publish rebuilds.
  std::unordered_set<BlockId> dirty_blocks;
  BlockId last_dirty_block = kNoBlock;
  bool all_tiles_dirty = false;
  OctoTileTable tiles;
  OctoTileSums sums;  // over tiles
  // Tiles under each ancestor above the tiles' depth (count_tile_ancestors).
  std::unordered_map<std::uint64_t, std::uint32_t> tiles_under;
  std::shared_ptr<const OctoTile> empty_tile;
  // Reused between batches so that they are allocated once.
  static constexpr std::uint64_t kMaxBitmapCells = std::uint64_t{1} << 27;  // 16 MiB per bitmap
  // The see-through rule spares voxels this close to a hit of the same scan (metres, in x and y).
  static constexpr double kSeeThroughSpare_m = 0.2;
  std::vector<octomap::OcTreeKey> ray_keys;  // the free keys of every ray of the batch, repeats included
  std::vector<octomap::OcTreeKey> hit_keys;  // the end keys of the hits, repeats included
  std::vector<std::uint64_t> free_bits, hit_bits;
  // The see-through rule's voxels near a hit (zero between calls) and the words it set.
  std::vector<std::uint64_t> near_hit_bits, near_hit_words;
  std::vector<std::uint64_t> free_codes, hit_codes;
  // update()'s cache: the nodes on the last updated key's path, root first, and that key.
  std::array<octomap::OcTreeNode*, 17> path{};
  int path_depth = -1;
  octomap::OcTreeKey path_key;
  std::vector<Ray> rays;
};

namespace {

// The rays one reading r along direction_S (unit, sensor frame) of a sensor at X_WS adds under limits (beam_use): one
// ray to the end when it is marked and carved alike, else a carving ray and a marking one.
template <typename Ray>
void push_rays(const geometry::Pose3& X_WS, const Eigen::Vector3d& direction_S, double r, double range_max,
               const BeamLimits& limits, std::vector<Ray>& rays) {
  const BeamUse use = beam_use(r, range_max, limits);
  if (use.hit && use.free_m >= r) {
    rays.push_back(Ray{to_octo(X_WS.transform * (r * direction_S)), true});
    return;
  }
  if (use.free_m > 0.0) rays.push_back(Ray{to_octo(X_WS.transform * (use.free_m * direction_S)), false});
  if (use.hit) rays.push_back(Ray{to_octo(X_WS.transform * (r * direction_S)), true, false});
}

}  // namespace

OctoMapModel::OctoMapModel(const OctoMapParams& params) : params_(params) {
  params_.validate();
  impl_ = std::make_unique<Impl>(params_);
  published_at_ = Clock::now();
  publish();
}

OctoMapModel::~OctoMapModel() = default;

void OctoMapModel::insert_scan(const geometry::Pose3& X_WS, float angle_min, float angle_increment,
                               std::span<const float> ranges, float range_max, const BeamLimits& limits) {
  require_finite_pose(X_WS, "insert_scan");
  if (!std::isfinite(angle_min) || !std::isfinite(angle_increment)) {
    throw std::invalid_argument("insert_scan: angle_min and angle_increment must be finite");
  }
  if (!std::isfinite(range_max) || range_max <= 0.0F) {
    throw std::invalid_argument("insert_scan: range_max must be finite and > 0");
  }
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    if (std::isnan(ranges[i]) || ranges[i] < 0.0F) {
      throw std::invalid_argument("insert_scan: ranges[" + std::to_string(i) + "] must be >= 0 and not NaN");
    }
  }
  const BeamLimits beam_limits = limits.capped(params_.max_range_m);
  const octomap::point3d origin = to_octo(X_WS.translation());
  std::vector<Impl::Ray>& rays = impl_->rays;
  rays.clear();
  rays.reserve(ranges.size());
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    const double r = ranges[i];
    if (r == 0.0) continue;  // no return: says nothing about the beam
    const double angle = double{angle_min} + static_cast<double>(i) * double{angle_increment};
    push_rays(X_WS, Eigen::Vector3d(std::cos(angle), std::sin(angle), 0.0), r, range_max, beam_limits, rays);
  }
  impl_->apply(origin, rays, params_.laser_see_through_clears);
  ++version_;
}

void OctoMapModel::insert_ray(const geometry::Pose3& X_WS, double range_m, double range_max_m,
                              const BeamLimits& limits) {
  require_finite_pose(X_WS, "insert_ray");
  if (!std::isfinite(range_max_m) || range_max_m <= 0.0) {
    throw std::invalid_argument("insert_ray: range_max_m must be finite and > 0");
  }
  if (std::isnan(range_m) || range_m < 0.0) throw std::invalid_argument("insert_ray: range_m must be >= 0");
  if (range_m == 0.0) return;
  impl_->rays.clear();
  push_rays(X_WS, Eigen::Vector3d::UnitX(), range_m, range_max_m, limits.capped(params_.max_range_m), impl_->rays);
  impl_->apply(to_octo(X_WS.translation()), impl_->rays);
  ++version_;
}

std::size_t OctoMapModel::insert_cloud(const geometry::Pose3& X_WS, std::span<const Eigen::Vector3f> points_S,
                                       const BeamLimits& limits) {
  require_finite_pose(X_WS, "insert_cloud");
  const Eigen::Isometry3f X_WS_f = X_WS.transform.cast<float>();
  std::vector<Eigen::Vector3f> points_W;
  points_W.reserve(points_S.size());
  for (const Eigen::Vector3f& p_S : points_S) {
    if (p_S.allFinite()) points_W.push_back(X_WS_f * p_S);
  }
  if (params_.voxel_filter_enabled || params_.outlier_filter_enabled) points_W = filter_cloud(points_W, params_);

  const BeamLimits cloud_limits = limits.capped(params_.max_range_m);
  const octomap::point3d origin = to_octo(X_WS.translation());
  const octomap::OcTree& tree = *impl_->tree;
  std::vector<Impl::Ray>& rays = impl_->rays;
  rays.clear();
  rays.reserve(points_W.size());
  octomap::KeySet end_keys;  // only for discretize_endpoints
  for (const Eigen::Vector3f& p : points_W) {
    octomap::point3d end{p.x(), p.y(), p.z()};
    if (params_.discretize_endpoints) {
      // As computeDiscreteUpdate: one ray per end voxel, to the voxel's centre.
      octomap::OcTreeKey key;
      if (!tree.coordToKeyChecked(end, key) || !end_keys.insert(key).second) continue;
      end = tree.keyToCoord(key);
    }
    // Same arithmetic (float) as computeUpdate's max-range branch, so that this path and insertPointCloud agree.
    const double length = (end - origin).norm();
    if (length <= cloud_limits.max_insert_range_m && length <= cloud_limits.max_free_range_m) {
      rays.push_back({end, true});
    } else if (length > cloud_limits.max_insert_range_m) {
      const double carve = std::min(cloud_limits.max_insert_range_m, cloud_limits.max_free_range_m);
      if (carve > 0.0) rays.push_back({origin + (end - origin).normalized() * static_cast<float>(carve), false});
    } else {
      // Marked, but carved only up to max_free_range_m.
      if (cloud_limits.max_free_range_m > 0.0) {
        rays.push_back(
            {origin + (end - origin).normalized() * static_cast<float>(cloud_limits.max_free_range_m), false});
      }
      rays.push_back({end, true, false});
    }
  }
  impl_->apply(origin, rays);
  ++version_;
  return points_W.size();
}

std::size_t OctoMapModel::import_pcd(const std::filesystem::path& path, const geometry::Pose3& X_WS) {
  const std::vector<Eigen::Vector3f> points_S = read_pcd_points(path);
  return insert_cloud(X_WS, points_S);
}

void OctoMapModel::save_bt(const std::filesystem::path& path) {
  impl_->refresh_inner();
  // writeBinaryConst, not writeBinary: the latter turns the live tree itself into its maximum-likelihood version.
  if (!impl_->tree->writeBinaryConst(path.string())) {
    throw std::runtime_error("cannot write OctoMap file " + path.string());
  }
}

void OctoMapModel::load_bt(const std::filesystem::path& path) {
  if (!std::filesystem::is_regular_file(path)) throw std::runtime_error("no OctoMap file " + path.string());
  auto tree = std::make_unique<octomap::OcTree>(params_.resolution_m);
  if (!tree->readBinary(path.string())) throw std::runtime_error("cannot read OctoMap file " + path.string());
  OctoMapParams params = params_;
  params.resolution_m = tree->getResolution();
  params.validate();
  apply_params(*tree, params);
  params_ = params;
  impl_->tree = std::move(tree);
  impl_->inner_stale = false;
  impl_->all_tiles_dirty = true;
  impl_->empty_tile = nullptr;
  ++version_;
}

std::shared_ptr<const OctoMapSnapshot> OctoMapModel::publish() {
  // What this publish rebuilds, for projections kept in step (changed_columns); the first snapshot, and the first
  // after a load, rebuild everything.
  std::optional<std::vector<OctoColumnRange>> changed_columns;
  const std::vector<OctoTileId> dirty_tiles = impl_->dirty_tile_ids();
  if (!impl_->all_tiles_dirty && impl_->empty_tile) changed_columns = columns_of_tiles(dirty_tiles);
  impl_->update_tiles(params_, dirty_tiles);
  if (!impl_->empty_tile) {
    auto empty_tree = std::make_shared<octomap::OcTree>(params_.resolution_m);
    apply_params(*empty_tree, params_);
    impl_->empty_tile = Impl::make_tile(std::move(empty_tree), 0);
  }
  auto snapshot_impl = std::make_unique<OctoMapSnapshot::Impl>();
  snapshot_impl->empty = impl_->empty_tile;
  snapshot_impl->tiles = impl_->tiles;  // the directory of chunks: the chunks and tiles are shared
  snapshot_impl->tile_sums = impl_->sums;
  snapshot_impl->nodes_above_tiles = impl_->tiles_under.size();
  snapshot_impl->live_tree_nodes = impl_->tree->size();
  snapshot_impl->changed_columns = std::move(changed_columns);
  snapshot_impl->changed_since_version = published_version_;
  std::shared_ptr<const OctoMapSnapshot> snapshot{
      new OctoMapSnapshot(std::move(snapshot_impl), version_, params_.terrain)};
  {
    const std::lock_guard lock(snapshot_mutex_);
    snapshot_ = snapshot;
  }
  published_version_ = version_;
  published_at_ = Clock::now();
  return snapshot;
}

bool OctoMapModel::maybe_publish(Clock::time_point now) {
  if (version_ == published_version_) return false;
  if (now - published_at_ < std::chrono::duration<double>(params_.min_publish_interval_s)) return false;
  publish();
  return true;
}

std::shared_ptr<const OctoMapSnapshot> OctoMapModel::snapshot() const {
  const std::lock_guard lock(snapshot_mutex_);
  return snapshot_;
}

std::optional<double> OctoMapModel::occupancy(const Eigen::Vector3d& p_W) const {
  return occupancy_in(*impl_->tree, p_W);
}

void OctoMapModel::for_each_leaf(const std::function<void(const OctoVoxel&)>& visit) const {
  const octomap::OcTree& tree = *impl_->tree;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) visit(voxel_of(it));
}

std::size_t OctoMapModel::leaf_count() const { return impl_->tree->getNumLeafNodes(); }

}  // namespace occgeo::mapping
