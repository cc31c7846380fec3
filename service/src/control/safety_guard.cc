#include "occgeo/service/control/safety_guard.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "model_geometry.h"
#include "occgeo/geometry/checks.h"

namespace occgeo::service::control {

namespace {

// The terrain around the swept footprint reaches this much farther, so the cells it reads have their neighbours.
constexpr double kTerrainMargin_m = 0.3;

// The cell size of the guard's 2D obstacles: the grid's, or without one the terrain's (twice the octree's resolution).
double cell_size(const GuardModels& models) {
  if (models.grid != nullptr) return models.grid->cell_size();
  return models.octomap != nullptr ? 2.0 * models.octomap->resolution() : 0.1;
}

// The recent returns of the tracked moving clusters, the only returns the guard checks besides the models (none when
// the check is off or nothing moves). Made once per guard call: a swept motion checks them at up to 400 poses.
class MovingReturns {
 public:
  MovingReturns(const GuardModels& models, const GuardParams& params) {
    if (!params.check_scan_returns || models.scan_returns == nullptr || models.moving_tracks.empty()) return;
    discs_.reserve(models.moving_tracks.size());
    for (const TrackedObstacle& track : models.moving_tracks) discs_.push_back({track.centre_W, track.radius_m});
    cells_.emplace(*models.scan_returns, params.scan_returns_max_age_s, cell_size(models), discs_);
  }
  MovingReturns(const MovingReturns&) = delete;  // the cells read discs_ in place
  MovingReturns& operator=(const MovingReturns&) = delete;
  [[nodiscard]] const RecentReturnCells* cells() const { return cells_ ? &*cells_ : nullptr; }

