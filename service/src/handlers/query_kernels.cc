#include "query_kernels.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <variant>

#include "model_geometry.h"
#include "occgeo/geometry/convex_polygon.h"
#include "occgeo/geometry/grid_ray.h"
#include "occgeo/geometry/kinematics.h"

namespace occgeo::service {

namespace {

void set_cell(const geometry::CellIndex& cell, v1::CellIndex& out) {
  out.set_ix(cell.ix);
  out.set_iy(cell.iy);
}

void set_vector(const Eigen::Vector3d& v, v1::Vector3& out) {
  out.set_x(v.x());
  out.set_y(v.y());
  out.set_z(v.z());
}

void set_point(const Eigen::Vector2d& p, v1::Point2D& out) {
  out.set_x(p.x());
  out.set_y(p.y());
}

bool contains_origin(const geometry::Footprint& footprint) {
  if (const auto* box = std::get_if<geometry::BoxFootprint>(&footprint)) {
    return std::abs(box->center_x) <= box->length / 2;
  }
  if (const auto* polygon = std::get_if<geometry::ConvexPolygonFootprint>(&footprint)) {
    return geometry::convex_polygon_contains(polygon->vertices_B, Eigen::Vector2d::Zero());
  }
  return true;
}

bool inside(const mapping::CellBox& box, const geometry::CellIndex& min, const geometry::CellIndex& max) {
  return min.ix >= box.min.ix && min.iy >= box.min.iy && max.ix <= box.max.ix && max.iy <= box.max.iy;
}

// One model's clearance: found, value, nearest obstacle point.
struct ModelClearance {
  bool found = false;
  double clearance_m = 0.0;
  Eigen::Vector2d point_W = Eigen::Vector2d::Zero();
  std::optional<geometry::CellIndex> cell;
};

ModelClearance model_clearance(const WorldSnapshot& snapshot, v1::Model model,
                               const geometry::ClearanceRequest& request) {
  if (model == v1::MODEL_GRID) {
    // The distance field answers (within one cell of exact, falling back to the exact search itself when the query
    // reaches beyond the field).
    const geometry::ClearanceResult r = snapshot.distance->compute_clearance(request);
    return {r.found, r.clearance_m, r.nearest_point_W, r.nearest_cell};
  }
  if (model == v1::MODEL_OCTOMAP) {
    const double top_m = geometry::footprint_height(request.footprint);
    if (const OctreeBandSnapshot* band = find_octree_band(snapshot.octree_bands.get(), top_m)) {
      // The band's field: within one voxel of the walk below (exactly it where the query reaches beyond the field).
      const geometry::ClearanceResult r = band->field->compute_clearance(request);
      return {r.found, r.clearance_m, r.nearest_point_W, r.nearest_cell};
    }
    // No field for this height yet: ask the octree's lane for one (made at its next publish) and walk meanwhile.
    if (snapshot.octree_band_requests) snapshot.octree_band_requests->want(top_m);
    const OctoMapColumns columns(*snapshot.octomap, top_m);
    const geometry::ClearanceResult r = geometry::compute_clearance(request, columns);
    return {r.found, r.clearance_m, r.nearest_point_W, r.nearest_cell};
  }
  const PtemClearance r =
      ptem_extent_clearance(*snapshot.ptem, request.footprint, request.pose, request.max_distance_m);
  return {r.found, r.clearance_m, r.nearest_point_W, std::nullopt};
}

}  // namespace

geometry::CollisionResult grid_collision(const mapping::GridSnapshot& grid, const mapping::DistanceFieldSnapshot* field,
                                         const geometry::Footprint& footprint, double bounding_radius_m,
                                         const geometry::Pose2& X_WB) {
  const double cell = grid.cell_size();
  if (field != nullptr && field->version() == grid.version() && std::isfinite(X_WB.x) && std::isfinite(X_WB.y) &&
      std::abs(X_WB.x) < 1e8 * cell && std::abs(X_WB.y) < 1e8 * cell) {
    if (const auto bounds = field->bounds()) {
      const geometry::CellIndex base = geometry::GridGeometry(cell).cell_of(X_WB.position());
      if (base.ix >= bounds->min.ix && base.ix <= bounds->max.ix && base.iy >= bounds->min.iy &&
          base.iy <= bounds->max.iy) {
        const double d = field->distance(base);
        if (d == 0.0 && contains_origin(footprint)) {
          // base_link is a point of both the footprint and this occupied cell.
          return {true, base, 0};
        }
        // Every footprint point lies within bounding_radius of base_link, hence within bounding_radius + half a
        // cell diagonal of the base cell's centre; a cell of margin covers the field's rounding. Occupied cells
        // nearer than d would lie inside the field's bounds, so d is only trusted when that disc is.
        const double reach = bounding_radius_m + cell * (M_SQRT1_2 + 1.0);
        const auto span = static_cast<std::int32_t>(std::ceil(d / cell)) + 1;
        if (d > reach && inside(*bounds, {base.ix - span, base.iy - span}, {base.ix + span, base.iy + span})) {
          return {};
        }
      }
    }
  }
  return geometry::check_collision({footprint, X_WB}, grid);
}

void answer_collision(const WorldSnapshot& snapshot, const geometry::Footprint& footprint, double bounding_radius_m,
                      const geometry::Pose2& X_WB, std::span<const v1::Model> models, v1::CollisionReply& out) {
  if (std::find(models.begin(), models.end(), v1::MODEL_PTEM) != models.end()) {
    if (const PtemContact keep_out = collide_ptem(*snapshot.ptem, footprint, X_WB, bounding_radius_m); keep_out.hit) {
      out.set_keep_out(true);
      set_vector(Eigen::Vector3d(keep_out.point_W.x(), keep_out.point_W.y(), 0.0), *out.mutable_keep_out_point());
    }
  }
  for (const v1::Model model : models) {
    if (model == v1::MODEL_GRID) {
      const geometry::CollisionResult result =
          grid_collision(*snapshot.grid, snapshot.distance.get(), footprint, bounding_radius_m, X_WB);
      out.set_cells_tested(static_cast<std::uint32_t>(result.cells_tested));
      if (!result.hit) continue;
      out.set_hit(true);
      if (result.cell) {
        set_cell(*result.cell, *out.mutable_cell());
        const Eigen::Vector2d center = geometry::GridGeometry(snapshot.grid->cell_size()).center_of(*result.cell);
        set_point(center, *out.mutable_cell_center());
        set_vector(Eigen::Vector3d(center.x(), center.y(), 0.0), *out.mutable_contact());
      }
    } else if (model == v1::MODEL_OCTOMAP) {
      const mapping::OctoCollision result = collide_octomap(*snapshot.octomap, footprint, X_WB);
      if (!result.hit) continue;
      out.set_hit(true);
      set_vector(result.contact_W, *out.mutable_contact());
    } else {
      const PtemContact result = collide_ptem_extent(*snapshot.ptem, footprint, X_WB, bounding_radius_m);
      if (!result.hit) continue;
      out.set_hit(true);
      set_vector(Eigen::Vector3d(result.point_W.x(), result.point_W.y(), 0.0), *out.mutable_contact());
    }
    out.set_model(model);
    break;
  }
}

void answer_clearance(const WorldSnapshot& snapshot, const geometry::Footprint& footprint, const geometry::Pose2& X_WB,
                      double max_distance_m, std::span<const v1::Model> models, v1::ClearanceReply& out) {
  geometry::ClearanceRequest request{footprint, X_WB, max_distance_m};
  out.set_clearance_m(max_distance_m);
  if (std::find(models.begin(), models.end(), v1::MODEL_PTEM) != models.end()) {
    const PtemClearance restricted = ptem_clearance(*snapshot.ptem, footprint, X_WB, max_distance_m);
    out.set_restricted_clearance_m(restricted.clearance_m);
    out.set_keep_out(restricted.found && restricted.clearance_m <= 0.0);
  }
  Eigen::Vector2d best_point_W = Eigen::Vector2d::Zero();
  // Keeps the nearest answer over the models; ties go to the model asked first. A later model is asked only within
  // the answer so far: an obstacle of its own beyond that cannot change the reply, and its field then settles most of
  // the footprint's edge from the per-line distances alone. Its guarantee holds within that distance as within any
  // (never below its exact clearance, at most a cell above), so when it finds nothing nearer its exact clearance is
  // at least the answer so far less its cell, and the reply stays within a cell of the nearest obstacle of any model.
  for (const v1::Model model : models) {
    if (out.found()) {
      if (out.clearance_m() <= 0.0) break;  // contact: nothing is nearer, and ties go to the model asked first
      request.max_distance_m = out.clearance_m();
    }
    const ModelClearance r = model_clearance(snapshot, model, request);
    if (!r.found || (out.found() && r.clearance_m >= out.clearance_m())) continue;
    out.set_found(true);
    out.set_clearance_m(r.clearance_m);
    out.set_model(model);
    set_point(r.point_W, *out.mutable_nearest_point());
    best_point_W = r.point_W;
    if (r.cell) {
      set_cell(*r.cell, *out.mutable_nearest_cell());
    } else {
      out.clear_nearest_cell();
    }
  }
  if (!out.found()) return;
  // Translating the footprint away from the nearest obstacle point, along the line joining it to the footprint's
  // nearest point, increases the distance at unit rate: the steepest ascent.
  const Eigen::Vector2d from = out.clearance_m() > 0.0 ? nearest_footprint_point(footprint, X_WB, best_point_W)
                                                       : footprint_center(footprint, X_WB);
  const Eigen::Vector2d away = from - best_point_W;
  const double norm = away.norm();
  if (norm > 1e-12) {
    out.mutable_gradient()->set_x(away.x() / norm);
    out.mutable_gradient()->set_y(away.y() / norm);
  }
}

double ray_cell_entry(const Eigen::Vector2d& origin_W, const Eigen::Vector2d& direction_W, double cell_size,
                      const geometry::CellIndex& cell) {
  double t_enter = 0.0;
  double t_exit = std::numeric_limits<double>::infinity();
  const double lo[2] = {cell.ix * cell_size, cell.iy * cell_size};
  for (int axis = 0; axis < 2; ++axis) {
    const double o = origin_W[axis];
    const double d = direction_W[axis];
    const double a = lo[axis];
    const double b = lo[axis] + cell_size;
    if (d == 0.0) {
      if (o < a || o > b) return -1.0;
      continue;
    }
    double t0 = (a - o) / d;
    double t1 = (b - o) / d;
    if (t0 > t1) std::swap(t0, t1);
    t_enter = std::max(t_enter, t0);
    t_exit = std::min(t_exit, t1);
  }
  return t_enter <= t_exit ? t_enter : -1.0;
}

void answer_raycast(const WorldSnapshot& snapshot, const geometry::Pose2& ray_W, double max_range_m, double height_m,
                    std::span<const v1::Model> models, v1::RaycastResult& out) {
  const Eigen::Vector2d origin_W = ray_W.position();
  const Eigen::Vector2d direction_W(std::cos(ray_W.theta), std::sin(ray_W.theta));
  out.set_range_m(max_range_m);
  for (const v1::Model model : models) {
    v1::RaycastHit* hit = out.add_per_model();
    hit->set_model(model);
    hit->set_range_m(max_range_m);
    if (model == v1::MODEL_GRID) {
      const mapping::GridSnapshot& grid = *snapshot.grid;
      const geometry::GridGeometry geometry(grid.cell_size());
      geometry::GridRayTraversal traversal(geometry, origin_W, origin_W + max_range_m * direction_W);
      while (true) {
        const geometry::CellIndex cell = traversal.cell();
        if (grid.occupied(cell)) {
          const double range =
              std::clamp(ray_cell_entry(origin_W, direction_W, grid.cell_size(), cell), 0.0, max_range_m);
          hit->set_hit(true);
          hit->set_range_m(range);
          set_point(origin_W + range * direction_W, *hit->mutable_point());
          set_cell(cell, *hit->mutable_cell());
          break;
        }
        if (traversal.done()) break;
        traversal.advance();
      }
    } else if (model == v1::MODEL_OCTOMAP) {
      const Eigen::Vector3d origin3(origin_W.x(), origin_W.y(), height_m);
      const Eigen::Vector3d direction3(direction_W.x(), direction_W.y(), 0.0);
      if (const auto r = snapshot.octomap->cast_ray(origin3, direction3, max_range_m)) {
        const Eigen::Vector2d center = r->voxel_center_W.head<2>();
        const double range = std::clamp((center - origin_W).dot(direction_W), 0.0, max_range_m);
        hit->set_hit(true);
        hit->set_range_m(range);
        set_point(origin_W + range * direction_W, *hit->mutable_point());
      }
    } else {
      const mapping::PtemSnapshot& ptem = *snapshot.ptem;
      if (ptem.restricted_threshold() && !ptem.clusters().empty()) {
        const auto steps = static_cast<std::int64_t>(std::ceil(max_range_m / kPtemRayStep_m));
        for (std::int64_t k = 0; k <= steps; ++k) {
          const double range = std::min(max_range_m, static_cast<double>(k) * kPtemRayStep_m);
          const Eigen::Vector2d p_W = origin_W + range * direction_W;
          if (!ptem.restricted(p_W)) continue;
          hit->set_hit(true);
          hit->set_range_m(range);
          set_point(p_W, *hit->mutable_point());
          break;
        }
      }
    }
    if (hit->hit() && (!out.hit() || hit->range_m() < out.range_m())) {
      out.set_hit(true);
      out.set_range_m(hit->range_m());
      out.set_model(model);
    }
  }
}

void answer_occupancy(const WorldSnapshot& snapshot, const Eigen::Vector3d& p_W, std::span<const v1::Model> models,
                      v1::OccupancySample& out) {
  for (const v1::Model model : models) {
    if (model == v1::MODEL_GRID) {
      const mapping::GridSnapshot& grid = *snapshot.grid;
      const geometry::CellIndex cell = geometry::GridGeometry(grid.cell_size()).cell_of(p_W.head<2>());
      set_cell(cell, *out.mutable_cell());
      out.set_observed(grid.observed(cell));
      out.set_certainty(grid.certainty(cell));
      out.set_occupied(grid.occupied(cell));
    } else if (model == v1::MODEL_OCTOMAP) {
      if (const auto probability = snapshot.octomap->occupancy(p_W)) {
        out.set_octree_known(true);
        out.set_octree_probability(*probability);
        out.set_octree_occupied(snapshot.octomap->occupied(p_W));
      }
    } else {
      out.set_threat(snapshot.ptem->threat(p_W.head<2>()));
      out.set_restricted(snapshot.ptem->restricted(p_W.head<2>()));
    }
  }
}

namespace {

// A motion as a function of a parameter tau in [0, tau_end]: constant (v, ω) (tau in seconds) or a path (tau = pose
// index + fraction along the segment).
class Motion {
 public:
  Motion(const v1::SweptMotion& motion, double bounding_radius_m) : motion_(motion), radius_(bounding_radius_m) {}

