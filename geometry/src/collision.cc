#include "occgeo/geometry/collision.h"

#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/narrowphase/collision.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "occgeo/geometry/convex_polygon.h"

// How the work is split between exact 2D geometry and FCL.
//
// Every occupied cell is a square prism spanning the footprint's whole z range, so contact and distance are 2D.
// A cheap exact 2D test classifies each candidate cell; only cells within kContactBand_m of touching go to
// fcl::collide, which decides them (touching counts as contact).
//
// FCL 0.7.0's GJK-based answers were measured against exact geometry (1e5 random cell/footprint pairs per query,
// plus placements 1e-12 to 1e-6 m either side of touching) and are used only where they are exact:
//  - fcl::distance is wrong by up to 0.45 m for two boxes with GST_LIBCCD (its GJK stops when a new support point is
//    as far from the origin as the current simplex, FCL issue #508), by up to 0.03 m with GST_INDEP at any
//    distance_tolerance, and by up to 0.68 m for a cylinder and a box with GST_LIBCCD at the default tolerance.
//    Clearances are therefore computed in closed form in 2D.
//  - fcl::collide for a cylinder and a box misses overlaps of 1e-8 m (GST_LIBCCD, default tolerance), reports
//    contact across gaps of 1e-8 m (GST_INDEP), and is inconsistent at exact touching with either. A vertical
//    cylinder touches a prism spanning its z range exactly when the sphere of the same radius at its mid-height
//    does, and FCL's sphere-box test is closed form, so the cylinder's FCL twin is that sphere.
//  - fcl::collide for two boxes (SAT) and for a sphere and a box agrees with exact geometry at 1e-12 m from touching
//    and counts touching as contact: these are the arbiters. Letting them decide every cell instead gives the same
//    answers on the randomized tests, 3-7x slower.

namespace occgeo::geometry {
namespace {

// Contact within this distance of touching is decided by FCL, metres. The 2D arithmetic is accurate to a few ulps
// of the coordinates (about 1e-13 m within 1 km of the origin), so outside this band its answer is exact.
constexpr double kContactBand_m = 1e-9;

// How far the cell prisms reach above and below the footprint, metres; any positive value gives the same answers.
constexpr double kCellOverhang_m = 0.5;

// A closed axis-aligned square cell in world coordinates, metres.
struct CellSquare {
  Eigen::Vector2d center_W;
  double half_size;
};

CellSquare square_of(const CellIndex& index, const GridGeometry& grid) {
  return {grid.center_of(index), grid.cell_size() / 2.0};
}

Eigen::Vector2d closest_point_in(const CellSquare& cell, const Eigen::Vector2d& p_W) {
  const Eigen::Vector2d half = Eigen::Vector2d::Constant(cell.half_size);
  return p_W.cwiseMax(cell.center_W - half).cwiseMin(cell.center_W + half);
}

// Distance from a footprint to a cell it does not overlap, metres, and the point of the cell where it is attained.
struct CellDistance {
  double distance_m = std::numeric_limits<double>::infinity();
  Eigen::Vector2d point_on_cell_W = Eigen::Vector2d::Zero();
};

// Exact distance between a convex shape and a cell square it does not overlap, with the closest point on the cell:
// the closest pair of two disjoint convex polygons always includes a vertex of one of them, so it is the nearest of
// the shape's vertices to the cell and the cell's corners to the shape (squared_to_shape(p_W): squared distance).
template <typename Vertices, typename SquaredDistanceToShape>
CellDistance convex_to_cell_distance(const CellSquare& cell, const Vertices& vertices_W,
                                     const SquaredDistanceToShape& squared_to_shape) {
  double best_squared = std::numeric_limits<double>::infinity();
  Eigen::Vector2d best_point_W = cell.center_W;
  for (const Eigen::Vector2d& vertex_W : vertices_W) {
    const Eigen::Vector2d on_cell_W = closest_point_in(cell, vertex_W);
    const double squared = (vertex_W - on_cell_W).squaredNorm();
    if (squared < best_squared) {
      best_squared = squared;
      best_point_W = on_cell_W;
    }
  }
  for (const double sx : {-1.0, 1.0}) {
    for (const double sy : {-1.0, 1.0}) {
      const Eigen::Vector2d cell_corner_W = cell.center_W + cell.half_size * Eigen::Vector2d(sx, sy);
      const double squared = squared_to_shape(cell_corner_W);
      if (squared < best_squared) {
        best_squared = squared;
        best_point_W = cell_corner_W;
      }
    }
  }
  return {std::sqrt(best_squared), best_point_W};
}

// Decides contact between a footprint's FCL shape and cell prisms with fcl::collide.
template <typename FootprintShape>
class FclContactArbiter {
 public:
  // X_WF places the footprint shape's centre in world; cell prisms are centred on the footprint's mid-height.
  FclContactArbiter(const FootprintShape& footprint_shape, const fcl::Transform3d& X_WF, double cell_size,
                    double footprint_height)
      : footprint_shape_(footprint_shape),
        X_WF_(X_WF),
        cell_shape_(cell_size, cell_size, footprint_height + 2.0 * kCellOverhang_m),
        X_WC_(fcl::Transform3d::Identity()) {
    footprint_shape_.computeLocalAABB();
    cell_shape_.computeLocalAABB();
    X_WC_.translation().z() = footprint_height / 2.0;
  }