 private:
  std::vector<GroundDisc> discs_;
  std::optional<RecentReturnCells> cells_;
};

// The terrain the guard reads within reach_m of base_link (world frame), when there is an octree to estimate it
// from: the surfaces the robot can drive on, where neither the grid's returns nor the octree's voxels of the surface
// are obstacles (the robot climbing a ramp its laser reads as a wall).
std::optional<mapping::TerrainMap> terrain_near(const GuardModels& models, const geometry::Footprint& footprint,
                                                const geometry::Pose2& X_WB, const GuardParams& params,
                                                double reach_m) {
  if (models.octomap == nullptr || !(params.check_grid || params.check_octomap || params.check_scan_returns) ||
      !models.octomap->terrain().enabled) {
    return std::nullopt;
  }
  const double cell_m = cell_size(models);
  const Eigen::Vector2d position_W = X_WB.position();
  const Eigen::Vector2d reach(reach_m, reach_m);
  return terrain_around(*models.octomap, cell_m, position_W - reach, position_W + reach,
                        geometry::footprint_height(footprint), position_W);
}

// model_in_contact with the terrain's exceptions (none when terrain is null).
std::string_view contact_on_terrain(const GuardModels& models, const mapping::TerrainMap* terrain,
                                    const RecentReturnCells* moving_returns, const geometry::Footprint& footprint,
                                    const geometry::Pose2& X_WB, const GuardParams& params) {
  if (params.check_grid && models.grid != nullptr) {
    const bool hit = terrain != nullptr
                         ? geometry::check_collision({footprint, X_WB}, TerrainMaskedCells(*models.grid, *terrain)).hit
                         : geometry::check_collision({footprint, X_WB}, *models.grid).hit;
    if (hit) return "grid";
  }
  if (params.check_ptem && models.ptem != nullptr && collide_ptem(*models.ptem, footprint, X_WB).hit) return "ptem";
  if (moving_returns != nullptr) {
    // Returns on a drivable surface (the laser plane meeting a ramp) are the terrain's, as for the grid.
    const bool hit =
        terrain != nullptr
            ? geometry::check_collision({footprint, X_WB}, TerrainMaskedCells(*moving_returns, *terrain)).hit
            : geometry::check_collision({footprint, X_WB}, *moving_returns).hit;
    if (hit) return "scan_returns";
  }
  if (params.check_octomap && models.octomap != nullptr) {
    // With a terrain the band follows the surface, which FCL's straight prism cannot: the same voxels as columns.
    const bool hit =
        terrain != nullptr
            ? geometry::check_collision({footprint, X_WB},
                                        OctoMapColumns(*models.octomap, geometry::footprint_height(footprint), terrain))
                  .hit
            : collide_octomap(*models.octomap, footprint, X_WB).hit;
    if (hit) return "octomap";
  }
  return "";
}

// Calls visit(source, model) for each consulted model that the guard reads as cells on the ground: the grid and the
// tracked walkers' recent returns, less what the terrain explains when there is one, and the octree's voxels in the
// footprint's height band as columns (OctoMapColumns applies the terrain itself).
template <typename Visit>
void for_each_cell_model(const GuardModels& models, const mapping::TerrainMap* terrain,
                         const RecentReturnCells* moving_returns, const geometry::Footprint& footprint,
                         const GuardParams& params, Visit&& visit) {
  const auto on_terrain = [&](const geometry::OccupiedCellSource& cells, std::string_view model) {
    if (terrain != nullptr) {
      visit(TerrainMaskedCells(cells, *terrain), model);
    } else {
      visit(cells, model);
    }
  };
  if (params.check_grid && models.grid != nullptr) on_terrain(*models.grid, "grid");
  if (params.check_octomap && models.octomap != nullptr) {
    visit(OctoMapColumns(*models.octomap, geometry::footprint_height(footprint), terrain), "octomap");
  }
  if (moving_returns != nullptr) on_terrain(*moving_returns, "scan_returns");
}

// Smallest distance from the footprint at X_WB to any consulted model's obstacle, looking no farther than
// max_distance_m; returns max_distance_m and model "" when nothing is that close.
std::pair<double, std::string_view> nearest_obstacle(const GuardModels& models, const mapping::TerrainMap* terrain,
                                                     const RecentReturnCells* moving_returns,
                                                     const geometry::Footprint& footprint, const geometry::Pose2& X_WB,
                                                     const GuardParams& params, double max_distance_m) {
  double best = max_distance_m;
  std::string_view model;
  const auto keep_nearer = [&](double clearance_m, bool found, std::string_view from) {
    if (found && clearance_m < best) {
      best = clearance_m;
      model = from;
    }
  };
  for_each_cell_model(models, terrain, moving_returns, footprint, params,
                      [&](const geometry::OccupiedCellSource& cells, std::string_view from) {
                        const auto clearance = geometry::compute_clearance({footprint, X_WB, max_distance_m}, cells);
                        keep_nearer(clearance.clearance_m, clearance.found, from);
                      });
  if (params.check_ptem && models.ptem != nullptr) {
    const auto clearance = ptem_clearance(*models.ptem, footprint, X_WB, max_distance_m);
    keep_nearer(clearance.clearance_m, clearance.found, "ptem");
  }
  return {best, model};
}

// An obstacle cell near the footprint: its centre (world frame) and side, metres.
struct ObstacleCell {
  Eigen::Vector2d centre_W;
  double side_m;
};

// The obstacle cells of the consulted cell models (for_each_cell_model, each of its own cell size) within reach_m of
// base_link at X_WB on both axes.
std::vector<ObstacleCell> obstacle_cells_near(const GuardModels& models, const mapping::TerrainMap* terrain,
                                              const RecentReturnCells* moving_returns,
                                              const geometry::Footprint& footprint, const geometry::Pose2& X_WB,
                                              const GuardParams& params, double reach_m) {
  std::vector<ObstacleCell> near;
  for_each_cell_model(models, terrain, moving_returns, footprint, params,
                      [&](const geometry::OccupiedCellSource& source, std::string_view /*model*/) {
                        const geometry::GridGeometry cells(source.cell_size());
                        const geometry::CellIndex min = cells.cell_of({X_WB.x - reach_m, X_WB.y - reach_m});
                        const geometry::CellIndex max = cells.cell_of({X_WB.x + reach_m, X_WB.y + reach_m});
                        source.for_each_occupied(min, max, [&](const geometry::CellIndex& c) {
                          near.push_back({cells.center_of(c), cells.cell_size()});
                          return true;
                        });
                      });
  return near;
}

// Whether a motion of a footprint that touches an obstacle cell brings it, within the first stop_distance_m of its
// sweep (1 cm steps), nearer than half a cell to the centre of an obstacle cell and nearer than it is now. Cells are
// 10 cm (the octree's columns 5 cm) and a wall's face may lie anywhere in its cells, so touching a cell is not yet
// touching the wall, and the robot gets out of such contact by moving; but a corner swinging towards the centre of a
// wall cell runs into the wall. Backing along a wall keeps the gap to the centres of the cells it touches (half a
// cell); a cell whose centre is inside the footprint tells nothing about deeper or shallower and is left out.
bool deepens_contact(const GuardModels& models, const mapping::TerrainMap* terrain,
                     const RecentReturnCells* moving_returns, const geometry::Footprint& footprint,
                     const geometry::Pose2& X_WB, double linear_mps, double angular_radps, const GuardParams& params) {
  constexpr double kTolerance_m = 0.002;
  constexpr double kStep_m = 0.01;
  const double reach_m = geometry::bounding_radius(footprint);
  const double sweep_rate_mps = std::abs(linear_mps) + reach_m * std::abs(angular_radps);
  if (sweep_rate_mps <= 0.0) return false;
  const double look_m = std::max(params.stop_distance_m, cell_size(models) / 2.0);
  // The cells whose centres lie outside the footprint but within reach of the motion, with their gaps now.
  struct NearCell {
    Eigen::Vector2d centre_W;
    double near_m;  // nearer than this is too near
    double gap_now_m;
  };
  std::vector<NearCell> near_cells;
  // A centre within look_m + half a cell of the footprint lies within this of base_link (the grid's cells are the
  // largest).
  const double cells_reach_m = reach_m + look_m + cell_size(models) / 2.0;
  for (const ObstacleCell& cell :
       obstacle_cells_near(models, terrain, moving_returns, footprint, X_WB, params, cells_reach_m)) {
    const double gap_m = distance_to_footprint(footprint, X_WB, cell.centre_W);
    const double near_m = 0.5 * cell.side_m - kTolerance_m;
    if (gap_m > 0.0 && gap_m <= look_m + near_m) near_cells.push_back({cell.centre_W, near_m, gap_m});
  }
  if (near_cells.empty()) return false;
  const int steps = std::clamp(static_cast<int>(std::ceil(look_m / kStep_m)), 1, 50);
  for (int k = 1; k <= steps; ++k) {
    const geometry::Pose2 X_WB_t = advance_pose(X_WB, linear_mps, angular_radps, look_m / sweep_rate_mps * k / steps);
    for (const NearCell& cell : near_cells) {
      const double gap_m = distance_to_footprint(footprint, X_WB_t, cell.centre_W);
      if (gap_m < cell.near_m && gap_m < cell.gap_now_m - kTolerance_m) return true;
    }
  }
  return false;
}

GuardDecision limited(GuardDecision decision, const GuardParams& params) {
  const double linear_scale = std::abs(decision.linear_mps) > params.limit_linear_mps
                                  ? params.limit_linear_mps / std::abs(decision.linear_mps)
                                  : 1.0;
  const double angular_scale = std::abs(decision.angular_radps) > params.limit_angular_radps
                                   ? params.limit_angular_radps / std::abs(decision.angular_radps)
                                   : 1.0;
  // One scale for both keeps the path's curvature: the robot still goes where the behaviour meant, slower.
  const double scale = std::min(linear_scale, angular_scale);
  if (scale < 1.0) {
    decision.linear_mps *= scale;
    decision.angular_radps *= scale;
    decision.action = GuardAction::kLimit;
  }
  return decision;
}

// Time step of the moving-obstacle prediction, seconds: a person at 0.7 m/s moves 7 cm per step.
constexpr double kPredictStep_s = 0.1;
// A motion whose smallest predicted gap to a moving obstacle is this much below standing still's closes in on it.
constexpr double kCloserThanStanding_m = 0.02;

// Distance from q (in the polygon's frame) to the convex, counter-clockwise polygon; 0 inside.
double distance_to_polygon(const std::vector<Eigen::Vector2d>& vertices, const Eigen::Vector2d& q) {
  bool inside = vertices.size() >= 3;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const Eigen::Vector2d& a = vertices[i];
    const Eigen::Vector2d& b = vertices[(i + 1) % vertices.size()];
    const Eigen::Vector2d ab = b - a;
    const Eigen::Vector2d aq = q - a;
    if (ab.x() * aq.y() - ab.y() * aq.x() < 0.0) inside = false;
    const double length_sq = ab.squaredNorm();
    const double s = length_sq > 0.0 ? std::clamp(aq.dot(ab) / length_sq, 0.0, 1.0) : 0.0;
    best = std::min(best, (aq - s * ab).norm());
  }
  return inside ? 0.0 : best;
}

}  // namespace

