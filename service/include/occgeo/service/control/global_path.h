#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "occgeo/geometry/cell.h"
#include "occgeo/mapping/grid_snapshot.h"
#include "occgeo/service/control/pointbug.h"

// A global path on the robot's remembered HIMM grid, to escape deadlocks the reactive behaviours cannot (seed 000
// §5.2, Fig 5.3): A* over 8-connected cells with octile step costs, occupied cells inflated by the robot's footprint,
// unknown cells allowed at an extra cost (the robot only knows what it has seen), inside a bounded window and
// expansion budget; the cell path is shortened by line-of-sight shortcuts that never raise its cost. A pure-pursuit
// follower turns a pose and a path into a body velocity.
namespace occgeo::service::control {

// Tuning of the planner.
struct GlobalPathParams {
  // The robot's footprint radius: every point of the returned path, shortcuts included, keeps at least this distance
  // from every occupied cell (a cell centre is free when it is at least footprint_radius_m + half a cell diagonal
  // from every occupied cell's square, so the segments between free centres keep the radius), metres, in [0, 5].
  double footprint_radius_m = 0.25;
  // A step into an unknown cell costs (1 + unknown_extra_cost) times its length; >= 0. 0 treats unknown as free.
  double unknown_extra_cost = 1.0;
  // Beyond footprint_radius_m (the hard limit: pass the footprint's inscribed radius so narrow but passable gaps stay
  // open) cells whose centre lies within cost_radius_m of an occupied cell cost extra, falling linearly from
  // near_obstacle_extra_cost at footprint_radius_m to 0 at cost_radius_m (pass the circumscribed radius): paths keep
  // away from walls where there is room and squeeze through gaps only when they must. Metres, in [0, 5]; 0: no
  // gradient.
  double cost_radius_m = 0.0;
  double near_obstacle_extra_cost = 2.0;  // >= 0
  // A cell is occupied from this certainty on; 0 means the grid's own occupied threshold. In [0, 255].
  int occupied_threshold = 0;
  // The search window: the box around start and goal, grown by this on every side, metres.
  double window_margin_m = 5.0;
  // Largest window side, cells; a start and goal farther apart are refused ("window_too_large").
  int max_window_cells = 1024;
  // Largest number of cells A* expands before it gives up ("expansion_limit").
  std::size_t max_expansions = 400000;
  // Shorten the cell path by line-of-sight shortcuts (never raising its cost).
  bool smooth = true;
  // Re-planning hysteresis: the path the robot follows now (world frame, from the robot's position on), or empty.
  // While every point of it still keeps footprint_radius_m (measured like the planned path; its first leg may leave
  // the inflated zone the robot stands in) it is the kept path; when the map has blocked it further on, the kept path
  // is its clear part up to the vertex before the first blocked leg, then a path planned from there. The kept path wins
  // unless the fresh one costs at least keep_min_gain_m and keep_min_gain_fraction of its cost less, both taken on the
  // same window with the same weights. A fresh path through a growing map otherwise flips between ways round an
  // obstacle whenever a wall comes into view, and the robot turns back.
  std::vector<Eigen::Vector2d> current_path_W;
  double keep_min_gain_m = 0.5;          // >= 0, metres
  double keep_min_gain_fraction = 0.15;  // in [0, 1)

