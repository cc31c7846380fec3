#include "occgeo/service/control/global_path.h"
#include "occgeo/geometry/pose.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <queue>
#include <stdexcept>
#include <string>

#include "param_checks.h"

namespace occgeo::service::control {
namespace {

using detail::require;
using detail::require_non_negative;
using detail::require_positive;

constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr double kSqrt2 = std::numbers::sqrt2;

using geometry::wrap_angle;

// A cell of the window as (column, row).
struct Local {
  int col = 0;
  int row = 0;
};

// The planner's view of one window: blocked cells, step weights and cell <-> index arithmetic.
class SearchGrid {
 public:
  SearchGrid(const PlanningWindow& window, const GlobalPathParams& params)
      : window_(window),
        blocked_(inflate(window, params.footprint_radius_m)),
        extra_(obstacle_cost(window, params)),
        unknown_factor_(1.0 + params.unknown_extra_cost) {}

  [[nodiscard]] int width() const { return window_.width; }
  [[nodiscard]] int height() const { return window_.height; }
  [[nodiscard]] std::size_t size() const { return window_.cells.size(); }
  [[nodiscard]] std::size_t index(Local c) const {
    return static_cast<std::size_t>(c.row) * static_cast<std::size_t>(window_.width) + static_cast<std::size_t>(c.col);
  }
  [[nodiscard]] Local local(std::size_t index) const {
    const auto width = static_cast<std::size_t>(window_.width);
    return {static_cast<int>(index % width), static_cast<int>(index / width)};
  }
  [[nodiscard]] bool inside(Local c) const { return c.col >= 0 && c.row >= 0 && c.col < width() && c.row < height(); }
  [[nodiscard]] bool occupied(std::size_t index) const { return window_.cells[index] == PlanningCell::kOccupied; }
  [[nodiscard]] bool blocked(std::size_t index) const { return blocked_[index]; }
  // Cost per metre of travel inside the cell.
  [[nodiscard]] double weight(std::size_t index) const {
    return (window_.cells[index] == PlanningCell::kUnknown ? unknown_factor_ : 1.0) +
           static_cast<double>(extra_[index]);
  }
  [[nodiscard]] double cell_size() const { return window_.cell_size_m; }
  [[nodiscard]] Eigen::Vector2d centre_W(Local c) const {
    return {(window_.origin.ix + c.col + 0.5) * window_.cell_size_m,
            (window_.origin.iy + c.row + 0.5) * window_.cell_size_m};
  }
  [[nodiscard]] geometry::CellIndex cell(Local c) const {
    return {window_.origin.ix + c.col, window_.origin.iy + c.row};
  }

  // Walks the segment from (ax, ay) to (ax + dx, ay + dy) (window cell coordinates: cell (col, row) covers
  // [col, col + 1) x [row, row + 1)) cell by cell (Amanatides–Woo, exact), calling visit(cell, fraction of the
  // segment inside it) in order; visit returns false to stop. True when the whole segment was visited.
  template <typename Visit>
  bool walk_cells(double ax, double ay, double dx, double dy, Visit&& visit) const {
    Local c{static_cast<int>(std::floor(ax)), static_cast<int>(std::floor(ay))};
    const int step_x = dx > 0 ? 1 : (dx < 0 ? -1 : 0);
    const int step_y = dy > 0 ? 1 : (dy < 0 ? -1 : 0);
    const double delta_x = step_x != 0 ? 1.0 / std::abs(dx) : kInfinity;
    const double delta_y = step_y != 0 ? 1.0 / std::abs(dy) : kInfinity;
    double next_x = step_x > 0 ? (c.col + 1 - ax) * delta_x : (step_x < 0 ? (ax - c.col) * delta_x : kInfinity);
    double next_y = step_y > 0 ? (c.row + 1 - ay) * delta_y : (step_y < 0 ? (ay - c.row) * delta_y : kInfinity);
    double t = 0.0;
    while (true) {
      const double t_exit = std::min({next_x, next_y, 1.0});
      if (!visit(c, t_exit - t)) return false;
      if (t_exit >= 1.0) return true;
      t = t_exit;
      if (next_x < next_y) {
        c.col += step_x;
        next_x += delta_x;
      } else if (next_y < next_x) {
        c.row += step_y;
        next_y += delta_y;
      } else {  // through a corner: the diagonal cell holds the corner point
        c.col += step_x;
        c.row += step_y;
        next_x += delta_x;
        next_y += delta_y;
      }
    }
  }