geometry::Pose2 advance_pose(const geometry::Pose2& X_WB, double linear_mps, double angular_radps, double t) {
  const double turned = angular_radps * t;
  if (std::abs(turned) < 1e-9) {
    return {X_WB.x + linear_mps * t * std::cos(X_WB.theta), X_WB.y + linear_mps * t * std::sin(X_WB.theta), X_WB.theta};
  }
  const double radius = linear_mps / angular_radps;
  const double theta = X_WB.theta + turned;
  return {X_WB.x + radius * (std::sin(theta) - std::sin(X_WB.theta)),
          X_WB.y - radius * (std::cos(theta) - std::cos(X_WB.theta)), geometry::wrap_angle(theta)};
}

double distance_to_footprint(const geometry::Footprint& footprint, const geometry::Pose2& X_WB,
                             const Eigen::Vector2d& p_W) {
  const double c = std::cos(X_WB.theta);
  const double s = std::sin(X_WB.theta);
  const Eigen::Vector2d d = p_W - X_WB.position();
  const Eigen::Vector2d q(c * d.x() + s * d.y(), -s * d.x() + c * d.y());  // p in base_link
  return std::visit(
      [&](const auto& shape) -> double {
        using Shape = std::decay_t<decltype(shape)>;
        if constexpr (std::is_same_v<Shape, geometry::BoxFootprint>) {
          const double dx = std::max(std::abs(q.x() - shape.center_x) - shape.length / 2.0, 0.0);
          const double dy = std::max(std::abs(q.y()) - shape.width / 2.0, 0.0);
          return std::hypot(dx, dy);
        } else if constexpr (std::is_same_v<Shape, geometry::CylinderFootprint>) {
          return std::max(q.norm() - shape.radius, 0.0);
        } else {
          return distance_to_polygon(shape.vertices_B, q);
        }
      },
      footprint);
}