  bool in_contact(const CellSquare& cell) {
    X_WC_.translation().head<2>() = cell.center_W;
    fcl::CollisionResultd result;
    fcl::collide(&footprint_shape_, X_WF_, &cell_shape_, X_WC_, request_, result);
    return result.isCollision();
  }

 private:
  FootprintShape footprint_shape_;
  fcl::Transform3d X_WF_;
  fcl::Boxd cell_shape_;
  fcl::Transform3d X_WC_;
  fcl::CollisionRequestd request_;
};

// A box footprint placed in the world: its exact 2D outline and, built on first use, its FCL twin.
class PlacedBox {
 public:
  PlacedBox(const BoxFootprint& box, const Pose2& X_WB, double cell_size)
      : box_(box),
        cell_size_(cell_size),
        axis_x_W_(std::cos(X_WB.theta), std::sin(X_WB.theta)),
        axis_y_W_(-axis_x_W_.y(), axis_x_W_.x()),
        center_W_(X_WB.position() + box.center_x * axis_x_W_),
        half_extents_(box.length / 2.0, box.width / 2.0),
        yaw_(X_WB.theta) {
    const double abs_cos = std::abs(axis_x_W_.x());
    const double abs_sin = std::abs(axis_x_W_.y());
    aabb_half_extents_ = {half_extents_.x() * abs_cos + half_extents_.y() * abs_sin,
                          half_extents_.x() * abs_sin + half_extents_.y() * abs_cos};
    unit_square_extent_on_box_axes_ = abs_cos + abs_sin;
    const Eigen::Vector2d along = half_extents_.x() * axis_x_W_;
    const Eigen::Vector2d across = half_extents_.y() * axis_y_W_;
    corners_W_ = {center_W_ + along + across, center_W_ - along + across, center_W_ - along - across,
                  center_W_ + along - across};
  }

  [[nodiscard]] const Eigen::Vector2d& center_W() const { return center_W_; }
  [[nodiscard]] Eigen::AlignedBox2d aabb_W() const {
    return {center_W_ - aabb_half_extents_, center_W_ + aabb_half_extents_};
  }

  // The largest gap between the projections of box and cell on the separating-axis candidates (world x and y, box
  // x and y), metres: positive means separated by at least that much, otherwise they overlap.
  [[nodiscard]] double separating_gap(const CellSquare& cell) const {
    const Eigen::Vector2d offset = cell.center_W - center_W_;
    const double cell_extent_on_box_axes = cell.half_size * unit_square_extent_on_box_axes_;
    return std::max({std::abs(offset.x()) - aabb_half_extents_.x() - cell.half_size,
                     std::abs(offset.y()) - aabb_half_extents_.y() - cell.half_size,
                     std::abs(offset.dot(axis_x_W_)) - half_extents_.x() - cell_extent_on_box_axes,
                     std::abs(offset.dot(axis_y_W_)) - half_extents_.y() - cell_extent_on_box_axes});
  }