  // The cost of the segment between the centres of a and b (length in each cell times the cell's weight), or nullopt
  // when it enters a blocked cell. Every point of the segment lies in a visited cell, so within half a cell diagonal
  // of a free centre: the inflation margin keeps it footprint_radius_m clear.
  [[nodiscard]] std::optional<double> line_cost(Local a, Local b) const {
    const double dx = b.col - a.col;
    const double dy = b.row - a.row;
    const double length_m = std::hypot(dx, dy) * cell_size();
    double cost_m = 0.0;
    const bool clear = walk_cells(a.col + 0.5, a.row + 0.5, dx, dy, [&](Local c, double fraction) {
      if (!inside(c)) return false;  // cannot happen between two inside cells; guards the indexing
      const std::size_t i = index(c);
      if (blocked(i)) return false;
      cost_m += fraction * length_m * weight(i);
      return true;
    });
    return clear ? std::optional<double>(cost_m) : std::nullopt;
  }

  // The cost of the segment from a_W to b_W (world frame, any points) as line_cost gives it, or nullopt when it leaves
  // the window, enters an occupied cell, or enters a blocked cell while not `escaping`. escaping lets a walk that
  // starts in the inflated zone leave it: it is cleared at the first free cell.
  [[nodiscard]] std::optional<double> segment_cost(const Eigen::Vector2d& a_W, const Eigen::Vector2d& b_W,
                                                   bool& escaping) const {
    const double ax = a_W.x() / cell_size() - window_.origin.ix;
    const double ay = a_W.y() / cell_size() - window_.origin.iy;
    const double dx = b_W.x() / cell_size() - window_.origin.ix - ax;
    const double dy = b_W.y() / cell_size() - window_.origin.iy - ay;
    if (!(std::abs(ax) < geometry::GridGeometry::kMaxCellIndex &&
          std::abs(ay) < geometry::GridGeometry::kMaxCellIndex)) {
      return std::nullopt;
    }
    const double length_m = (b_W - a_W).norm();
    double cost_m = 0.0;
    const bool clear = walk_cells(ax, ay, dx, dy, [&](Local c, double fraction) {
      if (!inside(c)) return false;
      const std::size_t i = index(c);
      if (occupied(i)) return false;
      if (!blocked(i)) {
        escaping = false;
      } else if (!escaping) {
        return false;
      }
      cost_m += fraction * length_m * weight(i);
      return true;
    });
    return clear ? std::optional<double>(cost_m) : std::nullopt;
  }

  // The cost of the polyline, as path_cost documents it.
  [[nodiscard]] std::optional<double> polyline_cost(std::span<const Eigen::Vector2d> path_W) const {
    if (path_W.empty()) return std::nullopt;
    bool escaping = true;
    double total_m = 0.0;
    for (std::size_t k = 0; k + 1 < path_W.size(); ++k) {
      const std::optional<double> piece = segment_cost(path_W[k], path_W[k + 1], escaping);
      if (!piece) return std::nullopt;
      total_m += *piece;
    }
    if (path_W.size() == 1) {
      const std::optional<double> here = segment_cost(path_W[0], path_W[0], escaping);
      if (!here) return std::nullopt;
    }
    return total_m;
  }