double predicted_gap(std::span<const TrackedObstacle> moving, const geometry::Footprint& footprint,
                     const geometry::Pose2& X_WB, double linear_mps, double angular_radps, double drive_s,
                     double horizon_s, double* at_s) {
  double best = std::numeric_limits<double>::infinity();
  if (at_s != nullptr) *at_s = 0.0;
  if (moving.empty()) return best;
  const int steps = std::max(1, static_cast<int>(std::ceil(horizon_s / kPredictStep_s)));
  for (int k = 0; k <= steps; ++k) {
    const double t = horizon_s * k / steps;
    const geometry::Pose2 pose = advance_pose(X_WB, linear_mps, angular_radps, std::min(t, drive_s));
    for (const TrackedObstacle& obstacle : moving) {
      const double gap = distance_to_footprint(footprint, pose, obstacle.predicted_W(t)) - obstacle.radius_m;
      if (gap < best) {
        best = gap;
        if (at_s != nullptr) *at_s = t;
      }
    }
  }
  return best;
}

std::optional<double> predicted_contact_s(std::span<const TrackedObstacle> moving, const geometry::Footprint& footprint,
                                          const geometry::Pose2& X_WB, double linear_mps, double angular_radps,
                                          double horizon_s, double margin_m) {
  // A horizon of 0 still looks at now: "already within the margin" is contact at 0 s.
  if (moving.empty() || !(horizon_s >= 0.0)) return std::nullopt;
  const int steps = std::max(1, static_cast<int>(std::ceil(horizon_s / kPredictStep_s)));
  for (int k = 0; k <= steps; ++k) {
    const double t = horizon_s * k / steps;
    const geometry::Pose2 pose = advance_pose(X_WB, linear_mps, angular_radps, t);
    for (const TrackedObstacle& obstacle : moving) {
      if (distance_to_footprint(footprint, pose, obstacle.predicted_W(t)) - obstacle.radius_m < margin_m) return t;
    }
  }
  return std::nullopt;
}