  [[nodiscard]] bool is_path() const { return !motion_.path().empty(); }
  [[nodiscard]] double end() const {
    return is_path() ? static_cast<double>(motion_.path_size() - 1) : motion_.duration_s();
  }
  [[nodiscard]] double seconds_per_tau() const {
    if (!is_path()) return 1.0;
    return motion_.path_dt_s() > 0.0 ? motion_.path_dt_s() : 1.0;
  }

  [[nodiscard]] geometry::Pose2 pose_at(double tau) const {
    if (!is_path()) {
      const v1::Pose2D& s = motion_.start();
      return geometry::integrate({s.x(), s.y(), s.theta()}, {motion_.linear_mps(), motion_.angular_radps()}, tau);
    }
    const auto [k, s] = segment_of(tau);
    const v1::Pose2D& a = motion_.path(k);
    if (s == 0.0) return {a.x(), a.y(), a.theta()};
    const v1::Pose2D& b = motion_.path(k + 1);
    return {a.x() + s * (b.x() - a.x()), a.y() + s * (b.y() - a.y()),
            a.theta() + s * geometry::wrap_angle(b.theta() - a.theta())};
  }

  // An upper bound on how fast any point of the footprint moves per unit of tau at tau (constant over a path
  // segment), metres; 0 when the footprint stands still.
  [[nodiscard]] double rate_at(double tau) const {
    if (!is_path()) return std::abs(motion_.linear_mps()) + std::abs(motion_.angular_radps()) * radius_;
    const auto [k, s] = segment_of(tau);
    if (k + 1 >= motion_.path_size()) return 0.0;
    const v1::Pose2D& a = motion_.path(k);
    const v1::Pose2D& b = motion_.path(k + 1);
    return std::hypot(b.x() - a.x(), b.y() - a.y()) + std::abs(geometry::wrap_angle(b.theta() - a.theta())) * radius_;
  }