 private:
  const PlanningWindow& window_;
  std::vector<bool> blocked_;
  std::vector<float> extra_;
  double unknown_factor_;
};

void check_window(const PlanningWindow& window) {
  require(window.width > 0, "window.width", "must be positive", window.width);
  require(window.height > 0, "window.height", "must be positive", window.height);
  require_positive("window.cell_size_m", window.cell_size_m);
  require(window.cells.size() == static_cast<std::size_t>(window.width) * static_cast<std::size_t>(window.height),
          "window.cells", "must hold width * height cells", static_cast<double>(window.cells.size()));
}

// The window cell holding p_W, or nullopt when it lies outside.
std::optional<Local> local_of(const PlanningWindow& window, const Eigen::Vector2d& p_W) {
  const double fx = std::floor(p_W.x() / window.cell_size_m) - window.origin.ix;
  const double fy = std::floor(p_W.y() / window.cell_size_m) - window.origin.iy;
  if (fx < 0.0 || fy < 0.0 || fx >= window.width || fy >= window.height) return std::nullopt;
  return Local{static_cast<int>(fx), static_cast<int>(fy)};
}

// Octile distance between cells, metres: a lower bound of any path's cost since weights are >= 1.
double octile_m(Local a, Local b, double cell_size_m) {
  const int dx = std::abs(a.col - b.col);
  const int dy = std::abs(a.row - b.row);
  return cell_size_m * (std::max(dx, dy) + (kSqrt2 - 1.0) * std::min(dx, dy));
}

void check_path(std::span<const Eigen::Vector2d> path_W, const char* field) {
  for (std::size_t i = 0; i < path_W.size(); ++i) {
    if (!path_W[i].allFinite()) {
      throw std::invalid_argument(std::string(field) + "[" + std::to_string(i) + "] must be finite");
    }
  }
}

}  // namespace

void GlobalPathParams::validate() const {
  require(std::isfinite(footprint_radius_m) && footprint_radius_m >= 0.0 && footprint_radius_m <= 5.0,
          "footprint_radius_m", "must be in [0, 5] metres", footprint_radius_m);
  require_non_negative("unknown_extra_cost", unknown_extra_cost);
  require(std::isfinite(cost_radius_m) && cost_radius_m >= 0.0 && cost_radius_m <= 5.0, "cost_radius_m",
          "must be in [0, 5] metres", cost_radius_m);
  require_non_negative("near_obstacle_extra_cost", near_obstacle_extra_cost);
  require(occupied_threshold >= 0 && occupied_threshold <= 255, "occupied_threshold", "must be in [0, 255]",
          occupied_threshold);
  require_non_negative("window_margin_m", window_margin_m);
  require(max_window_cells >= 1 && max_window_cells <= 65536, "max_window_cells", "must be in [1, 65536]",
          max_window_cells);
  require(max_expansions >= 1, "max_expansions", "must be at least 1", static_cast<double>(max_expansions));
  check_path(current_path_W, "current_path_W");
  require_non_negative("keep_min_gain_m", keep_min_gain_m);
  require(std::isfinite(keep_min_gain_fraction) && keep_min_gain_fraction >= 0.0 && keep_min_gain_fraction < 1.0,
          "keep_min_gain_fraction", "must be in [0, 1)", keep_min_gain_fraction);
}

void PurePursuitParams::validate() const {
  require_positive("lookahead_m", lookahead_m);
  require_positive("linear_speed_mps", linear_speed_mps);
  require_positive("max_angular_radps", max_angular_radps);
  require_positive("goal_tolerance_m", goal_tolerance_m);
  require(std::isfinite(rotate_in_place_rad) && rotate_in_place_rad > 0.0 && rotate_in_place_rad <= std::numbers::pi,
          "rotate_in_place_rad", "must be in (0, pi] radians", rotate_in_place_rad);
  require_non_negative("slowdown_distance_m", slowdown_distance_m);
}

std::string_view to_string(GlobalPathStatus status) {
  switch (status) {
    case GlobalPathStatus::kFound:
      return "found";
    case GlobalPathStatus::kStartOccupied:
      return "start_occupied";
    case GlobalPathStatus::kGoalBlocked:
      return "goal_blocked";
    case GlobalPathStatus::kWindowTooLarge:
      return "window_too_large";
    case GlobalPathStatus::kExpansionLimit:
      return "expansion_limit";
    case GlobalPathStatus::kNoPath:
      return "no_path";
  }
  return "unknown";
}

PlanningWindow planning_window(const mapping::GridSnapshot& grid, geometry::CellIndex min, geometry::CellIndex max,
                               int occupied_threshold) {
  const std::int64_t width = static_cast<std::int64_t>(max.ix) - min.ix + 1;
  const std::int64_t height = static_cast<std::int64_t>(max.iy) - min.iy + 1;
  require(width >= 1 && width <= 65536, "max.ix", "must be in [min.ix, min.ix + 65535]", static_cast<double>(max.ix));
  require(height >= 1 && height <= 65536, "max.iy", "must be in [min.iy, min.iy + 65535]", static_cast<double>(max.iy));
  const int threshold = occupied_threshold > 0 ? occupied_threshold : grid.occupied_threshold();
  PlanningWindow window;
  window.origin = min;
  window.width = static_cast<int>(width);
  window.height = static_cast<int>(height);
  window.cell_size_m = grid.cell_size();
  const std::vector<std::uint8_t> values = grid.window(min, window.width, window.height);
  window.cells.reserve(values.size());
  for (const std::uint8_t value : values) {
    if (value == mapping::kUnobserved) {
      window.cells.push_back(PlanningCell::kUnknown);
    } else {
      window.cells.push_back(value >= threshold ? PlanningCell::kOccupied : PlanningCell::kFree);
    }
  }
  return window;
}

std::vector<bool> inflate(const PlanningWindow& window, double footprint_radius_m) {
  check_window(window);
  require(std::isfinite(footprint_radius_m) && footprint_radius_m >= 0.0 && footprint_radius_m <= 5.0,
          "footprint_radius_m", "must be in [0, 5] metres", footprint_radius_m);
  // In cells: a centre is blocked when closer than this to an occupied cell's square.
  const double reach = footprint_radius_m / window.cell_size_m + kSqrt2 / 2.0;
  const int span = static_cast<int>(std::ceil(reach)) + 1;
  struct Offset {
    int dx, dy;
  };
  std::vector<Offset> offsets;
  for (int dy = -span; dy <= span; ++dy) {
    for (int dx = -span; dx <= span; ++dx) {
      const double gap_x = std::max(0.0, std::abs(dx) - 0.5);
      const double gap_y = std::max(0.0, std::abs(dy) - 0.5);
      if (std::hypot(gap_x, gap_y) < reach) offsets.push_back({dx, dy});
    }
  }
  const auto occupied = [&](int col, int row) {
    return col >= 0 && row >= 0 && col < window.width && row < window.height &&
           window.cells[static_cast<std::size_t>(row) * static_cast<std::size_t>(window.width) +
                        static_cast<std::size_t>(col)] == PlanningCell::kOccupied;
  };
  std::vector<bool> blocked(window.cells.size(), false);
  for (int row = 0; row < window.height; ++row) {
    for (int col = 0; col < window.width; ++col) {
      if (!occupied(col, row)) continue;
      blocked[static_cast<std::size_t>(row) * static_cast<std::size_t>(window.width) + static_cast<std::size_t>(col)] =
          true;
      // A cell inside a blob of occupied cells is never the nearest one to a cell outside it (stepping from it toward
      // that cell along an axis reaches an edge cell no farther away), so only edge cells spread the margin. Cells
      // beyond the window count as not occupied, so the window's border cells are edges too.
      if (occupied(col - 1, row) && occupied(col + 1, row) && occupied(col, row - 1) && occupied(col, row + 1)) {
        continue;
      }
      for (const Offset& offset : offsets) {
        const int c = col + offset.dx;
        const int r = row + offset.dy;
        if (c < 0 || r < 0 || c >= window.width || r >= window.height) continue;
        blocked[static_cast<std::size_t>(r) * static_cast<std::size_t>(window.width) + static_cast<std::size_t>(c)] =
            true;
      }
    }
  }
  return blocked;
}

std::vector<float> obstacle_cost(const PlanningWindow& window, const GlobalPathParams& params) {
  check_window(window);
  params.validate();
  std::vector<float> extra(window.cells.size(), 0.0F);
  if (params.cost_radius_m <= params.footprint_radius_m || params.near_obstacle_extra_cost <= 0.0) return extra;
  // In cells, from a centre to an occupied cell's square: full extra cost at `hard`, none from `soft` on.
  const double hard = params.footprint_radius_m / window.cell_size_m + kSqrt2 / 2.0;
  const double soft = params.cost_radius_m / window.cell_size_m + kSqrt2 / 2.0;
  const int span = static_cast<int>(std::ceil(soft)) + 1;
  struct Offset {
    int dx, dy;
    float extra;
  };
  std::vector<Offset> offsets;
  for (int dy = -span; dy <= span; ++dy) {
    for (int dx = -span; dx <= span; ++dx) {
      const double gap = std::hypot(std::max(0.0, std::abs(dx) - 0.5), std::max(0.0, std::abs(dy) - 0.5));
      if (gap >= soft) continue;
      const double fraction = std::clamp((soft - gap) / (soft - hard), 0.0, 1.0);
      offsets.push_back({dx, dy, static_cast<float>(params.near_obstacle_extra_cost * fraction)});
    }
  }
  const auto occupied = [&](int col, int row) {
    return col >= 0 && row >= 0 && col < window.width && row < window.height &&
           window.cells[static_cast<std::size_t>(row) * static_cast<std::size_t>(window.width) +
                        static_cast<std::size_t>(col)] == PlanningCell::kOccupied;
  };
  for (int row = 0; row < window.height; ++row) {
    for (int col = 0; col < window.width; ++col) {
      // As in inflate: only edge cells of an occupied blob can be the nearest one to a cell outside it.
      if (!occupied(col, row) ||
          (occupied(col - 1, row) && occupied(col + 1, row) && occupied(col, row - 1) && occupied(col, row + 1))) {
        continue;
      }
      for (const Offset& offset : offsets) {
        const int c = col + offset.dx;
        const int r = row + offset.dy;
        if (c < 0 || r < 0 || c >= window.width || r >= window.height) continue;
        float& cell =
            extra[static_cast<std::size_t>(r) * static_cast<std::size_t>(window.width) + static_cast<std::size_t>(c)];
        cell = std::max(cell, offset.extra);
      }
    }
  }
  return extra;
}

namespace {

// A* and shortcuts from start_W to goal_W on the grid (both inside the window); the current path is not looked at.
GlobalPathResult search_path(const SearchGrid& grid, const PlanningWindow& window, const Eigen::Vector2d& start_W,
                             const Eigen::Vector2d& goal_W, const GlobalPathParams& params) {
  const std::optional<Local> start = local_of(window, start_W);
  const std::optional<Local> goal = local_of(window, goal_W);
  GlobalPathResult result;
  const std::size_t start_index = grid.index(*start);
  const std::size_t goal_index = grid.index(*goal);
  if (grid.occupied(start_index)) {
    result.status = GlobalPathStatus::kStartOccupied;
    return result;
  }
  if (grid.blocked(goal_index)) {
    result.status = GlobalPathStatus::kGoalBlocked;
    return result;
  }

  // A*, 8-connected; a step costs its length times the weight of the cell it enters. A start inside the inflated zone
  // may move through that zone (never into an occupied cell) until it reaches free cells, and never back.
  std::vector<double> cost_to(grid.size(), kInfinity);
  std::vector<std::int64_t> parent(grid.size(), -1);
  std::vector<bool> closed(grid.size(), false);
  struct Open {
    double estimate_m;
    double cost_m;
    std::size_t index;
    // Smallest estimate first; ties: larger cost (deeper), then smaller index, so runs are reproducible.
    bool operator>(const Open& other) const {
      if (estimate_m != other.estimate_m) return estimate_m > other.estimate_m;
      if (cost_m != other.cost_m) return cost_m < other.cost_m;
      return index > other.index;
    }
  };
  std::priority_queue<Open, std::vector<Open>, std::greater<>> open;
  cost_to[start_index] = 0.0;
  open.push({octile_m(*start, *goal, grid.cell_size()), 0.0, start_index});
  bool found = false;
  while (!open.empty()) {
    const Open top = open.top();
    open.pop();
    if (closed[top.index]) continue;
    if (result.expansions >= params.max_expansions) {
      result.status = GlobalPathStatus::kExpansionLimit;
      return result;
    }
    closed[top.index] = true;
    ++result.expansions;
    if (top.index == goal_index) {
      found = true;
      break;
    }
    const Local here = grid.local(top.index);
    const bool escaping = grid.blocked(top.index);
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        if (dx == 0 && dy == 0) continue;
        const Local next{here.col + dx, here.row + dy};
        if (!grid.inside(next)) continue;
        const std::size_t next_index = grid.index(next);
        if (closed[next_index] || grid.occupied(next_index)) continue;
        if (!escaping && grid.blocked(next_index)) continue;
        const double step_m = (dx != 0 && dy != 0 ? kSqrt2 : 1.0) * grid.cell_size() * grid.weight(next_index);
        const double cost_m = top.cost_m + step_m;
        if (cost_m < cost_to[next_index]) {
          cost_to[next_index] = cost_m;
          parent[next_index] = static_cast<std::int64_t>(top.index);
          open.push({cost_m + octile_m(next, *goal, grid.cell_size()), cost_m, next_index});
        }
      }
    }
  }
  if (!found) {
    result.status = GlobalPathStatus::kNoPath;
    return result;
  }