void GuardParams::validate() const {
  geometry::require(std::isfinite(horizon_s) && horizon_s > 0.0 && horizon_s <= 10.0, "horizon_s",
                    "must be in (0, 10] seconds", horizon_s);
  geometry::require(std::isfinite(step_m) && step_m >= 0.005 && step_m <= 1.0, "step_m", "must be in [0.005, 1] metres",
                    step_m);
  geometry::require(std::isfinite(step_rad) && step_rad >= 0.005 && step_rad <= 1.0, "step_rad",
                    "must be in [0.005, 1] radians", step_rad);
  geometry::require(std::isfinite(stop_time_s) && stop_time_s >= 0.0 && stop_time_s <= horizon_s, "stop_time_s",
                    "must be in [0, horizon_s] seconds", stop_time_s);
  geometry::require(std::isfinite(stop_distance_m) && stop_distance_m >= 0.0 && stop_distance_m <= 10.0,
                    "stop_distance_m", "must be in [0, 10] metres", stop_distance_m);
  geometry::require(std::isfinite(slowdown_ratio) && slowdown_ratio > 0.0 && slowdown_ratio <= 1.0, "slowdown_ratio",
                    "must be in (0, 1]", slowdown_ratio);
  geometry::require(std::isfinite(limit_distance_m) && limit_distance_m >= 0.0 && limit_distance_m <= 10.0,
                    "limit_distance_m", "must be in [0, 10] metres", limit_distance_m);
  geometry::require(std::isfinite(predict_horizon_s) && predict_horizon_s >= 0.0 && predict_horizon_s <= 10.0,
                    "predict_horizon_s", "must be in [0, 10] seconds", predict_horizon_s);
  geometry::require(std::isfinite(predict_margin_m) && predict_margin_m >= 0.0 && predict_margin_m <= 2.0,
                    "predict_margin_m", "must be in [0, 2] metres", predict_margin_m);
  geometry::require(
      std::isfinite(scan_returns_max_age_s) && scan_returns_max_age_s >= 0.0 && scan_returns_max_age_s <= 10.0,
      "scan_returns_max_age_s", "must be in [0, 10] seconds", scan_returns_max_age_s);
  geometry::require(std::isfinite(limit_linear_mps) && limit_linear_mps > 0.0, "limit_linear_mps", "must be positive",
                    limit_linear_mps);
  geometry::require(std::isfinite(limit_angular_radps) && limit_angular_radps > 0.0, "limit_angular_radps",
                    "must be positive", limit_angular_radps);
}

std::string_view guard_action_name(GuardAction action) {
  switch (action) {
    case GuardAction::kPass:
      return "pass";
    case GuardAction::kSlow:
      return "slow";
    case GuardAction::kLimit:
      return "limit";
    case GuardAction::kStop:
      return "stop";
  }
  return "pass";
}

std::string_view model_in_contact(const GuardModels& models, const geometry::Footprint& footprint,
                                  const geometry::Pose2& X_WB, const GuardParams& params) {
  const auto terrain =
      terrain_near(models, footprint, X_WB, params, geometry::bounding_radius(footprint) + kTerrainMargin_m);
  const MovingReturns moving_returns(models, params);
  return contact_on_terrain(models, terrain ? &*terrain : nullptr, moving_returns.cells(), footprint, X_WB, params);
}