  // Exact distance to a cell the box does not overlap.
  [[nodiscard]] CellDistance distance_to(const CellSquare& cell) const {
    return convex_to_cell_distance(cell, corners_W_, [&](const Eigen::Vector2d& p_W) {
      const Eigen::Vector2d offset = p_W - center_W_;
      const Eigen::Vector2d outside(std::max(std::abs(offset.dot(axis_x_W_)) - half_extents_.x(), 0.0),
                                    std::max(std::abs(offset.dot(axis_y_W_)) - half_extents_.y(), 0.0));
      return outside.squaredNorm();
    });
  }

  bool fcl_in_contact(const CellSquare& cell) {
    if (!fcl_) {
      fcl::Transform3d X_WF = fcl::Transform3d::Identity();
      X_WF.linear() = Eigen::AngleAxisd(yaw_, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      X_WF.translation() << center_W_, box_.height / 2.0;
      fcl_.emplace(fcl::Boxd(box_.length, box_.width, box_.height), X_WF, cell_size_, box_.height);
    }
    return fcl_->in_contact(cell);
  }

 private:
  BoxFootprint box_;
  double cell_size_;
  Eigen::Vector2d axis_x_W_;
  Eigen::Vector2d axis_y_W_;
  Eigen::Vector2d center_W_;
  Eigen::Vector2d half_extents_;
  double yaw_;
  Eigen::Vector2d aabb_half_extents_;
  double unit_square_extent_on_box_axes_;  // Half-extent of a square of half-size 1 projected on a box axis.
  std::array<Eigen::Vector2d, 4> corners_W_;
  std::optional<FclContactArbiter<fcl::Boxd>> fcl_;
};

// A cylinder footprint placed in the world: a disc in 2D and, built on first use, its FCL twin (see top of file).
class PlacedDisc {
 public:
  PlacedDisc(const CylinderFootprint& cylinder, const Pose2& X_WB, double cell_size)
      : cylinder_(cylinder), cell_size_(cell_size), center_W_(X_WB.position()) {}

  [[nodiscard]] const Eigen::Vector2d& center_W() const { return center_W_; }
  [[nodiscard]] Eigen::AlignedBox2d aabb_W() const {
    const Eigen::Vector2d half = Eigen::Vector2d::Constant(cylinder_.radius);
    return {center_W_ - half, center_W_ + half};
  }

  // Distance from the disc to the cell when positive, metres; non-positive means they overlap.
  [[nodiscard]] double separating_gap(const CellSquare& cell) const {
    return (center_W_ - closest_point_in(cell, center_W_)).norm() - cylinder_.radius;
  }

  // Exact distance to a cell the disc does not overlap (clamped at zero for cells that FCL found just touching).
  [[nodiscard]] CellDistance distance_to(const CellSquare& cell) const {
    return {std::max(separating_gap(cell), 0.0), closest_point_in(cell, center_W_)};
  }

  bool fcl_in_contact(const CellSquare& cell) {
    if (!fcl_) {
      fcl::Transform3d X_WF = fcl::Transform3d::Identity();
      X_WF.translation() << center_W_, cylinder_.height / 2.0;
      fcl_.emplace(fcl::Sphered(cylinder_.radius), X_WF, cell_size_, cylinder_.height);
    }
    return fcl_->in_contact(cell);
  }

 private:
  CylinderFootprint cylinder_;
  double cell_size_;
  Eigen::Vector2d center_W_;
  std::optional<FclContactArbiter<fcl::Sphered>> fcl_;
};

// A convex polygon footprint placed in the world. Its FCL twin (fcl::Convex, used against the OctoMap) is GJK-based,
// which the measurements above found inexact near touching, so here the exact 2D separating-axis test decides every
// cell itself, touching included.
class PlacedPolygon {
 public:
  PlacedPolygon(const ConvexPolygonFootprint& polygon, const Pose2& X_WB)
      : vertices_W_(placed_vertices(polygon, X_WB)), center_W_(vertex_centroid(vertices_W_)) {
    const std::size_t n = vertices_W_.size();
    edge_normals_W_.reserve(n);
    edge_offsets_.reserve(n);
    for (std::size_t k = 0; k < n; ++k) {
      const Eigen::Vector2d edge = vertices_W_[(k + 1) % n] - vertices_W_[k];
      const Eigen::Vector2d outward = Eigen::Vector2d(edge.y(), -edge.x()).normalized();
      edge_normals_W_.push_back(outward);
      edge_offsets_.push_back(outward.dot(vertices_W_[k]));
      aabb_W_.extend(vertices_W_[k]);
    }
  }