  std::vector<Local> path;
  for (std::int64_t i = static_cast<std::int64_t>(goal_index); i >= 0; i = parent[static_cast<std::size_t>(i)]) {
    path.push_back(grid.local(static_cast<std::size_t>(i)));
  }
  std::reverse(path.begin(), path.end());
  result.status = GlobalPathStatus::kFound;
  result.cost_m = cost_to[goal_index];
  for (const Local& c : path) result.cells.push_back(grid.cell(c));

  // Shortcuts: from each kept cell, go straight to the farthest following cell the line reaches without entering a
  // blocked cell and without costing more than the cell path between them (compared by the same per-cell measure).
  std::vector<double> along_m(path.size(), 0.0);  // per-cell cost of the cell path up to each cell
  for (std::size_t i = 1; i < path.size(); ++i) {
    const std::optional<double> step = grid.line_cost(path[i - 1], path[i]);
    // A step out of the inflated zone around the start has no line cost; count its A* cost instead.
    along_m[i] = along_m[i - 1] + step.value_or(cost_to[grid.index(path[i])] - cost_to[grid.index(path[i - 1])]);
  }
  std::vector<std::size_t> kept{0};
  std::size_t anchor = 0;
  while (anchor + 1 < path.size()) {
    std::size_t best = anchor + 1;
    if (params.smooth) {
      for (std::size_t j = anchor + 2; j < path.size(); ++j) {
        const std::optional<double> cost = grid.line_cost(path[anchor], path[j]);
        if (!cost.has_value() || *cost > along_m[j] - along_m[anchor] + 1e-9) break;
        best = j;
      }
    }
    kept.push_back(best);
    anchor = best;
  }
  result.waypoints_W.push_back(start_W);
  for (std::size_t k = 1; k < kept.size(); ++k) {
    const std::optional<double> cost = grid.line_cost(path[kept[k - 1]], path[kept[k]]);
    result.smoothed_cost_m += cost.value_or(along_m[kept[k]] - along_m[kept[k - 1]]);
    if (k + 1 < kept.size()) result.waypoints_W.push_back(grid.centre_W(path[kept[k]]));
  }
  result.waypoints_W.push_back(goal_W);

