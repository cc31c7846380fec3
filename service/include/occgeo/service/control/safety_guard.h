#pragma once

#include <optional>
#include <span>
#include <string_view>

#include "occgeo/geometry/collision.h"
#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/mapping/ptem.h"
#include "occgeo/service/control/cluster_tracker.h"

// The safety guard every motion command passes, whatever produced it: the robot's footprint is swept along the
// commanded body velocity over a short horizon and checked against the world's models (the HIMM grid and the
// OctoMap with FCL, the PTEM's restricted region), then zones in the style of a collision monitor decide: stop
// when contact is near in time or distance, slow down by a ratio when contact lies within the horizon, limit the
// speeds when an obstacle is close to the footprint where it stands. Moving obstacles (tracked PTEM clusters) are
// checked at their predicted positions: the guard stops or slows a motion that runs into where one will be, or that
// closes in on one coming at the robot faster than standing still would, but never a motion that only fails to get
// out of its way (the robot standing there would be hit as well).

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
  // The returns the laser saw in the last scan_returns_max_age_s (the PTEM clusters made that recently, their returns
  // only) of the people and carts tracked as moving (GuardModels::moving_tracks), whose returns the grid and the octree
  // do not keep. Still things stay the grid's: their raw returns beside a robot wedged at a box would stop every turn.
  bool check_scan_returns = true;
  double scan_returns_max_age_s = 0.3;
  // Moving obstacles are predicted this far ahead, seconds, by the guard and by goto and waypoints, which yield to
  // them (wait short of a crossing, step aside from one on course to hit the robot); 0 turns prediction off.
  double predict_horizon_s = 3.0;
  double predict_margin_m = 0.2;  // a moving obstacle predicted closer than this to the footprint counts as contact
  // Throws std::invalid_argument naming the first field out of range.
  void validate() const;
};

// The world's models as one snapshot holds them; a null model is not consulted.
struct GuardModels {
  const geometry::OccupiedCellSource* grid = nullptr;
  const mapping::OctoMapSnapshot* octomap = nullptr;
  const mapping::PtemSnapshot* ptem = nullptr;          // its restricted region, with check_ptem
  const mapping::PtemSnapshot* scan_returns = nullptr;  // its recent clusters' returns, with check_scan_returns ...
  std::span<const TrackedObstacle> moving_tracks{};     // ... those within these tracks' circles (the world's trackers)
};

enum class GuardAction { kPass, kSlow, kLimit, kStop };

struct GuardDecision {
  GuardAction action = GuardAction::kPass;
  std::string_view zone;   // "", "stop", "slowdown", "limit", "contact", "predict_stop" or "predict_slow"
  std::string_view model;  // "grid", "octomap", "ptem", "scan_returns", "moving" or "" (what triggered the zone)
  double time_to_contact_s = 0.0;      // horizon_s when no contact within the horizon
  double distance_to_contact_m = 0.0;  // base_link's path length until contact (the horizon's when none)
  double linear_mps = 0.0;             // the command after the guard
  double angular_radps = 0.0;
};

// Distance from p_W to the footprint at X_WB (world frame), metres; 0 inside it.
double distance_to_footprint(const geometry::Footprint& footprint, const geometry::Pose2& X_WB,
                             const Eigen::Vector2d& p_W);

// base_link after driving the body velocity for t_s seconds from X_WB (exact unicycle arc).
geometry::Pose2 advance_pose(const geometry::Pose2& X_WB, double linear_mps, double angular_radps, double t_s);

// Smallest predicted gap (metres, negative when overlapping) between the footprint and the moving obstacles' discs
// over [0, horizon_s], the robot driving the body velocity for drive_s seconds from X_WB and then standing; the time
// of that smallest gap in *at_s when given. +inf without obstacles.
double predicted_gap(std::span<const TrackedObstacle> moving, const geometry::Footprint& footprint,
                     const geometry::Pose2& X_WB, double linear_mps, double angular_radps, double drive_s,
                     double horizon_s, double* at_s = nullptr);

// The first time in [0, horizon_s] at which the footprint, driving the body velocity from X_WB, comes within margin_m
// of a moving obstacle's predicted disc (0 when it is that close now, also for a horizon of 0); nullopt when it never
// does.
std::optional<double> predicted_contact_s(std::span<const TrackedObstacle> moving, const geometry::Footprint& footprint,
                                          const geometry::Pose2& X_WB, double linear_mps, double angular_radps,
                                          double horizon_s, double margin_m);

// "pass", "slow", "limit" or "stop".
std::string_view guard_action_name(GuardAction action);

// The first model in contact with the footprint at X_WB, or "" when none is; `models` as above.
std::string_view model_in_contact(const GuardModels& models, const geometry::Footprint& footprint,
                                  const geometry::Pose2& X_WB, const GuardParams& params);

// Guards one command (body velocity in base_link) of a robot with this footprint at X_WB (world frame). A robot
// already touching an obstacle may only turn in place or back away, at the limit zone's speeds. moving are the
// moving obstacles with their velocities (ClusterTracker), checked at their predicted positions. params must be valid.
GuardDecision guard_command(const GuardModels& models, const geometry::Footprint& footprint,
                            const geometry::Pose2& X_WB, double linear_mps, double angular_radps,
                            const GuardParams& params, std::span<const TrackedObstacle> moving = {});

}  // namespace occgeo::service::control
