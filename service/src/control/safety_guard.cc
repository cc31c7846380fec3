#include "occgeo/service/control/safety_guard.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

#include "model_geometry.h"

namespace occgeo::service::control {

namespace {

// The terrain around the swept footprint reaches this much farther, so the cells it reads have their neighbours.
constexpr double kTerrainMargin_m = 0.3;

void require(bool ok, const char* field, const char* what) {
  if (!ok) throw std::invalid_argument(std::string(field) + " " + what);
}

// base_link after driving the body velocity for t seconds from X_WB (exact unicycle arc).
geometry::Pose2 advance(const geometry::Pose2& X_WB, double linear_mps, double angular_radps, double t) {
  const double turned = angular_radps * t;
  if (std::abs(turned) < 1e-9) {
    return {X_WB.x + linear_mps * t * std::cos(X_WB.theta), X_WB.y + linear_mps * t * std::sin(X_WB.theta), X_WB.theta};
  }
  const double radius = linear_mps / angular_radps;
  const double theta = X_WB.theta + turned;
  return {X_WB.x + radius * (std::sin(theta) - std::sin(X_WB.theta)),
          X_WB.y - radius * (std::cos(theta) - std::cos(X_WB.theta)), geometry::wrap_angle(theta)};
}

double footprint_height(const geometry::Footprint& footprint) {
  return std::visit([](const auto& shape) { return shape.height; }, footprint);
}

// The terrain the guard reads within reach_m of base_link (world frame), when there is an octree to estimate it
// from: the surfaces the robot can drive on, where neither the grid's returns nor the octree's voxels of the surface
// are obstacles (the robot climbing a ramp its laser reads as a wall).
std::optional<mapping::TerrainMap> terrain_near(const GuardModels& models, const geometry::Footprint& footprint,
                                                const geometry::Pose2& X_WB, const GuardParams& params,
                                                double reach_m) {
  if (models.octomap == nullptr || !(params.check_grid || params.check_octomap) || !models.octomap->terrain().enabled) {
    return std::nullopt;
  }
  const double cell_m = models.grid != nullptr ? models.grid->cell_size() : 2.0 * models.octomap->resolution();
  const Eigen::Vector2d position_W = X_WB.position();
  const Eigen::Vector2d reach(reach_m, reach_m);
  return terrain_around(*models.octomap, cell_m, position_W - reach, position_W + reach, footprint_height(footprint),
                        position_W);
}

// model_in_contact with the terrain's exceptions (none when terrain is null).
std::string_view contact_on_terrain(const GuardModels& models, const mapping::TerrainMap* terrain,
                                    const geometry::Footprint& footprint, const geometry::Pose2& X_WB,
                                    const GuardParams& params) {
  if (params.check_grid && models.grid != nullptr) {
    const bool hit = terrain != nullptr
                         ? geometry::check_collision({footprint, X_WB}, TerrainMaskedCells(*models.grid, *terrain)).hit
                         : geometry::check_collision({footprint, X_WB}, *models.grid).hit;
    if (hit) return "grid";
  }
  if (params.check_ptem && models.ptem != nullptr && collide_ptem(*models.ptem, footprint, X_WB).hit) return "ptem";
  if (params.check_octomap && models.octomap != nullptr) {
    // With a terrain the band follows the surface, which FCL's straight prism cannot: the same voxels as columns.
    const bool hit = terrain != nullptr
                         ? geometry::check_collision(
                               {footprint, X_WB}, OctoMapColumns(*models.octomap, footprint_height(footprint), terrain))
                               .hit
                         : collide_octomap(*models.octomap, footprint, X_WB).hit;
    if (hit) return "octomap";
  }
  return "";
}

// Smallest distance from the footprint at X_WB to any consulted model's obstacle, looking no farther than
// max_distance_m; returns max_distance_m and model "" when nothing is that close.
std::pair<double, std::string_view> nearest_obstacle(const GuardModels& models, const mapping::TerrainMap* terrain,
                                                     const geometry::Footprint& footprint, const geometry::Pose2& X_WB,
                                                     const GuardParams& params, double max_distance_m) {
  double best = max_distance_m;
  std::string_view model;
  if (params.check_grid && models.grid != nullptr) {
    const auto clearance =
        terrain != nullptr
            ? geometry::compute_clearance({footprint, X_WB, max_distance_m}, TerrainMaskedCells(*models.grid, *terrain))
            : geometry::compute_clearance({footprint, X_WB, max_distance_m}, *models.grid);
    if (clearance.found && clearance.clearance_m < best) {
      best = clearance.clearance_m;
      model = "grid";
    }
  }
  if (params.check_octomap && models.octomap != nullptr) {
    const OctoMapColumns columns(*models.octomap, footprint_height(footprint), terrain);
    const auto clearance = geometry::compute_clearance({footprint, X_WB, max_distance_m}, columns);
    if (clearance.found && clearance.clearance_m < best) {
      best = clearance.clearance_m;
      model = "octomap";
    }
  }
  if (params.check_ptem && models.ptem != nullptr) {
    const auto clearance = ptem_clearance(*models.ptem, footprint, X_WB, max_distance_m);
    if (clearance.found && clearance.clearance_m < best) {
      best = clearance.clearance_m;
      model = "ptem";
    }
  }
  return {best, model};
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

}  // namespace

void GuardParams::validate() const {
  require(std::isfinite(horizon_s) && horizon_s > 0.0 && horizon_s <= 10.0, "horizon_s", "must be in (0, 10] seconds");
  require(std::isfinite(step_m) && step_m >= 0.005 && step_m <= 1.0, "step_m", "must be in [0.005, 1] metres");
  require(std::isfinite(step_rad) && step_rad >= 0.005 && step_rad <= 1.0, "step_rad", "must be in [0.005, 1] radians");
  require(std::isfinite(stop_time_s) && stop_time_s >= 0.0 && stop_time_s <= horizon_s, "stop_time_s",
          "must be in [0, horizon_s] seconds");
  require(std::isfinite(stop_distance_m) && stop_distance_m >= 0.0 && stop_distance_m <= 10.0, "stop_distance_m",
          "must be in [0, 10] metres");
  require(std::isfinite(slowdown_ratio) && slowdown_ratio > 0.0 && slowdown_ratio <= 1.0, "slowdown_ratio",
          "must be in (0, 1]");
  require(std::isfinite(limit_distance_m) && limit_distance_m >= 0.0 && limit_distance_m <= 10.0, "limit_distance_m",
          "must be in [0, 10] metres");
  require(std::isfinite(limit_linear_mps) && limit_linear_mps > 0.0, "limit_linear_mps", "must be positive");
  require(std::isfinite(limit_angular_radps) && limit_angular_radps > 0.0, "limit_angular_radps", "must be positive");
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
  return contact_on_terrain(models, terrain ? &*terrain : nullptr, footprint, X_WB, params);
}

GuardDecision guard_command(const GuardModels& models, const geometry::Footprint& footprint,
                            const geometry::Pose2& X_WB, double linear_mps, double angular_radps,
                            const GuardParams& params) {
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
  if (const std::string_view touching = contact_on_terrain(models, on_terrain, footprint, X_WB, params);
      !touching.empty()) {
    decision.zone = "contact";
    decision.model = touching;
    decision.time_to_contact_s = 0.0;
    decision.distance_to_contact_m = 0.0;
    if (linear_mps > 0.0) {
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
    const std::string_view hit =
        contact_on_terrain(models, on_terrain, footprint, advance(X_WB, linear_mps, angular_radps, t), params);
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
  if (params.limit_distance_m > 0.0) {
    const std::string_view model =
        nearest_obstacle(models, on_terrain, footprint, X_WB, params, params.limit_distance_m).second;
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