  return result;
}

// The part of path_W before its first blocked leg, ending at a vertex (at least the first leg must be clear); empty
// when even that is blocked.
std::vector<Eigen::Vector2d> clear_prefix(const SearchGrid& grid, std::span<const Eigen::Vector2d> path_W) {
  std::vector<Eigen::Vector2d> prefix;
  bool escaping = true;
  for (std::size_t k = 0; k + 1 < path_W.size(); ++k) {
    if (!grid.segment_cost(path_W[k], path_W[k + 1], escaping)) break;
    if (prefix.empty()) prefix.push_back(path_W[k]);
    prefix.push_back(path_W[k + 1]);
  }
  return prefix;
}

}  // namespace

GlobalPathResult plan_global_path(const PlanningWindow& window, const Eigen::Vector2d& start_W,
                                  const Eigen::Vector2d& goal_W, const GlobalPathParams& params) {
  params.validate();
  check_window(window);
  require(start_W.allFinite(), "start_W", "must be finite", start_W.x());
  require(goal_W.allFinite(), "goal_W", "must be finite", goal_W.x());
  require(local_of(window, start_W).has_value(), "start_W", "must lie inside the window", start_W.x());
  require(local_of(window, goal_W).has_value(), "goal_W", "must lie inside the window", goal_W.x());

  const SearchGrid grid(window, params);
  GlobalPathResult result = search_path(grid, window, start_W, goal_W, params);
  if (result.status != GlobalPathStatus::kFound || params.current_path_W.size() < 2) return result;

  // Hysteresis: the path being followed is kept while it is clear and the new one is not clearly cheaper. When the
  // growing map blocks it further on, its clear part is kept and only the rest re-planned, so a wall coming into
  // view does not send the robot back to try the other way round (seen free cells are cheaper than unknown ones, and
  // the robot has seen most of where it came from), unless that other way is clearly cheaper.
  std::vector<Eigen::Vector2d> kept_W;
  result.current_cost_m = grid.polyline_cost(params.current_path_W);
  std::optional<double> kept_cost_m = result.current_cost_m;
  if (kept_cost_m) {
    kept_W = params.current_path_W;
  } else {
    std::vector<Eigen::Vector2d> prefix_W = clear_prefix(grid, params.current_path_W);
    if (prefix_W.size() >= 2 && local_of(window, prefix_W.back())) {
      const GlobalPathResult rest = search_path(grid, window, prefix_W.back(), goal_W, params);
      if (rest.status == GlobalPathStatus::kFound) {
        prefix_W.insert(prefix_W.end(), rest.waypoints_W.begin() + 1, rest.waypoints_W.end());
        kept_cost_m = grid.polyline_cost(prefix_W);
        if (kept_cost_m) kept_W = std::move(prefix_W);
      }
    }
  }
  const double new_cost_m = grid.polyline_cost(result.waypoints_W).value_or(result.smoothed_cost_m);
  if (kept_cost_m) {
    const double gain_needed_m = std::max(params.keep_min_gain_m, params.keep_min_gain_fraction * *kept_cost_m);
    if (new_cost_m > *kept_cost_m - gain_needed_m) {
      result.waypoints_W = std::move(kept_W);
      result.kept_current = true;
    }
  }
  return result;
}

