#pragma once

#include <string_view>

#include "occgeo/geometry/collision.h"
#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/mapping/ptem.h"

// The safety guard every motion command passes, whatever produced it: the robot's footprint is swept along the
// commanded body velocity over a short horizon and checked against the world's models (the HIMM grid and the
// OctoMap with FCL, the PTEM's restricted region), then zones in the style of a collision monitor decide: stop
// when contact is near in time or distance, slow down by a ratio when contact lies within the horizon, limit the
// speeds when an obstacle is close to the footprint where it stands.

namespace occgeo::service::control {

// Tuning of the guard (config section `guard:`).
struct GuardParams {
  bool enabled = true;
  double horizon_s = 1.0;            // the commanded motion is swept this far ahead, seconds
  double step_m = 0.05;              // swept poses are at most this far apart along the path, metres
  double step_rad = 0.1;             // ... and this far apart in heading, radians
  double stop_time_s = 0.35;         // contact sooner than this at the commanded speed: stop
  double stop_distance_m = 0.10;     // contact within this path length: stop
  double slowdown_ratio = 0.5;       // contact within the horizon (but not a stop): both speeds scaled by this
  double limit_distance_m = 0.30;    // an obstacle within this of the footprint where it stands: limit speeds
  double limit_linear_mps = 0.3;     // the limit zone's largest |linear|, m/s
  double limit_angular_radps = 0.8;  // the limit zone's largest |angular|, rad/s
  bool check_grid = true;            // which models the guard consults
  bool check_octomap = true;
  bool check_ptem = false;  // off by default: a long wall's enclosing circle covers free ground
  // Throws std::invalid_argument naming the first field out of range.
  void validate() const;
};

// The world's models as one snapshot holds them; a null model is not consulted.
struct GuardModels {
  const geometry::OccupiedCellSource* grid = nullptr;
  const mapping::OctoMapSnapshot* octomap = nullptr;
  const mapping::PtemSnapshot* ptem = nullptr;
};

enum class GuardAction { kPass, kSlow, kLimit, kStop };

struct GuardDecision {
  GuardAction action = GuardAction::kPass;
  std::string_view zone;               // "", "stop", "slowdown", "limit" or "contact"
  std::string_view model;              // "grid", "octomap", "ptem" or "" (what triggered the zone)
  double time_to_contact_s = 0.0;      // horizon_s when no contact within the horizon
  double distance_to_contact_m = 0.0;  // base_link's path length until contact (the horizon's when none)
  double linear_mps = 0.0;             // the command after the guard
  double angular_radps = 0.0;
};

// "pass", "slow", "limit" or "stop".
std::string_view guard_action_name(GuardAction action);

// The first model in contact with the footprint at X_WB, or "" when none is; `models` as above.
std::string_view model_in_contact(const GuardModels& models, const geometry::Footprint& footprint,
                                  const geometry::Pose2& X_WB, const GuardParams& params);

// Guards one command (body velocity in base_link) of a robot with this footprint at X_WB (world frame). A robot
// already touching an obstacle may only turn in place or back away, at the limit zone's speeds. params must be valid.
GuardDecision guard_command(const GuardModels& models, const geometry::Footprint& footprint,
                            const geometry::Pose2& X_WB, double linear_mps, double angular_radps,
                            const GuardParams& params);

}  // namespace occgeo::service::control
