// FCL lives here only: the octree view of a snapshot and footprint collision against it.

#include <fcl/fcl.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>

#include "octomap_internal.h"

namespace occgeo::mapping {

struct FclOctreeView {
  // Shares the snapshot's tree; FCL only reads it, so concurrent queries on one view are safe (each collide call
  // builds its own traversal state).
  fcl::CollisionObjectd object;
};

std::shared_ptr<const FclOctreeView> make_fcl_view(const std::shared_ptr<const octomap::OcTree>& tree) {
  auto geometry = std::make_shared<fcl::OcTreed>(tree);
  return std::make_shared<const FclOctreeView>(FclOctreeView{fcl::CollisionObjectd(geometry)});
}

namespace {

// Every OcTree has 16 levels: its root covers keys [0, 2^16) on each axis.
constexpr int kTreeDepth = 16;
constexpr int kKeyCount = 1 << kTreeDepth;
// Cells of 4 voxels keep the summary small (1/16 of the voxel plane) yet fine enough to tell a pose beside a wall from
// one touching it (with 8-voxel cells bench_octomap's BM_CollideBox/0 took ~10% longer); a map wider than kMaxCells
// cells gets coarser cells instead of more memory (4 bytes a cell).
constexpr int kFinestCellShift = 2;
constexpr std::int64_t kMaxCells = std::int64_t{1} << 20;

// Growth of a queried box, in voxels: far above FCL's solver tolerances (~1e-6 m) and the rounding of voxel bounds, far
// below a voxel, so that a footprint standing on the floor's voxels (touching, not overlapping) is not sent to FCL.
constexpr double kMarginVoxels = 0.01;
// Nodes of this many voxels (per edge) or fewer enter the summary whole: it knows occupied z to 4 voxels.
constexpr int kSummaryNodeKeys = 4;

// An occupied node's key box: [base, base + size) on each axis.
struct LeafKeys {
  std::array<int, 3> base;
  int size;
};

void collect_occupied(const octomap::OcTree& tree, const octomap::OcTreeNode* node, std::array<int, 3> base, int size,
                      std::vector<LeafKeys>& out) {
  // An inner node holds the highest occupancy of its children (publish brings inner nodes up to date, readBinary sets
  // them so): below the threshold, nothing under it is occupied. Free space, most of a tree, is skipped whole.
  if (!tree.isNodeOccupied(node)) return;
  // An occupied node of kSummaryNodeKeys voxels or fewer has an occupied leaf somewhere inside: its whole box stands
  // for it (conservative), which spares the walk of the deepest levels, where most nodes are.
  if (size <= kSummaryNodeKeys || !tree.nodeHasChildren(node)) {
    out.push_back({base, size});
    return;
  }
  const int half = size / 2;
  for (unsigned int i = 0; i < 8; ++i) {
    if (!tree.nodeChildExists(node, i)) continue;
    const std::array<int, 3> child_base{base[0] + ((i & 1U) != 0 ? half : 0), base[1] + ((i & 2U) != 0 ? half : 0),
                                        base[2] + ((i & 4U) != 0 ? half : 0)};
    collect_occupied(tree, tree.getNodeChild(node, i), child_base, half, out);
  }
}

}  // namespace

OccupiedColumns OccupiedColumns::build(const octomap::OcTree& tree) {
  OccupiedColumns columns;
  columns.resolution_m = tree.getResolution();
  if (tree.getRoot() == nullptr) return columns;
  std::vector<LeafKeys> leaves;
  collect_occupied(tree, tree.getRoot(), {0, 0, 0}, kKeyCount, leaves);
  if (leaves.empty()) return columns;
  std::array<int, 2> key_min{kKeyCount, kKeyCount}, key_max{-1, -1};
  for (const LeafKeys& leaf : leaves) {
    for (int axis = 0; axis < 2; ++axis) {
      key_min[axis] = std::min(key_min[axis], leaf.base[axis]);
      key_max[axis] = std::max(key_max[axis], leaf.base[axis] + leaf.size - 1);
    }
  }
  int shift = kFinestCellShift;
  const auto cell_count = [&](int s) {
    return std::int64_t{(key_max[0] >> s) - (key_min[0] >> s) + 1} * ((key_max[1] >> s) - (key_min[1] >> s) + 1);
  };
  while (cell_count(shift) > kMaxCells) ++shift;
  columns.cell_shift = shift;
  columns.cell_min_x = key_min[0] >> shift;
  columns.cell_min_y = key_min[1] >> shift;
  columns.cells_x = (key_max[0] >> shift) - columns.cell_min_x + 1;
  columns.cells_y = (key_max[1] >> shift) - columns.cell_min_y + 1;
  const auto cells = static_cast<std::size_t>(columns.cells_x) * static_cast<std::size_t>(columns.cells_y);
  columns.z_low.assign(cells, UINT16_MAX);
  columns.z_high.assign(cells, 0);
  for (const LeafKeys& leaf : leaves) {
    const auto z_low = static_cast<std::uint16_t>(leaf.base[2]);
    const auto z_high = static_cast<std::uint16_t>(leaf.base[2] + leaf.size - 1);
    for (int cy = (leaf.base[1] >> shift); cy <= ((leaf.base[1] + leaf.size - 1) >> shift); ++cy) {
      for (int cx = (leaf.base[0] >> shift); cx <= ((leaf.base[0] + leaf.size - 1) >> shift); ++cx) {
        const std::size_t cell =
            static_cast<std::size_t>(cy - columns.cell_min_y) * static_cast<std::size_t>(columns.cells_x) +
            static_cast<std::size_t>(cx - columns.cell_min_x);
        columns.z_low[cell] = std::min(columns.z_low[cell], z_low);
        columns.z_high[cell] = std::max(columns.z_high[cell], z_high);
      }
    }
  }
  return columns;
}

bool OccupiedColumns::provably_free(const Eigen::Vector3d& min_W, const Eigen::Vector3d& max_W) const {
  if (cells_x == 0) return true;
  if (!min_W.allFinite() || !max_W.allFinite()) return false;
  // OctoMap's key of a coordinate: floor(c / resolution) + 2^15. The box grows by kMarginVoxels on each side, so that
  // a voxel it merely touches counts, as in FCL.
  const double margin_m = kMarginVoxels * resolution_m;
  std::array<double, 3> key_lo{}, key_hi{};
  for (int axis = 0; axis < 3; ++axis) {
    key_lo[axis] = std::floor((min_W[axis] - margin_m) / resolution_m) + kKeyCount / 2;
    key_hi[axis] = std::floor((max_W[axis] + margin_m) / resolution_m) + kKeyCount / 2;
    if (key_hi[axis] < 0.0 || key_lo[axis] > kKeyCount - 1.0) return true;  // no leaf exists beyond the key range
    key_lo[axis] = std::max(key_lo[axis], 0.0);
    key_hi[axis] = std::min(key_hi[axis], kKeyCount - 1.0);
  }
  const int cx_lo = std::max(static_cast<int>(key_lo[0]) >> cell_shift, cell_min_x);
  const int cx_hi = std::min(static_cast<int>(key_hi[0]) >> cell_shift, cell_min_x + cells_x - 1);
  const int cy_lo = std::max(static_cast<int>(key_lo[1]) >> cell_shift, cell_min_y);
  const int cy_hi = std::min(static_cast<int>(key_hi[1]) >> cell_shift, cell_min_y + cells_y - 1);
  const auto z_lo = static_cast<std::uint16_t>(key_lo[2]);
  const auto z_hi = static_cast<std::uint16_t>(key_hi[2]);
  for (int cy = cy_lo; cy <= cy_hi; ++cy) {
    const std::size_t row = static_cast<std::size_t>(cy - cell_min_y) * static_cast<std::size_t>(cells_x);
    for (int cx = cx_lo; cx <= cx_hi; ++cx) {
      const std::size_t cell = row + static_cast<std::size_t>(cx - cell_min_x);
      if (z_low[cell] <= z_hi && z_high[cell] >= z_lo) return false;
    }
  }
  return true;
}

namespace {

// The world-frame bounding box of the points p_F of a shape posed at X_WF.
template <typename Points>
std::pair<Eigen::Vector3d, Eigen::Vector3d> world_box(const Eigen::Isometry3d& X_WF, const Points& points_F) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(kInf), hi = Eigen::Vector3d::Constant(-kInf);
  for (const Eigen::Vector3d& p_F : points_F) {
    const Eigen::Vector3d p_W = X_WF * p_F;
    lo = lo.cwiseMin(p_W);
    hi = hi.cwiseMax(p_W);
  }
  return {lo, hi};
}

// The corners of the box [-half, half] centred on its frame.
std::array<Eigen::Vector3d, 8> box_corners(const Eigen::Vector3d& half) {
  std::array<Eigen::Vector3d, 8> corners;
  for (unsigned int i = 0; i < 8; ++i) {
    corners[i] = {(i & 1U) != 0 ? half.x() : -half.x(), (i & 2U) != 0 ? half.y() : -half.y(),
                  (i & 4U) != 0 ? half.z() : -half.z()};
  }
  return corners;
}

void require_dimension(double value, const char* field) {
  if (!std::isfinite(value) || value <= 0.0) {
    throw std::invalid_argument(std::string("collide: footprint ") + field + " must be finite and > 0");
  }
}

}  // namespace

