#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/kinematics.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/mapping/grid_snapshot.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/mapping/ptem.h"
#include "occgeo/service/control/bearcat.h"
#include "occgeo/service/control/behaviour_state.h"
#include "occgeo/service/control/cluster_tracker.h"
#include "occgeo/service/control/pointbug.h"
#include "occgeo/service/control/safety_guard.h"
#include "occgeo/service/control/servo_sweep.h"
#include "occgeo/service/control/wander.h"

// The one interface every behaviour the server can run implements, so that the scan handler drives any of them the
// same way: each control cycle gets the robot's first laser scan and its pose, and returns a body velocity (and, for
// behaviours that compute them, differential wheel speeds). Behaviours are deterministic given their inputs.

namespace occgeo::service::control {

// One reading of a servo-swept single-beam rangefinder (seed 003's LIDAR-Lite), as its robot reported it.
struct ServoSample {
  double servo_angle_rad = 0.0;  // the servo's angle, radians
  double range_m = 0.0;          // metres; at or beyond the sensor's range_max_m means no return
  double stamp_s = 0.0;          // seconds
};

// What a behaviour sees in one control cycle.
struct BehaviourInput {
  ScanView scan;                                // the robot's first laser, sensor frame
  std::optional<geometry::Pose2> X_WB;          // base_link in the world frame (odometry), when known
  double stamp_s = 0.0;                         // the scan's stamp, seconds
  const mapping::GridSnapshot* grid = nullptr;  // the world's latest models, when the caller has them
  const mapping::PtemSnapshot* ptem = nullptr;
  const mapping::OctoMapSnapshot* octomap = nullptr;  // for obstacles above or below the laser plane
  // A robot without a laser steers by its range array (seed 001's sonar ring): each element's bearing in base_link and
  // its reading as a distance from base_link's origin along that bearing; scan is then empty.
  std::optional<RangeSet> ring = std::nullopt;
  // A robot whose only range sensor is a servo-swept beam steers by it, one reading per cycle; scan is then empty.
  std::optional<ServoSample> servo = std::nullopt;
  // The clusters the world's trackers follow as moving (WorldSnapshot::moving), whose returns ptem's latest scans hold
  // but the grid does not: the guard's checks of a motion look at those returns too (GuardModels::moving_tracks).
  std::span<const TrackedObstacle> moving_tracks{};
};

// What a behaviour commands.
struct BehaviourCommand {
  double linear_mps = 0.0;                       // forward speed of base_link, m/s
  double angular_radps = 0.0;                    // counter-clockwise yaw rate, rad/s
  std::optional<geometry::WheelSpeeds> wheels;   // differential wheel speeds, when the behaviour computes them
  bool stop = false;                             // stand still
  BehaviourState state = BehaviourState::kNone;  // e.g. kSteerGap, kStepToGoal, kReached
  // A straight leg the behaviour drives to its end (PointBug's drive to a sudden point, as the seed's drive_goto):
  // its whole length from where it began, metres, and a number that changes with each new leg (from 1).
  std::optional<double> leg_m;
  std::uint64_t leg_id = 0;
};

class Behaviour {
 public:
  virtual ~Behaviour() = default;
  // The name a DriveRequest gives it, e.g. "wander".
  [[nodiscard]] virtual std::string_view name() const = 0;
  // One decision; throws std::invalid_argument naming the field when the input is malformed.
  virtual BehaviourCommand decide(const BehaviourInput& input) = 0;
  // Where the behaviour is heading now (goto's goal, the current waypoint), world frame; nullopt without a goal.
  [[nodiscard]] virtual std::optional<Eigen::Vector2d> current_goal() const { return std::nullopt; }
  // The path it follows from here, world frame (waypoints still ahead, a global escape path); empty when it has none.
  [[nodiscard]] virtual std::vector<Eigen::Vector2d> planned_path() const { return {}; }
  // The moving obstacles it tracks, as of its latest decision, for the guard's prediction; empty when it tracks none.
  [[nodiscard]] virtual std::vector<TrackedObstacle> moving_obstacles() const { return {}; }
};

// What the robot is, as the behaviours need it.
struct RobotShape {
  geometry::Footprint footprint;
  double laser_x_m = 0.0;       // the first laser's position ahead of base_link, metres
  double max_linear_mps = 1.0;  // the drive's largest forward speed, m/s
};

// The Bearcat behaviour (seed 000 §4.2–4.3); params must be valid.
std::unique_ptr<Behaviour> make_bearcat(const BearcatParams& params);

// Seed 001's wander/avoid on the laser's beams, with the obstacle threshold raised to 1.5 robot widths measured
// from base_link's front edge for robots larger than the seed's Scout; params must be valid.
std::unique_ptr<Behaviour> make_wander(const WanderParams& params, const RobotShape& robot);

// PointBug's parameters for a robot with a forward laser: the seed's ActivityBot values scaled to the robot's size
// (obstacle range, distance and angle corrections) and speed.
PointBugParams pointbug_params_for(const RobotShape& robot);

// PointBug to (goal_x_m, goal_y_m), world frame, fed a ±90° sweep at whole degrees taken from the laser scan;
// velocities are limited so that each control cycle (period_s) ends at, not beyond, the current turn or leg. With
// corridor_half_width_m > 0 (beyond the seed) the reading straight ahead is the nearest return inside the corridor
// that wide either side of the heading, so an obstacle off the centre beam but in the body's way stops the approach.
std::unique_ptr<Behaviour> make_goto(const PointBugParams& params, double goal_x_m, double goal_y_m, double period_s,
                                     double corridor_half_width_m = 0.0);

// Seed 003's PointBug on its own sensor, a single beam on a servo that turns back and forth (one reading per control
// cycle of period_s, servo_yaw_rad being the servo's zero in base_link). The readings are assembled into sweeps
// (ServoSweepAssembler); while stepping to the goal the robot goes on the latest reading straight ahead, taken at its
// current heading and shortened by the distance driven since; without one it stands until the servo passes ahead
// again ("look_ahead"). When that reading is within obstacle_range_m the robot stops and waits for a whole sweep taken
// standing ("sweep"), as the seed's robot stops and sweeps both sides, and PointBug picks its sudden point from it.
// Throws std::invalid_argument naming the bad field of params or limits.
std::unique_ptr<Behaviour> make_servo_goto(const PointBugParams& params, const ServoSweepLimits& limits,
                                           double servo_yaw_rad, double goal_x_m, double goal_y_m, double period_s);

// PTEM waypoint guidance (seed 004 §4.4–4.5) along waypoints_W (world frame) against the input's PTEM snapshot, with
// the body radius and speeds of this robot.
std::unique_ptr<Behaviour> make_waypoints(const RobotShape& robot, std::vector<Eigen::Vector2d> waypoints_W);

// Beyond the seeds: deadlock escape. Runs the inner behaviour; when it reports no_path, or the loop detector sees it
// loop or stall, plans a global path over the remembered HIMM grid (inflated by the footprint) to the inner
// behaviour's current goal and follows it by pure pursuit (state "escape_<trigger>"), then resumes a fresh inner
// behaviour from `rebuild`. For goto it also looks ahead: when the straight way to the goal runs into an occupied cell
// of the remembered grid, it follows the global path at once (state "escape_blocked"). The global path's hard limit is
// the footprint's inscribed radius, with a cost gradient out to its circumscribed radius. While it follows the path, a
// command the safety guard (`guard`, as the server runs it) would stop is replaced for 1.5 s by the first motion the
// guard lets through, as make_map_escape does. An inner behaviour without a goal runs unchanged.
std::unique_ptr<Behaviour> make_escape(std::function<std::unique_ptr<Behaviour>()> rebuild, const RobotShape& robot,
                                       const GuardParams& guard);

// Beyond the seeds, for behaviours without a goal (Bearcat, wander): when the inner behaviour stops (the Bearcat's
// deadlock) or makes no headway (0.5 m) for 6 s, plans a way out over the remembered HIMM grid to the first reachable
// point round the robot (4 m, 2.5 m, 1.5 m away; behind it first) and follows it by pure pursuit (state
// "escape_<trigger>"), then resumes a fresh inner behaviour from `rebuild`. With no way out on the map yet it turns on
// the spot ("escape_look_round") instead of stopping. While it escapes or is stalled, a command the safety guard
// (`guard`, as the server runs it) would stop is replaced for 1.5 s by the first motion the guard lets through: the
// same turn on the spot, the same turn on an arc forward, backing, the other turn, creeping forward.
std::unique_ptr<Behaviour> make_map_escape(std::function<std::unique_ptr<Behaviour>()> rebuild, const RobotShape& robot,
                                           const GuardParams& guard);

// Beyond the seeds: yielding to moving obstacles. Tracks the PTEM's clusters (ClusterTracker) and runs the inner
// behaviour; when a moving obstacle is predicted (guard.predict_horizon_s ahead) to come within
// guard.predict_margin_m of the robot standing where it is, the robot steps aside: of a few short arcs forward and
// backward, the one that keeps it farthest from the obstacles' predicted discs without touching the map
// ("yield_aside"). Otherwise, when the inner behaviour's command runs into a moving obstacle's predicted position,
// the robot slows down while the contact is far ("yield_slow") and stops short of it when it is near ("yield_wait"),
// going on once the obstacle has passed. Returns near the robot that came at it between two scans count as one more
// moving obstacle, at their mean displacement, when they are most of the returns round the nearest of them and the
// previous scan found them where they now are: a cart whose cluster merges with a door frame, or a walker's with a
// shelf, which the tracker cannot follow. With predict_horizon_s 0 the inner behaviour runs unchanged.
std::unique_ptr<Behaviour> make_yield(std::unique_ptr<Behaviour> inner, const RobotShape& robot,
                                      const GuardParams& guard);

// The ±90°, 1° sweep PointBug reads, taken from a laser scan: each whole degree reads the nearest beam within half a
// beam step (or half a degree), else no return. laser_x_m shifts nothing: ranges stay the sensor's.
std::vector<SweepReading> sweep_from_scan(const ScanView& scan);

}  // namespace occgeo::service::control