  // Throws std::invalid_argument naming the first field that is not finite or out of range.
  void validate() const;
};

enum class GlobalPathStatus {
  kFound,
  kStartOccupied,   // the start cell itself is occupied
  kGoalBlocked,     // the goal cell is occupied or within the footprint radius of an occupied cell
  kWindowTooLarge,  // start and goal too far apart for max_window_cells
  kExpansionLimit,  // the budget ran out before the goal was reached
  kNoPath,          // every reachable cell of the window was expanded: the goal is cut off
};

// "found", "start_occupied", "goal_blocked", "window_too_large", "expansion_limit" or "no_path".
std::string_view to_string(GlobalPathStatus status);

// What a cell is to the planner.
enum class PlanningCell : std::uint8_t { kFree, kUnknown, kOccupied };

// A dense window of cells in grid order: cell (origin.ix + col, origin.iy + row) is cells[row * width + col].
struct PlanningWindow {
  geometry::CellIndex origin;
  int width = 0;
  int height = 0;
  double cell_size_m = 0.0;  // side of a cell, metres
  std::vector<PlanningCell> cells;
};

// The window of the snapshot between min and max (inclusive), occupied from `occupied_threshold` (certainty) on and
// unknown where never observed. Throws std::invalid_argument when max < min or the window is too large for int.
PlanningWindow planning_window(const mapping::GridSnapshot& grid, geometry::CellIndex min, geometry::CellIndex max,
                               int occupied_threshold);

struct GlobalPathResult {
  GlobalPathStatus status = GlobalPathStatus::kNoPath;
  // Start, shortcut corners and goal, world frame, metres; empty unless found. The first point is the start and the
  // last the goal as given.
  std::vector<Eigen::Vector2d> waypoints_W;
  // The A* cell path from the start cell to the goal cell, before shortcuts; empty unless found.
  std::vector<geometry::CellIndex> cells;
  double cost_m = 0.0;           // cost of the cell path (length, unknown steps weighted), metres
  double smoothed_cost_m = 0.0;  // cost of the waypoint path between the first and last cell centres, metres
  std::size_t expansions = 0;    // cells A* expanded
  // Set when the path of params.current_path_W was kept (waypoints_W is that path, or its clear part and a path on
  // from there; cells stay those of the fresh search, and the costs above are the fresh path's).
  bool kept_current = false;
  std::optional<double> current_cost_m;  // the current path's cost on the window; nullopt when none or blocked
};

// A* from start_W to goal_W (world frame) on the window; the start may lie within the footprint radius of a wall (the
// path then leaves that zone and never re-enters it). Throws std::invalid_argument naming the field when params are
// invalid, the points are not finite or lie outside the window, or the window is malformed.
GlobalPathResult plan_global_path(const PlanningWindow& window, const Eigen::Vector2d& start_W,
                                  const Eigen::Vector2d& goal_W, const GlobalPathParams& params);

// The window plan_global_path searches on a grid snapshot: the box of the cells of start and goal grown by
// params.window_margin_m; nullopt when that is over params.max_window_cells on either axis. Throws
// std::invalid_argument naming start_W or goal_W when it is not finite or lies 2^30 cells or more from the origin.
std::optional<PlanningWindow> window_around(const mapping::GridSnapshot& grid, const Eigen::Vector2d& start_W,
                                            const Eigen::Vector2d& goal_W, const GlobalPathParams& params);

// Same on a grid snapshot, on window_around's window (kWindowTooLarge when there is none).
GlobalPathResult plan_global_path(const mapping::GridSnapshot& grid, const Eigen::Vector2d& start_W,
                                  const Eigen::Vector2d& goal_W, const GlobalPathParams& params);

// The cost of following the polyline path_W (world frame) on the window with the planner's weights (length in each
// cell times its weight, as the planned path's cost is measured), or nullopt when a point of it lies outside the
// window or in a blocked cell; the first leg may cross blocked cells until it first reaches a free one (a start in the
// inflated zone), never an occupied one. Throws std::invalid_argument naming the field when params, the window or a
// point is invalid.
std::optional<double> path_cost(const PlanningWindow& window, std::span<const Eigen::Vector2d> path_W,
                                const GlobalPathParams& params);

// The free/blocked verdict plan_global_path uses for each cell of the window (row-major like cells): true where the
// centre is closer than footprint_radius_m + half a cell diagonal to an occupied cell's square.
std::vector<bool> inflate(const PlanningWindow& window, double footprint_radius_m);

// The extra cost per metre plan_global_path adds for each cell of the window (row-major like cells) near obstacles:
// near_obstacle_extra_cost at footprint_radius_m + half a cell diagonal from an occupied cell's square, falling
// linearly to 0 at cost_radius_m + half a cell diagonal; 0 everywhere when cost_radius_m <= footprint_radius_m.
std::vector<float> obstacle_cost(const PlanningWindow& window, const GlobalPathParams& params);

// True when no occupied cell of the snapshot comes within radius_m of the segment from a_W to b_W (world frame): the
// straight way is open as far as the robot remembers. Cells are measured to their squares, so this errs toward
// "blocked". Throws std::invalid_argument naming the field when a point is not finite or radius_m is not in [0, 5].
bool segment_clear(const mapping::GridSnapshot& grid, const Eigen::Vector2d& a_W, const Eigen::Vector2d& b_W,
                   double radius_m);

// Tuning of the path follower.
struct PurePursuitParams {
  double lookahead_m = 0.5;                             // distance along the path to the aim point, metres
  double linear_speed_mps = 0.3;                        // cruise speed, m/s
  double max_angular_radps = 1.0;                       // yaw rate limit, rad/s
  double goal_tolerance_m = 0.1;                        // the path's end is reached within this, metres
  double rotate_in_place_rad = std::numbers::pi / 3.0;  // aim point farther off the heading: turn on the spot
  double slowdown_distance_m = 0.5;                     // speed ramps down linearly over this before the end, m

  // Throws std::invalid_argument naming the first field that is not finite or out of range.
  void validate() const;
};

struct PurePursuitCommand {
  double linear_mps = 0.0;     // forward speed, m/s
  double angular_radps = 0.0;  // counter-clockwise yaw rate, rad/s
  bool reached = false;        // within goal_tolerance_m of the path's last point: stand still
  std::size_t segment = 0;     // the path segment nearest the robot (segment i runs from path[i] to path[i + 1])
  Eigen::Vector2d aim_W = Eigen::Vector2d::Zero();  // the aim point, world frame
};

// One pure-pursuit step: the nearest point of the path at or after segment from_segment (pass the previous
// command's segment so a path that doubles back is not cut short), the aim point lookahead_m further along, and the
// arc to it. Throws std::invalid_argument naming the field when the path is empty or not finite, the pose is not
// finite or params are invalid.
PurePursuitCommand pure_pursuit(const Pose2& pose, std::span<const Eigen::Vector2d> path_W,
                                const PurePursuitParams& params, std::size_t from_segment = 0);

}  // namespace occgeo::service::control
