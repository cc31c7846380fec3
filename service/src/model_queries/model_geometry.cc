#include "model_geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <tuple>
#include <utility>
#include <variant>
#include <vector>

#include "occgeo/geometry/convex_polygon.h"

namespace occgeo::service {

double octomap_ground_band_m(const mapping::OctoMapSnapshot& octomap) {
  return std::max(octomap.terrain().ground_band_m, octomap.resolution()) + 0.01;
}

mapping::TerrainMap terrain_around(const mapping::OctoMapSnapshot& octomap, double cell_size_m,
                                   const Eigen::Vector2d& lo_W, const Eigen::Vector2d& hi_W, double height_m,
                                   const std::optional<Eigen::Vector2d>& robot_W) {
  const auto index = [&](double v) { return static_cast<std::int32_t>(std::floor(v / cell_size_m)); };
  return {
      octomap,           cell_size_m, {index(lo_W.x()), index(lo_W.y())}, {index(hi_W.x()), index(hi_W.y())}, height_m,
      octomap.terrain(), robot_W};
}

void TerrainMaskedCells::for_each_occupied(geometry::CellIndex min, geometry::CellIndex max,
                                           const std::function<bool(const geometry::CellIndex&)>& visit) const {
  cells_.for_each_occupied(
      min, max, [&](const geometry::CellIndex& cell) { return terrain_.explains_returns(cell) || visit(cell); });
}

void RecentReturnCells::for_each_occupied(geometry::CellIndex min, geometry::CellIndex max,
                                          const std::function<bool(const geometry::CellIndex&)>& visit) const {
  if (within_.empty()) return;
  const double cell_m = cells_.cell_size();
  const Eigen::Vector2d lo(min.ix * cell_m, min.iy * cell_m);
  const Eigen::Vector2d hi((max.ix + 1) * cell_m, (max.iy + 1) * cell_m);
  // A tracked disc holds its cluster's returns up to float rounding.
  constexpr double kWithinMargin_m = 0.02;
  const auto within = [this](const Eigen::Vector2d& p_W) {
    return std::any_of(within_.begin(), within_.end(), [&p_W](const GroundDisc& disc) {
      return (p_W - disc.centre_W).norm() <= disc.radius_m + kWithinMargin_m;
    });
  };
  for (const mapping::PtemCluster& cluster : ptem_.clusters()) {
    if (cluster.age_s > max_age_s_) continue;
    // The circle holds every return: a cluster whose circle misses the box has none in it.
    const Eigen::Vector2d nearest = cluster.centre_W.cwiseMax(lo).cwiseMin(hi);
    if ((nearest - cluster.centre_W).norm() > cluster.radius_m) continue;
    for (const Eigen::Vector2d& p_W : cluster.extent_W) {
      if (!within(p_W)) continue;
      const geometry::CellIndex c = cells_.cell_of(p_W);
      if (c.ix < min.ix || c.ix > max.ix || c.iy < min.iy || c.iy > max.iy) continue;
      if (!visit(c)) return;
    }
  }
}

OctoMapColumns::OctoMapColumns(const mapping::OctoMapSnapshot& octomap, double top_m,
                               const mapping::TerrainMap* terrain, bool plausible_surfaces)
    : octomap_(octomap),
      bottom_m_(octomap_ground_band_m(octomap)),
      top_m_(top_m),
      terrain_(terrain),
      plausible_surfaces_(plausible_surfaces) {}

void OctoMapColumns::for_each_occupied(geometry::CellIndex min, geometry::CellIndex max,
                                       const std::function<bool(const geometry::CellIndex&)>& visit) const {
  const double r = octomap_.resolution();
  // The z range any column's band can reach: over the floor, or over the drivable surfaces.
  double low_m = bottom_m_;
  double high_m = top_m_;
  if (terrain_ != nullptr) {
    low_m = std::min(low_m, terrain_->lowest_drivable_surface_m());
    high_m = std::max(high_m, terrain_->highest_drivable_surface_m() + top_m_);
  }
  if (high_m < low_m) return;
  const Eigen::Vector3d min_W(min.ix * r, min.iy * r, low_m);
  const Eigen::Vector3d max_W((max.ix + 1.0) * r, (max.iy + 1.0) * r, high_m);
  octomap_.for_each_occupied(min_W, max_W, [&](const mapping::OctoVoxel& voxel) {
    const double half = voxel.size_m / 2.0;
    // Voxel faces lie on multiples of r: round, not floor, against the centre's float error.
    const auto first = [&](double c) { return static_cast<std::int32_t>(std::lround((c - half) / r)); };
    const auto last = [&](double c) { return static_cast<std::int32_t>(std::lround((c + half) / r)) - 1; };
    const std::int32_t x0 = std::max(first(voxel.center_W.x()), min.ix);
    const std::int32_t x1 = std::min(last(voxel.center_W.x()), max.ix);
    const std::int32_t y0 = std::max(first(voxel.center_W.y()), min.iy);
    const std::int32_t y1 = std::min(last(voxel.center_W.y()), max.iy);
    const double voxel_bottom = voxel.center_W.z() - half;
    const double voxel_top = voxel.center_W.z() + half;
    for (std::int32_t ix = x0; ix <= x1; ++ix) {
      for (std::int32_t iy = y0; iy <= y1; ++iy) {
        auto [band_low, band_high] = std::pair(bottom_m_, top_m_);
        if (terrain_ != nullptr) {
          const Eigen::Vector2d column_centre_W((ix + 0.5) * r, (iy + 0.5) * r);
          std::tie(band_low, band_high) =
              terrain_->obstacle_band(terrain_->cell_index(column_centre_W), bottom_m_, top_m_, plausible_surfaces_);
        }
        // Overlap of the closed band with the voxel, as the z box of the query above decides it.
        if (band_high < band_low || voxel_top < band_low || voxel_bottom > band_high) continue;
        if (!visit({ix, iy})) return false;
      }
    }
    return true;
  });
}

mapping::OctoCollision collide_octomap(const mapping::OctoMapSnapshot& octomap, const geometry::Footprint& footprint,
                                       const geometry::Pose2& X_WB) {
  const double band = octomap_ground_band_m(octomap);
  geometry::Footprint lifted = footprint;
  bool too_short = false;
  std::visit(
      [&](auto& shape) {
        if (shape.height <= band) too_short = true;
        shape.height -= band;
      },
      lifted);
  if (too_short) return {};
  geometry::Pose3 X_WL = geometry::Pose3::from_pose2(X_WB);
  X_WL.transform.translation().z() = band;
  return octomap.collide(lifted, X_WL);
}

namespace {

// X_WB with its rotation's cosine and sine worked out once, for the many points a PTEM check maps in and out of the
// body frame. The arithmetic is Pose2::inverse().transform() and Pose2::transform() exactly.
struct PlanarFrame {
  explicit PlanarFrame(const geometry::Pose2& pose) : c(std::cos(pose.theta)), s(std::sin(pose.theta)), X_WB(pose) {}
  [[nodiscard]] Eigen::Vector2d to_body(const Eigen::Vector2d& p_W) const {
    const double x_inv = -c * X_WB.x - s * X_WB.y, y_inv = s * X_WB.x - c * X_WB.y;
    return {x_inv + c * p_W.x() + s * p_W.y(), y_inv - s * p_W.x() + c * p_W.y()};
  }
  [[nodiscard]] Eigen::Vector2d to_world(const Eigen::Vector2d& p_B) const {
    return {X_WB.x + c * p_B.x() - s * p_B.y(), X_WB.y + s * p_B.x() + c * p_B.y()};
  }
  double c, s;
  geometry::Pose2 X_WB;
};

Eigen::Vector2d nearest_footprint_point(const geometry::Footprint& footprint, const PlanarFrame& frame,
                                        const Eigen::Vector2d& p_W) {
  const Eigen::Vector2d p_B = frame.to_body(p_W);
  Eigen::Vector2d q_B;
  if (const auto* box = std::get_if<geometry::BoxFootprint>(&footprint)) {
    q_B = {std::clamp(p_B.x(), box->center_x - box->length / 2, box->center_x + box->length / 2),
           std::clamp(p_B.y(), -box->width / 2, box->width / 2)};
  } else if (const auto* polygon = std::get_if<geometry::ConvexPolygonFootprint>(&footprint)) {
    q_B = geometry::closest_point_in_convex_polygon(polygon->vertices_B, p_B);
  } else {
    const double radius = std::get<geometry::CylinderFootprint>(footprint).radius;
    const double n = p_B.norm();
    q_B = n <= radius ? p_B : Eigen::Vector2d(p_B * (radius / n));
  }
  return frame.to_world(q_B);
}

}  // namespace

Eigen::Vector2d nearest_footprint_point(const geometry::Footprint& footprint, const geometry::Pose2& X_WB,
                                        const Eigen::Vector2d& p_W) {
  return nearest_footprint_point(footprint, PlanarFrame(X_WB), p_W);
}

Eigen::Vector2d footprint_center(const geometry::Footprint& footprint, const geometry::Pose2& X_WB) {
  if (const auto* box = std::get_if<geometry::BoxFootprint>(&footprint)) return X_WB.transform({box->center_x, 0.0});
  if (const auto* polygon = std::get_if<geometry::ConvexPolygonFootprint>(&footprint)) {
    return X_WB.transform(geometry::vertex_centroid(polygon->vertices_B));
  }
  return X_WB.position();
}

namespace {

// Points of the footprint every step metres on its boundary and on a grid inside, world frame.
std::vector<Eigen::Vector2d> footprint_samples(const geometry::Footprint& footprint, const geometry::Pose2& X_WB,
                                               double step) {
  std::vector<Eigen::Vector2d> points_B;
  if (const auto* box = std::get_if<geometry::BoxFootprint>(&footprint)) {
    const int nx = std::max(1, static_cast<int>(std::ceil(box->length / step)));
    const int ny = std::max(1, static_cast<int>(std::ceil(box->width / step)));
    for (int i = 0; i <= nx; ++i) {
      for (int j = 0; j <= ny; ++j) {
        points_B.emplace_back(box->center_x - box->length / 2 + box->length * i / nx,
                              -box->width / 2 + box->width * j / ny);
      }
    }
  } else if (const auto* polygon = std::get_if<geometry::ConvexPolygonFootprint>(&footprint)) {
    // The boundary every step, then a grid over the bounding box clipped to the polygon.
    const std::vector<Eigen::Vector2d>& vertices = polygon->vertices_B;
    Eigen::AlignedBox2d box_B;
    for (std::size_t k = 0; k < vertices.size(); ++k) {
      const Eigen::Vector2d& a = vertices[k];
      const Eigen::Vector2d& b = vertices[(k + 1) % vertices.size()];
      box_B.extend(a);
      const int pieces = std::max(1, static_cast<int>(std::ceil((b - a).norm() / step)));
      for (int i = 0; i < pieces; ++i) points_B.push_back(a + (b - a) * (static_cast<double>(i) / pieces));
    }
    const Eigen::Vector2d extent = box_B.sizes();
    const int nx = std::max(1, static_cast<int>(std::ceil(extent.x() / step)));
    const int ny = std::max(1, static_cast<int>(std::ceil(extent.y() / step)));
    for (int i = 1; i < nx; ++i) {
      for (int j = 1; j < ny; ++j) {
        const Eigen::Vector2d p_B = box_B.min() + Eigen::Vector2d(extent.x() * i / nx, extent.y() * j / ny);
        if (geometry::convex_polygon_contains(vertices, p_B)) points_B.push_back(p_B);
      }
    }
  } else {
    const double radius = std::get<geometry::CylinderFootprint>(footprint).radius;
    const int rings = std::max(1, static_cast<int>(std::ceil(radius / step)));
    points_B.emplace_back(0.0, 0.0);
    for (int k = 1; k <= rings; ++k) {
      const double rho = radius * k / rings;
      const int around = std::max(6, static_cast<int>(std::ceil(2 * M_PI * rho / step)));
      for (int a = 0; a < around; ++a) {
        const double angle = 2 * M_PI * a / around;
        points_B.emplace_back(rho * std::cos(angle), rho * std::sin(angle));
      }
    }
  }
  std::vector<Eigen::Vector2d> points_W;
  points_W.reserve(points_B.size());
  for (const auto& p_B : points_B) points_W.push_back(X_WB.transform(p_B));
  return points_W;
}

}  // namespace

PtemContact collide_ptem(const mapping::PtemSnapshot& ptem, const geometry::Footprint& footprint,
                         const geometry::Pose2& X_WB) {
  return collide_ptem(ptem, footprint, X_WB, geometry::bounding_radius(footprint));
}

PtemContact collide_ptem(const mapping::PtemSnapshot& ptem, const geometry::Footprint& footprint,
                         const geometry::Pose2& X_WB, double bounding_radius_m) {
  if (!ptem.restricted_threshold()) return {};
  const double threshold = *ptem.restricted_threshold() * (1.0 - 1e-9);  // covers rounding against PtemSnapshot::threat
  // Each PDF is largest on the footprint at the footprint's point nearest its mean, so the sum of those maxima bounds
  // the threat over the whole footprint. Far from clusters it stays below f_r, and the sampling below (hundreds of
  // points, each summing every PDF) is skipped: that is what makes a query away from obstacles cheap.
  // First a cheaper bound from the footprint's bounding circle (no point is nearer a mean than the circle is): when
  // no cluster's circle can reach into the footprint and even this bound stays below f_r, the answer is no.
  double circle_bound = 0.0;
  bool may_touch = false;
  for (const mapping::PtemCluster& cluster : ptem.clusters()) {
    const double gap_m = std::max(0.0, (cluster.centre_W - X_WB.position()).norm() - bounding_radius_m);
    if (gap_m <= cluster.radius_m) {
      may_touch = true;
      break;
    }
    circle_bound += mapping::ptem_term_density(gap_m * gap_m, cluster.sigma_m);
  }
  if (!may_touch && circle_bound < threshold) return {};
  const PlanarFrame frame(X_WB);
  double threat_bound = 0.0;
  for (const mapping::PtemCluster& cluster : ptem.clusters()) {
    const Eigen::Vector2d q_W = nearest_footprint_point(footprint, frame, cluster.centre_W);
    const double distance_sq = (q_W - cluster.centre_W).squaredNorm();
    if (std::sqrt(distance_sq) <= cluster.radius_m) return {true, q_W};
    threat_bound += mapping::ptem_term_density(distance_sq, cluster.sigma_m);
  }
  if (threat_bound < threshold) return {};
  for (const Eigen::Vector2d& p_W : footprint_samples(footprint, X_WB, kPtemSampleStep_m)) {
    if (ptem.restricted(p_W)) return {true, p_W};
  }
  return {};
}

namespace {

// Distance from the footprint at X_WB to the nearest cluster circle, no farther than max_distance_m; 0 inside one.
PtemClearance ptem_circle_clearance(const mapping::PtemSnapshot& ptem, const geometry::Footprint& footprint,
                                    const geometry::Pose2& X_WB, double max_distance_m) {
  PtemClearance out;
  out.clearance_m = max_distance_m;
  const PlanarFrame frame(X_WB);
  for (const mapping::PtemCluster& cluster : ptem.clusters()) {
    const Eigen::Vector2d q_W = nearest_footprint_point(footprint, frame, cluster.centre_W);
    const Eigen::Vector2d away = q_W - cluster.centre_W;
    const double d = std::max(0.0, away.norm() - cluster.radius_m);
    if (d <= out.clearance_m && (!out.found || d < out.clearance_m)) {
      out.found = true;
      out.clearance_m = d;
      out.nearest_point_W = cluster.centre_W + away.normalized() * cluster.radius_m;
    }
  }
  return out;
}

}  // namespace

PtemClearance ptem_clearance(const mapping::PtemSnapshot& ptem, const geometry::Footprint& footprint,
                             const geometry::Pose2& X_WB, double max_distance_m) {
  PtemClearance out;
  out.clearance_m = max_distance_m;
  if (!ptem.restricted_threshold()) return out;
  if (const PtemContact contact = collide_ptem(ptem, footprint, X_WB); contact.hit) {
    return {true, 0.0, contact.point_W};
  }
  return ptem_circle_clearance(ptem, footprint, X_WB, max_distance_m);
}

PtemContact collide_ptem_extent(const mapping::PtemSnapshot& ptem, const geometry::Footprint& footprint,
                                const geometry::Pose2& X_WB, double bounding_radius_m) {
  std::optional<PlanarFrame> frame;
  for (const mapping::PtemCluster& cluster : ptem.clusters()) {
    // The circle holds every return of the cluster: most clusters are far and need no body-frame arithmetic.
    if ((cluster.centre_W - X_WB.position()).norm() > bounding_radius_m + cluster.radius_m) continue;
    if (!frame) frame.emplace(X_WB);
    if ((nearest_footprint_point(footprint, *frame, cluster.centre_W) - cluster.centre_W).norm() > cluster.radius_m) {
      continue;
    }
    for (const Eigen::Vector2d& p_W : cluster.extent_W) {
      // Inside the closed footprint its nearest point is the point itself (up to the frame's rounding).
      if ((nearest_footprint_point(footprint, *frame, p_W) - p_W).squaredNorm() <= 1e-18) return {true, p_W};
    }
  }
  return {};
}

PtemClearance ptem_extent_clearance(const mapping::PtemSnapshot& ptem, const geometry::Footprint& footprint,
                                    const geometry::Pose2& X_WB, double max_distance_m) {
  PtemClearance out;
  out.clearance_m = max_distance_m;
  const PlanarFrame frame(X_WB);
  for (const mapping::PtemCluster& cluster : ptem.clusters()) {
    // The distance to the circle bounds the distance to any return inside it: skip clusters that cannot be nearer.
    const double circle_gap_m =
        (nearest_footprint_point(footprint, frame, cluster.centre_W) - cluster.centre_W).norm() - cluster.radius_m;
    if (circle_gap_m > out.clearance_m || (out.found && circle_gap_m >= out.clearance_m)) continue;
    for (const Eigen::Vector2d& p_W : cluster.extent_W) {
      const double d = (nearest_footprint_point(footprint, frame, p_W) - p_W).norm();
      if (d <= out.clearance_m && (!out.found || d < out.clearance_m)) {
        out.found = true;
        out.clearance_m = d <= 1e-9 ? 0.0 : d;
        out.nearest_point_W = p_W;
      }
    }
  }
  return out;
}

}  // namespace occgeo::service