std::optional<double> path_cost(const PlanningWindow& window, std::span<const Eigen::Vector2d> path_W,
                                const GlobalPathParams& params) {
  params.validate();
  check_window(window);
  check_path(path_W, "path_W");
  const SearchGrid grid(window, params);
  return grid.polyline_cost(path_W);
}

std::optional<PlanningWindow> window_around(const mapping::GridSnapshot& grid, const Eigen::Vector2d& start_W,
                                            const Eigen::Vector2d& goal_W, const GlobalPathParams& params) {
  params.validate();
  const geometry::GridGeometry cells(grid.cell_size());
  const std::optional<geometry::CellIndex> start = cells.checked_cell_of(start_W);
  const std::optional<geometry::CellIndex> goal = cells.checked_cell_of(goal_W);
  require(start.has_value(), "start_W", "must be finite and within 2^30 cells of the origin", start_W.x());
  require(goal.has_value(), "goal_W", "must be finite and within 2^30 cells of the origin", goal_W.x());
  // In doubles: the margin may take a cell near the limit beyond int32.
  const double margin_cells = std::ceil(params.window_margin_m / grid.cell_size());
  const double min_x = std::min(start->ix, goal->ix) - margin_cells;
  const double min_y = std::min(start->iy, goal->iy) - margin_cells;
  const double max_x = std::max(start->ix, goal->ix) + margin_cells;
  const double max_y = std::max(start->iy, goal->iy) + margin_cells;
  if (max_x - min_x + 1.0 > params.max_window_cells || max_y - min_y + 1.0 > params.max_window_cells) {
    return std::nullopt;
  }
  return planning_window(grid, {static_cast<std::int32_t>(min_x), static_cast<std::int32_t>(min_y)},
                         {static_cast<std::int32_t>(max_x), static_cast<std::int32_t>(max_y)},
                         params.occupied_threshold);
}