OctoCollision collide_footprint(const FclOctreeView& view, const OccupiedColumns* columns,
                                const geometry::Footprint& footprint, const geometry::Pose3& X_WB) {
  if (!X_WB.transform.matrix().allFinite()) throw std::invalid_argument("collide: X_WB must be finite");
  // Footprints stand on base_link's z = 0; FCL's shapes are centred on their frame, hence the shift by half a height.
  std::shared_ptr<fcl::CollisionGeometryd> shape;
  Eigen::Isometry3d X_BF = Eigen::Isometry3d::Identity();
  bool proven_free = false;  // set when the broadphase proves the pose collision-free
  std::visit(
      [&](const auto& f) {
        using T = std::decay_t<decltype(f)>;
        if constexpr (std::is_same_v<T, geometry::BoxFootprint>) {
          require_dimension(f.length, "length");
          require_dimension(f.width, "width");
          require_dimension(f.height, "height");
          if (!std::isfinite(f.center_x)) throw std::invalid_argument("collide: footprint center_x must be finite");
          X_BF.translation() = Eigen::Vector3d{f.center_x, 0.0, f.height / 2};
          if (columns != nullptr) {
            const auto [lo, hi] =
                world_box(X_WB.transform * X_BF, box_corners({f.length / 2, f.width / 2, f.height / 2}));
            proven_free = columns->provably_free(lo, hi);
            if (proven_free) return;
          }
          shape = std::make_shared<fcl::Boxd>(f.length, f.width, f.height);
        } else if constexpr (std::is_same_v<T, geometry::ConvexPolygonFootprint>) {
          require_dimension(f.height, "height");
          if (f.vertices_B.size() < 3) throw std::invalid_argument("collide: footprint polygon needs >= 3 vertices");
          geometry::PrismMesh mesh = geometry::prism_mesh(f);
          if (columns != nullptr) {
            const auto [lo, hi] = world_box(X_WB.transform, mesh.vertices_B);
            proven_free = columns->provably_free(lo, hi);
            if (proven_free) return;
          }
          // The mesh stands on base_link's z = 0 already: X_BF stays identity.
          shape = std::make_shared<fcl::Convexd>(
              std::make_shared<const std::vector<Eigen::Vector3d>>(std::move(mesh.vertices_B)), mesh.face_count,
              std::make_shared<const std::vector<int>>(std::move(mesh.faces)));
        } else {
          require_dimension(f.radius, "radius");
          require_dimension(f.height, "height");
          X_BF.translation() = Eigen::Vector3d{0.0, 0.0, f.height / 2};
          if (columns != nullptr) {
            // The cylinder's circumscribed square prism: a slightly bigger box, still conservative.
            const auto [lo, hi] = world_box(X_WB.transform * X_BF, box_corners({f.radius, f.radius, f.height / 2}));
            proven_free = columns->provably_free(lo, hi);
            if (proven_free) return;
          }
          shape = std::make_shared<fcl::Cylinderd>(f.radius, f.height);
        }
      },
      footprint);
  if (proven_free) return {};
  const fcl::CollisionObjectd body(shape, X_WB.transform * X_BF);

  fcl::CollisionRequestd request;
  request.num_max_contacts = 1;
  request.enable_contact = true;
  fcl::CollisionResultd result;
  fcl::collide(&body, &view.object, request, result);
  OctoCollision collision;
  if (result.isCollision()) {
    collision.hit = true;
    if (result.numContacts() > 0) collision.contact_W = result.getContact(0).pos;
  }
  return collision;
}

}  // namespace occgeo::mapping