  // Where the segment holding tau ends (tau_end for a (v, ω) motion).
  [[nodiscard]] double segment_end(double tau) const {
    if (!is_path()) return end();
    return std::min(end(), std::floor(tau) + 1.0);
  }

 private:
  [[nodiscard]] std::pair<int, double> segment_of(double tau) const {
    const int last = motion_.path_size() - 1;
    const double clamped = std::clamp(tau, 0.0, static_cast<double>(last));
    int k = static_cast<int>(std::floor(clamped));
    if (k >= last) return {last, 0.0};
    return {k, clamped - k};
  }

  const v1::SweptMotion& motion_;
  double radius_;
};

// The smallest clearance over the models, searching no farther than max_distance_m; exact for GRID below
// kSweptContact_m + one cell (the distance field's bound is used above that, lowered by a cell so it never exceeds
// the exact clearance).
struct SweptClearance {
  double clearance_m;
  v1::Model model = v1::MODEL_UNSPECIFIED;
  Eigen::Vector2d point_W = Eigen::Vector2d::Zero();
};

SweptClearance swept_clearance(const WorldSnapshot& snapshot, const geometry::Footprint& footprint,
                               std::span<const v1::Model> models, const geometry::Pose2& X_WB, double max_distance_m) {
  // clearance_m is the smallest lower bound over the models; model and point name the obstacle when that bound is a
  // measured distance (a contact is only ever reported from one).
  SweptClearance best{max_distance_m};
  const auto offer = [&](double lower_bound_m, std::optional<std::pair<v1::Model, Eigen::Vector2d>> obstacle) {
    if (lower_bound_m >= best.clearance_m) return;
    best.clearance_m = lower_bound_m;
    best.model = obstacle ? obstacle->first : v1::MODEL_UNSPECIFIED;
    if (obstacle) best.point_W = obstacle->second;
  };
  for (const v1::Model model : models) {
    geometry::ClearanceRequest request{footprint, X_WB, max_distance_m};
    if (model == v1::MODEL_GRID) {
      // The field's clearance is never below the exact one and at most a cell above it (also when it finds nothing
      // within max_distance_m), so one cell less is a lower bound; near contact the exact search decides.
      const double cell = snapshot.grid->cell_size();
      const geometry::ClearanceResult upper = snapshot.distance->compute_clearance(request);
      const double lower = (upper.found ? upper.clearance_m : max_distance_m) - cell;
      if (lower > kSweptContact_m) {
        offer(lower, std::nullopt);
        continue;
      }
      const geometry::ClearanceResult exact = geometry::compute_clearance(request, *snapshot.grid);
      if (exact.found) offer(exact.clearance_m, std::pair{model, exact.nearest_point_W});
      continue;
    }
    if (model == v1::MODEL_OCTOMAP) {
      // As for the grid: the band's field gives an upper bound at most a voxel above the walk's answer.
      const double top_m = geometry::footprint_height(footprint);
      if (const OctreeBandSnapshot* band = find_octree_band(snapshot.octree_bands.get(), top_m)) {
        const geometry::ClearanceResult upper = band->field->compute_clearance(request);
        const double lower = (upper.found ? upper.clearance_m : max_distance_m) - snapshot.octomap->resolution();
        if (lower > kSweptContact_m) {
          offer(lower, std::nullopt);
          continue;
        }
        const OctoMapColumns columns(*snapshot.octomap, top_m);
        const geometry::ClearanceResult exact = geometry::compute_clearance(request, columns);
        if (exact.found) offer(exact.clearance_m, std::pair{model, exact.nearest_point_W});
        continue;
      }
    }
    const ModelClearance r = model_clearance(snapshot, model, request);
    if (r.found) offer(r.clearance_m, std::pair{model, r.point_W});
  }
  return best;
}

}  // namespace

void answer_swept(const WorldSnapshot& snapshot, const geometry::Footprint& footprint,
                  std::span<const v1::Model> models, const v1::SweptMotion& motion, v1::SweptResult& out) {
  const Motion path(motion, geometry::bounding_radius(footprint));
  const double end = path.end();
  // Conservative advancement: no point of the footprint moves farther than the clearance before the next check, so
  // no contact is stepped over.
  constexpr int kMaxSteps = 1000000;
  double tau = 0.0;
  geometry::Pose2 pose = path.pose_at(0.0);
  for (int step = 0; step < kMaxSteps; ++step) {
    pose = path.pose_at(tau);
    const double rate = path.rate_at(tau);
    const double segment_end = path.segment_end(tau);
    const double reach = std::clamp(rate * (segment_end - tau) + kSweptContact_m, 2 * kSweptContact_m, 2.0);
    const SweptClearance c = swept_clearance(snapshot, footprint, models, pose, reach);
    if (c.model != v1::MODEL_UNSPECIFIED && c.clearance_m <= kSweptContact_m) {
      out.set_hit(true);
      out.set_model(c.model);
      set_point(c.point_W, *out.mutable_contact());
      break;
    }
    if (tau >= end) break;
    if (rate <= 0.0 || tau >= segment_end) {
      tau = segment_end > tau ? segment_end : std::min(end, std::floor(tau) + 1.0);
      continue;
    }
    tau = std::min(segment_end, tau + c.clearance_m / rate);
  }
  out.set_time_s(tau * path.seconds_per_tau());
  out.mutable_pose()->set_x(pose.x);
  out.mutable_pose()->set_y(pose.y);
  out.mutable_pose()->set_theta(pose.theta);
}

}  // namespace occgeo::service