GlobalPathResult plan_global_path(const mapping::GridSnapshot& grid, const Eigen::Vector2d& start_W,
                                  const Eigen::Vector2d& goal_W, const GlobalPathParams& params) {
  const std::optional<PlanningWindow> window = window_around(grid, start_W, goal_W, params);
  if (!window) {
    GlobalPathResult result;
    result.status = GlobalPathStatus::kWindowTooLarge;
    return result;
  }
  return plan_global_path(*window, start_W, goal_W, params);
}

bool segment_clear(const mapping::GridSnapshot& grid, const Eigen::Vector2d& a_W, const Eigen::Vector2d& b_W,
                   double radius_m) {
  require(a_W.allFinite(), "a_W", "must be finite", a_W.x());
  require(b_W.allFinite(), "b_W", "must be finite", b_W.x());
  require(std::isfinite(radius_m) && radius_m >= 0.0 && radius_m <= 5.0, "radius_m", "must be in [0, 5] metres",
          radius_m);
  const double cell_m = grid.cell_size();
  const Eigen::Vector2d lo = a_W.cwiseMin(b_W).array() - radius_m - cell_m;
  const Eigen::Vector2d hi = a_W.cwiseMax(b_W).array() + radius_m + cell_m;
  const geometry::GridGeometry cells(cell_m);
  const std::optional<geometry::CellIndex> min = cells.checked_cell_of(lo);
  const std::optional<geometry::CellIndex> max = cells.checked_cell_of(hi);
  require(min && max, "a_W", "must lie within 2^30 cells of the origin", a_W.x());
  const Eigen::Vector2d along = b_W - a_W;
  const double length_sq = along.squaredNorm();
  // A cell's square reaches half a diagonal beyond its centre.
  const double reach_m = radius_m + cell_m * kSqrt2 / 2.0;
  bool clear = true;
  grid.for_each_occupied(*min, *max, [&](const geometry::CellIndex& c) {
    const Eigen::Vector2d centre((c.ix + 0.5) * cell_m, (c.iy + 0.5) * cell_m);
    const double t = length_sq > 0.0 ? std::clamp((centre - a_W).dot(along) / length_sq, 0.0, 1.0) : 0.0;
    if ((a_W + t * along - centre).norm() < reach_m) clear = false;
    return clear;
  });
  return clear;
}