  [[nodiscard]] const Eigen::Vector2d& center_W() const { return center_W_; }
  [[nodiscard]] Eigen::AlignedBox2d aabb_W() const { return aabb_W_; }

  // The largest gap on the separating-axis candidates (world x and y both ways, each edge's outward normal), metres:
  // positive means separated by at least that much, otherwise they overlap.
  [[nodiscard]] double separating_gap(const CellSquare& cell) const {
    double gap = std::max({aabb_W_.min().x() - (cell.center_W.x() + cell.half_size),
                           cell.center_W.x() - cell.half_size - aabb_W_.max().x(),
                           aabb_W_.min().y() - (cell.center_W.y() + cell.half_size),
                           cell.center_W.y() - cell.half_size - aabb_W_.max().y()});
    for (std::size_t k = 0; k < edge_normals_W_.size(); ++k) {
      const Eigen::Vector2d& n = edge_normals_W_[k];
      const double cell_low = n.dot(cell.center_W) - cell.half_size * (std::abs(n.x()) + std::abs(n.y()));
      gap = std::max(gap, cell_low - edge_offsets_[k]);
    }
    return gap;
  }

  // Exact distance to a cell the polygon does not overlap.
  [[nodiscard]] CellDistance distance_to(const CellSquare& cell) const {
    return convex_to_cell_distance(cell, vertices_W_, [&](const Eigen::Vector2d& p_W) {
      return (closest_point_in_convex_polygon(vertices_W_, p_W) - p_W).squaredNorm();
    });
  }

  // Called only within kContactBand_m of touching: the same separating axes with unnormalised edge normals, whose
  // products are exact for vertices and cells on a binary lattice, so exact touching counts as contact there.
  bool fcl_in_contact(const CellSquare& cell) const {
    if (aabb_W_.min().x() > cell.center_W.x() + cell.half_size ||
        aabb_W_.max().x() < cell.center_W.x() - cell.half_size ||
        aabb_W_.min().y() > cell.center_W.y() + cell.half_size ||
        aabb_W_.max().y() < cell.center_W.y() - cell.half_size) {
      return false;
    }
    const std::size_t n = vertices_W_.size();
    for (std::size_t k = 0; k < n; ++k) {
      const Eigen::Vector2d edge = vertices_W_[(k + 1) % n] - vertices_W_[k];
      const Eigen::Vector2d outward(edge.y(), -edge.x());
      const double cell_low =
          outward.dot(cell.center_W) - cell.half_size * (std::abs(outward.x()) + std::abs(outward.y()));
      if (cell_low > outward.dot(vertices_W_[k])) return false;
    }
    return true;
  }