GuardDecision guard_command(const GuardModels& models, const geometry::Footprint& footprint,
                            const geometry::Pose2& X_WB, double linear_mps, double angular_radps,
                            const GuardParams& params, std::span<const TrackedObstacle> moving) {
  GuardDecision decision;
  decision.linear_mps = linear_mps;
  decision.angular_radps = angular_radps;
  decision.time_to_contact_s = params.horizon_s;
  const double reach_m = geometry::bounding_radius(footprint);
  // How far the footprint's farthest point travels per second: the path plus the turn's sweep.
  const double sweep_rate_mps = std::abs(linear_mps) + reach_m * std::abs(angular_radps);
  decision.distance_to_contact_m = sweep_rate_mps * params.horizon_s;
  if (!params.enabled) return decision;
  if (linear_mps == 0.0 && angular_radps == 0.0) return decision;

  // One terrain estimate for every pose of the sweep and the limit zone around the robot.
  const auto terrain =
      terrain_near(models, footprint, X_WB, params,
                   reach_m + std::max(decision.distance_to_contact_m, params.limit_distance_m) + kTerrainMargin_m);
  const mapping::TerrainMap* on_terrain = terrain ? &*terrain : nullptr;
  const MovingReturns moving_returns(models, params);
  if (const std::string_view touching =
          contact_on_terrain(models, on_terrain, moving_returns.cells(), footprint, X_WB, params);
      !touching.empty()) {
    decision.zone = "contact";
    decision.model = touching;
    decision.time_to_contact_s = 0.0;
    decision.distance_to_contact_m = 0.0;
    // The robot gets out of contact by turning or backing, but not deeper into it. Forward stays refused: allowed
    // along what it touches, it crept into places the escape could not get it out of (the ActivityBot in the cup).
    if (linear_mps > 0.0 || deepens_contact(models, on_terrain, moving_returns.cells(), footprint, X_WB, linear_mps,
                                            angular_radps, params)) {
      decision.action = GuardAction::kStop;
      decision.linear_mps = 0.0;
      decision.angular_radps = 0.0;
      return decision;
    }
    decision = limited(decision, params);
    if (decision.action == GuardAction::kPass) decision.action = GuardAction::kLimit;
    return decision;
  }

  const double path_m = std::abs(linear_mps) * params.horizon_s;
  const double turn_rad = std::abs(angular_radps) * params.horizon_s;
  const int steps =
      std::clamp(static_cast<int>(std::ceil(std::max(path_m / params.step_m, turn_rad / params.step_rad))), 1, 400);
  for (int k = 1; k <= steps; ++k) {
    const double t = params.horizon_s * k / steps;
    const std::string_view hit = contact_on_terrain(models, on_terrain, moving_returns.cells(), footprint,
                                                    advance_pose(X_WB, linear_mps, angular_radps, t), params);
    if (hit.empty()) continue;
    decision.model = hit;
    decision.time_to_contact_s = t;
    decision.distance_to_contact_m = sweep_rate_mps * t;
    if (t <= params.stop_time_s || decision.distance_to_contact_m <= params.stop_distance_m) {
      decision.action = GuardAction::kStop;
      decision.zone = "stop";
      decision.linear_mps = 0.0;
      decision.angular_radps = 0.0;
      return decision;
    }
    decision.action = GuardAction::kSlow;
    decision.zone = "slowdown";
    decision.linear_mps *= params.slowdown_ratio;
    decision.angular_radps *= params.slowdown_ratio;
    break;
  }
  if (params.predict_horizon_s > 0.0 && !moving.empty()) {
    // Only a motion that runs into a moving obstacle's predicted position where standing still would not, or that
    // closes in on it faster: stopping a robot that is stepping out of the way would leave it in the obstacle's path.
    const std::optional<double> moving_s = predicted_contact_s(moving, footprint, X_WB, linear_mps, angular_radps,
                                                               params.predict_horizon_s, params.predict_margin_m);
    bool runs_into = false;
    if (moving_s) {
      runs_into = !predicted_contact_s(moving, footprint, X_WB, 0.0, 0.0, *moving_s, params.predict_margin_m);
      if (!runs_into) {
        // Standing still meets it too (it is coming at the robot), yet the motion may not close in on it faster than
        // standing would: a corner swung into a person beside the robot, an arc across a cart's way. Judged over the
        // stopping time and two more prediction steps: the next commands judge what comes after.
        const double window_s = params.stop_time_s + 2.0 * kPredictStep_s;
        const double gap_moving_m =
            predicted_gap(moving, footprint, X_WB, linear_mps, angular_radps, window_s, window_s);
        const double gap_standing_m = predicted_gap(moving, footprint, X_WB, 0.0, 0.0, 0.0, window_s);
        runs_into = gap_moving_m < params.predict_margin_m && gap_moving_m < gap_standing_m - kCloserThanStanding_m;
      }
    }
    if (runs_into) {
      const double distance_m = sweep_rate_mps * *moving_s;
      if (*moving_s <= params.stop_time_s + params.predict_horizon_s / 3.0 || distance_m <= params.stop_distance_m) {
        decision.action = GuardAction::kStop;
        decision.zone = "predict_stop";
        decision.model = "moving";
        decision.time_to_contact_s = *moving_s;
        decision.distance_to_contact_m = distance_m;
        decision.linear_mps = 0.0;
        decision.angular_radps = 0.0;
        return decision;
      }
      if (decision.action == GuardAction::kPass) {
        decision.action = GuardAction::kSlow;
        decision.zone = "predict_slow";
        decision.model = "moving";
        decision.time_to_contact_s = *moving_s;
        decision.distance_to_contact_m = distance_m;
        decision.linear_mps *= params.slowdown_ratio;
        decision.angular_radps *= params.slowdown_ratio;
      }
    }
  }
  if (params.limit_distance_m > 0.0) {
    const std::string_view model =
        nearest_obstacle(models, on_terrain, moving_returns.cells(), footprint, X_WB, params, params.limit_distance_m)
            .second;
    if (!model.empty()) {
      const GuardDecision capped = limited(decision, params);
      if (capped.action == GuardAction::kLimit && decision.action == GuardAction::kPass) {
        decision = capped;
        decision.zone = "limit";
        decision.model = model;
      } else if (capped.action == GuardAction::kLimit) {
        decision.linear_mps = capped.linear_mps;  // slowed and limited: the slowdown zone stays the reason shown
        decision.angular_radps = capped.angular_radps;
      }
    }
  }
  return decision;
}

}  // namespace occgeo::service::control