PurePursuitCommand pure_pursuit(const Pose2& pose, std::span<const Eigen::Vector2d> path_W,
                                const PurePursuitParams& params, std::size_t from_segment) {
  params.validate();
  require(std::isfinite(pose.x), "pose.x", "must be finite", pose.x);
  require(std::isfinite(pose.y), "pose.y", "must be finite", pose.y);
  require(std::isfinite(pose.theta), "pose.theta", "must be finite", pose.theta);
  require(!path_W.empty(), "path_W", "must not be empty", 0.0);
  for (std::size_t i = 0; i < path_W.size(); ++i) {
    if (!path_W[i].allFinite()) throw std::invalid_argument("path_W[" + std::to_string(i) + "] must be finite");
  }
  const Eigen::Vector2d p_W(pose.x, pose.y);
  PurePursuitCommand command;
  const std::size_t segments = path_W.size() - 1;
  const Eigen::Vector2d& end_W = path_W.back();
  if ((end_W - p_W).norm() <= params.goal_tolerance_m) {
    command.reached = true;
    command.segment = segments == 0 ? 0 : segments - 1;
    command.aim_W = end_W;
    return command;
  }

  // The nearest point on the path at or after from_segment.
  std::size_t nearest_segment = 0;
  double nearest_t = 0.0;
  double nearest_m = kInfinity;
  const std::size_t first = segments == 0 ? 0 : std::min(from_segment, segments - 1);
  for (std::size_t i = first; i < segments; ++i) {
    const Eigen::Vector2d along = path_W[i + 1] - path_W[i];
    const double length_sq = along.squaredNorm();
    const double t = length_sq > 0.0 ? std::clamp((p_W - path_W[i]).dot(along) / length_sq, 0.0, 1.0) : 0.0;
    const double distance_m = (path_W[i] + t * along - p_W).norm();
    if (distance_m < nearest_m) {
      nearest_m = distance_m;
      nearest_segment = i;
      nearest_t = t;
    }
  }
  command.segment = nearest_segment;

  // The aim point: lookahead_m further along the path from the nearest point, or the end.
  Eigen::Vector2d aim_W = end_W;
  double remaining_m = params.lookahead_m;
  double to_end_m = 0.0;
  if (segments > 0) {
    Eigen::Vector2d from_W =
        path_W[nearest_segment] + nearest_t * (path_W[nearest_segment + 1] - path_W[nearest_segment]);
    bool aimed = false;
    for (std::size_t i = nearest_segment; i < segments; ++i) {
      const double piece_m = (path_W[i + 1] - from_W).norm();
      if (!aimed && piece_m >= remaining_m && piece_m > 0.0) {
        aim_W = from_W + (path_W[i + 1] - from_W) * (remaining_m / piece_m);
        aimed = true;
      }
      if (!aimed) remaining_m -= piece_m;
      to_end_m += piece_m;
      from_W = path_W[i + 1];
    }
  }
  to_end_m = std::max(to_end_m, (end_W - p_W).norm());
  command.aim_W = aim_W;

  const Eigen::Vector2d to_aim = aim_W - p_W;
  const double heading_error_rad = wrap_angle(std::atan2(to_aim.y(), to_aim.x()) - pose.theta);
  if (std::abs(heading_error_rad) > params.rotate_in_place_rad) {
    command.angular_radps = std::copysign(params.max_angular_radps, heading_error_rad);
    return command;
  }
  double speed_mps = params.linear_speed_mps;
  if (params.slowdown_distance_m > 0.0) speed_mps *= std::min(1.0, to_end_m / params.slowdown_distance_m);
  speed_mps = std::max(speed_mps, 0.1 * params.linear_speed_mps);  // never creep below a tenth of cruise
  // The arc through the aim point: curvature 2 sin(error) / distance.
  const double distance_m = to_aim.norm();
  const double curvature = distance_m > 0.0 ? 2.0 * std::sin(heading_error_rad) / distance_m : 0.0;
  double angular_radps = speed_mps * curvature;
  if (std::abs(angular_radps) > params.max_angular_radps) {
    // Keep the arc, slow down.
    speed_mps *= params.max_angular_radps / std::abs(angular_radps);
    angular_radps = std::copysign(params.max_angular_radps, angular_radps);
  }
  command.linear_mps = speed_mps;
  command.angular_radps = angular_radps;
  return command;
}

}  // namespace occgeo::service::control