 private:
  std::vector<Eigen::Vector2d> vertices_W_;
  Eigen::Vector2d center_W_;
  std::vector<Eigen::Vector2d> edge_normals_W_;
  std::vector<double> edge_offsets_;  // Outward normal . any point of the edge, metres.
  Eigen::AlignedBox2d aabb_W_;
};

// Contact between footprint and cell given their separating gap; FCL decides the cases near touching.
template <typename PlacedFootprint>
bool in_contact(PlacedFootprint& footprint, const CellSquare& cell, double separating_gap) {
  if (separating_gap > kContactBand_m) return false;
  if (separating_gap < -kContactBand_m) return true;
  return footprint.fcl_in_contact(cell);
}

// An inclusive rectangle of cell indices.
struct CellRange {
  CellIndex min;
  CellIndex max;
};

// The cells whose closed squares come within kContactBand_m of box_W. Throws std::invalid_argument, blaming
// `fields`, when the range grown by `growth_cells` on every side would leave the int32 index range.
CellRange cells_near(const Eigen::AlignedBox2d& box_W, double cell_size, double growth_cells, const char* fields) {
  const double lowest = std::numeric_limits<std::int32_t>::min() + growth_cells;
  const double highest = std::numeric_limits<std::int32_t>::max() - growth_cells;
  const Eigen::Vector2d min = ((box_W.min().array() - kContactBand_m) / cell_size).floor();
  const Eigen::Vector2d max = ((box_W.max().array() + kContactBand_m) / cell_size).floor();
  if (!(min.minCoeff() >= lowest && max.maxCoeff() <= highest)) {
    throw std::invalid_argument(std::string(fields) + ": search area outside the int32 cell index range");
  }
  return {{static_cast<std::int32_t>(min.x()), static_cast<std::int32_t>(min.y())},
          {static_cast<std::int32_t>(max.x()), static_cast<std::int32_t>(max.y())}};
}

// Visits the occupied cells of ring `ring` around `core`: the core itself for ring 0, otherwise the cells whose
// Chebyshev index distance from the core is `ring`.
void visit_ring(const OccupiedCellSource& source, const CellRange& core, std::int32_t ring,
                const std::function<bool(const CellIndex&)>& visit) {
  if (ring == 0) {
    source.for_each_occupied(core.min, core.max, visit);
    return;
  }
  const CellIndex lo{core.min.ix - ring, core.min.iy - ring};
  const CellIndex hi{core.max.ix + ring, core.max.iy + ring};
  source.for_each_occupied(lo, {hi.ix, lo.iy}, visit);
  source.for_each_occupied({lo.ix, hi.iy}, hi, visit);
  source.for_each_occupied({lo.ix, lo.iy + 1}, {lo.ix, hi.iy - 1}, visit);
  source.for_each_occupied({hi.ix, lo.iy + 1}, {hi.ix, hi.iy - 1}, visit);
}

template <typename PlacedFootprint>
CollisionResult collide_with_cells(PlacedFootprint& footprint, const OccupiedCellSource& source,
                                   const GridGeometry& grid) {
  struct Search {
    PlacedFootprint& footprint;
    const GridGeometry& grid;
    CollisionResult result;
  } search{footprint, grid, {}};
  // Capturing one reference keeps the std::function in its small-object buffer: no allocation per query.
  const std::function<bool(const CellIndex&)> visit = [&search](const CellIndex& index) {
    ++search.result.cells_tested;
    const CellSquare cell = square_of(index, search.grid);
    if (!in_contact(search.footprint, cell, search.footprint.separating_gap(cell))) return true;
    search.result.hit = true;
    search.result.cell = index;
    return false;
  };
  const CellRange candidates = cells_near(footprint.aabb_W(), grid.cell_size(), 0.0, "CollisionRequest.pose");
  source.for_each_occupied(candidates.min, candidates.max, visit);
  return search.result;
}

template <typename PlacedFootprint>
ClearanceResult clearance_to_cells(PlacedFootprint& footprint, double max_distance_m, const OccupiedCellSource& source,
                                   const GridGeometry& grid) {
  struct Search {
    PlacedFootprint& footprint;
    const GridGeometry& grid;
    ClearanceResult result;
    bool contact_found = false;
  } search{footprint, grid, {}};
  search.result.clearance_m = max_distance_m;
  const std::function<bool(const CellIndex&)> visit = [&search](const CellIndex& index) {
    const CellSquare cell = square_of(index, search.grid);
    const double gap = search.footprint.separating_gap(cell);
    if (gap > search.result.clearance_m) return true;  // The gap bounds the distance from below.
    if (in_contact(search.footprint, cell, gap)) {
      search.result = {true, 0.0, index, closest_point_in(cell, search.footprint.center_W())};
      search.contact_found = true;
      return false;
    }
    const CellDistance distance = search.footprint.distance_to(cell);
    if (distance.distance_m <= search.result.clearance_m) {
      search.result = {true, distance.distance_m, index, distance.point_on_cell_W};
    }
    return true;
  };
  // Ring 0 holds every cell that can touch the footprint. Cells beyond ring k are more than k * cell_size from the
  // footprint's AABB, hence from the footprint, so the search ends by ring ceil(max_distance_m / cell_size), or one
  // later through rounding.
  const double max_rings = std::ceil(max_distance_m / grid.cell_size()) + 1.0;
  const CellRange core =
      cells_near(footprint.aabb_W(), grid.cell_size(), max_rings, "ClearanceRequest.pose and max_distance_m");
  for (std::int32_t ring = 0; !search.contact_found; ++ring) {
    visit_ring(source, core, ring, visit);
    if (search.result.clearance_m <= ring * grid.cell_size()) break;
  }
  return search.result;
}

// Throws std::invalid_argument naming `request_name`.`field` unless value is positive and finite; builds the message
// only when throwing, so valid requests cost no allocation.
void require_positive(double value, const char* request_name, const char* field) {
  if (!(std::isfinite(value) && value > 0.0)) {
    throw std::invalid_argument(std::string(request_name) + "." + field + " must be positive and finite, got " +
                                std::to_string(value));
  }
}

void validate(const Footprint& footprint, const Pose2& pose, const char* request_name) {
  if (!(std::isfinite(pose.x) && std::isfinite(pose.y) && std::isfinite(pose.theta))) {
    throw std::invalid_argument(std::string(request_name) + ".pose must be finite");
  }
  if (const auto* box = std::get_if<BoxFootprint>(&footprint)) {
    require_positive(box->length, request_name, "footprint.length");
    require_positive(box->width, request_name, "footprint.width");
    require_positive(box->height, request_name, "footprint.height");
    if (!std::isfinite(box->center_x)) {
      throw std::invalid_argument(std::string(request_name) + ".footprint.center_x must be finite");
    }
    return;
  }
  if (const auto* polygon = std::get_if<ConvexPolygonFootprint>(&footprint)) {
    require_positive(polygon->height, request_name, "footprint.height");
    if (const std::string problem = convex_polygon_problem(polygon->vertices_B, Orientation::counter_clockwise);
        !problem.empty()) {
      throw std::invalid_argument(std::string(request_name) + ".footprint.polygon." + problem);
    }
    return;
  }
  const auto& cylinder = std::get<CylinderFootprint>(footprint);
  require_positive(cylinder.radius, request_name, "footprint.radius");
  require_positive(cylinder.height, request_name, "footprint.height");
}

GridGeometry grid_of(const OccupiedCellSource& source) {
  const double cell_size = source.cell_size();
  require_positive(cell_size, "OccupiedCellSource", "cell_size()");
  return GridGeometry(cell_size);
}

// Runs query on the footprint placed at X_WB.
template <typename Query>
auto with_placed_footprint(const Footprint& footprint, const Pose2& X_WB, double cell_size, Query&& query) {
  if (const auto* box = std::get_if<BoxFootprint>(&footprint)) {
    PlacedBox placed(*box, X_WB, cell_size);
    return query(placed);
  }
  if (const auto* polygon = std::get_if<ConvexPolygonFootprint>(&footprint)) {
    PlacedPolygon placed(*polygon, X_WB);
    return query(placed);
  }
  PlacedDisc placed(std::get<CylinderFootprint>(footprint), X_WB, cell_size);
  return query(placed);
}

}  // namespace

CollisionResult check_collision(const CollisionRequest& request, const OccupiedCellSource& source) {
  validate(request.footprint, request.pose, "CollisionRequest");
  const GridGeometry grid = grid_of(source);
  return with_placed_footprint(request.footprint, request.pose, grid.cell_size(),
                               [&](auto& placed) { return collide_with_cells(placed, source, grid); });
}

ClearanceResult compute_clearance(const ClearanceRequest& request, const OccupiedCellSource& source) {
  validate(request.footprint, request.pose, "ClearanceRequest");
  if (!(std::isfinite(request.max_distance_m) && request.max_distance_m >= 0.0)) {
    throw std::invalid_argument("ClearanceRequest.max_distance_m must be finite and >= 0, got " +
                                std::to_string(request.max_distance_m));
  }
  const GridGeometry grid = grid_of(source);
  return with_placed_footprint(request.footprint, request.pose, grid.cell_size(), [&](auto& placed) {
    return clearance_to_cells(placed, request.max_distance_m, source, grid);
  });
}

}  // namespace occgeo::geometry
