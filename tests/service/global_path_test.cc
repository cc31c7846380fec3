// The global path for deadlock escape: out of the U-shaped trap of seed 000 Fig 5.3 on a real HIMM grid snapshot,
// inflation that keeps every point of the path a footprint radius from the walls, the "no path" reasons, unknown
// cells at an extra cost, A*'s cost against a brute-force Dijkstra on hundreds of random grids, and the pure-pursuit
// follower driving a kinematic robot along a path.
#include "occgeo/service/control/global_path.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "occgeo/mapfile/map_file.h"
#include "occgeo/mapping/himm_grid.h"

namespace occgeo::service::control {
namespace {

constexpr double kCell = 0.1;
constexpr double kInfinity = std::numeric_limits<double>::infinity();

// A world of cells from cell (0, 0): '#' occupied, '.' free (observed), '?' never observed.
struct World {
  int width = 0;
  int height = 0;
  std::vector<char> cells;  // row-major, row 0 at y = 0

  World(int w, int h, char fill) : width(w), height(h), cells(static_cast<std::size_t>(w) * h, fill) {}
  char& at(int x, int y) { return cells[static_cast<std::size_t>(y) * width + x]; }
  char at(int x, int y) const { return cells[static_cast<std::size_t>(y) * width + x]; }
  void fill(int x0, int y0, int x1, int y1, char value) {
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) at(x, y) = value;
    }
  }

  // As a map_server image whose grey levels HimmGrid::from_image reads as certainty 15, 0 or unobserved.
  [[nodiscard]] mapfile::OccupancyImage image() const {
    mapfile::OccupancyImage image;
    image.width = static_cast<std::uint32_t>(width);
    image.height = static_cast<std::uint32_t>(height);
    image.resolution = kCell;
    image.pixels.resize(cells.size());
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        const char c = at(x, y);
        image.pixels[static_cast<std::size_t>(height - 1 - y) * width + x] = c == '#' ? 0 : (c == '.' ? 254 : 205);
      }
    }
    return image;
  }
  [[nodiscard]] std::shared_ptr<const mapping::GridSnapshot> snapshot() const {
    return mapping::HimmGrid::from_image(image(), mapping::HimmParams{}).snapshot();
  }
  [[nodiscard]] PlanningWindow window() const {
    PlanningWindow window;
    window.origin = {0, 0};
    window.width = width;
    window.height = height;
    window.cell_size_m = kCell;
    for (const char c : cells) {
      window.cells.push_back(c == '#' ? PlanningCell::kOccupied
                                      : (c == '.' ? PlanningCell::kFree : PlanningCell::kUnknown));
    }
    return window;
  }
};

// Distance from p to the square of cell (x, y).
double distance_to_cell(const Eigen::Vector2d& p, int x, int y) {
  const double dx = std::max({x * kCell - p.x(), 0.0, p.x() - (x + 1) * kCell});
  const double dy = std::max({y * kCell - p.y(), 0.0, p.y() - (y + 1) * kCell});
  return std::hypot(dx, dy);
}

// Smallest distance from any point of the polyline (sampled every millimetre) to an occupied cell.
double wall_clearance(const std::vector<Eigen::Vector2d>& path, const World& world) {
  double best = kInfinity;
  for (std::size_t i = 0; i + 1 < path.size(); ++i) {
    const int samples = std::max(1, static_cast<int>(std::ceil((path[i + 1] - path[i]).norm() / 0.001)));
    for (int k = 0; k <= samples; ++k) {
      const Eigen::Vector2d p = path[i] + (path[i + 1] - path[i]) * (static_cast<double>(k) / samples);
      for (int y = 0; y < world.height; ++y) {
        for (int x = 0; x < world.width; ++x) {
          if (world.at(x, y) == '#') best = std::min(best, distance_to_cell(p, x, y));
        }
      }
    }
  }
  return best;
}

double length(const std::vector<Eigen::Vector2d>& path) {
  double total = 0.0;
  for (std::size_t i = 0; i + 1 < path.size(); ++i) total += (path[i + 1] - path[i]).norm();
  return total;
}

// Seed 000 Fig 5.3: a U whose closed end stands between the robot, inside it, and the goal. Walls one cell thick:
// the arms along y = 1 m and y = 3 m from x = 2 m to 4 m, the closed end along x = 4 m.
World u_trap(char fill) {
  World world(60, 40, fill);
  world.fill(20, 10, 40, 10, '#');
  world.fill(20, 30, 40, 30, '#');
  world.fill(40, 10, 40, 30, '#');
  return world;
}

TEST(GlobalPath, LeadsOutOfTheUTrapAndRoundToTheGoal) {
  const World world = u_trap('.');
  const auto snapshot = world.snapshot();
  GlobalPathParams params;
  params.footprint_radius_m = 0.25;
  const Eigen::Vector2d start(3.25, 2.05);
  const Eigen::Vector2d goal(5.25, 2.05);
  const GlobalPathResult result = plan_global_path(*snapshot, start, goal, params);
  ASSERT_EQ(result.status, GlobalPathStatus::kFound) << to_string(result.status);
  ASSERT_GE(result.waypoints_W.size(), 3U);
  EXPECT_TRUE(result.waypoints_W.front().isApprox(start));
  EXPECT_TRUE(result.waypoints_W.back().isApprox(goal));
  // Out through the mouth (x < 2 m), round an arm (beyond y = 3 m or below y = 1 m) and in to the goal.
  double min_x = kInfinity;
  double max_off_m = 0.0;
  for (const Eigen::Vector2d& p : result.waypoints_W) {
    min_x = std::min(min_x, p.x());
    max_off_m = std::max(max_off_m, std::abs(p.y() - 2.0));
  }
  EXPECT_LT(min_x, 2.0);
  EXPECT_GT(max_off_m, 1.0 + params.footprint_radius_m);
  EXPECT_GE(wall_clearance(result.waypoints_W, world), params.footprint_radius_m - 1e-9);
  // Out about 1.25 m, along and back round about 4.5 m, in again about 1.25 m; shortcuts only shorten it.
  EXPECT_GT(length(result.waypoints_W), 5.5);
  EXPECT_LE(result.smoothed_cost_m, result.cost_m + 1e-9);
  EXPECT_LT(result.waypoints_W.size(), 12U);  // shortcuts leave a handful of corners, not a staircase
}

TEST(GlobalPath, CrossesUnknownSpaceWhenThatIsAllThereIs) {
  // The robot has only seen the U and its inside; everything else is unknown.
  World world = u_trap('?');
  world.fill(21, 11, 39, 29, '.');
  const auto snapshot = world.snapshot();
  const GlobalPathResult result = plan_global_path(*snapshot, {3.25, 2.05}, {5.25, 2.05}, GlobalPathParams{});
  ASSERT_EQ(result.status, GlobalPathStatus::kFound) << to_string(result.status);
  EXPECT_GE(wall_clearance(result.waypoints_W, world), GlobalPathParams{}.footprint_radius_m - 1e-9);
  // The way round lies in unknown space.
  EXPECT_TRUE(std::any_of(result.cells.begin(), result.cells.end(),
                          [&](const geometry::CellIndex& c) { return world.at(c.ix, c.iy) == '?'; }));
}

TEST(GlobalPath, PrefersSeenFreeSpaceOverUnknownAtAHighExtraCost) {
  // A 2 m unknown block straight between start and goal; a known free way round it over the top.
  World world(40, 40, '.');
  world.fill(10, 0, 29, 29, '?');
  const Eigen::Vector2d start(0.55, 0.55);
  const Eigen::Vector2d goal(3.55, 0.55);
  GlobalPathParams params;
  params.footprint_radius_m = 0.0;
  params.unknown_extra_cost = 0.0;
  const GlobalPathResult cheap = plan_global_path(world.window(), start, goal, params);
  ASSERT_EQ(cheap.status, GlobalPathStatus::kFound);
  EXPECT_NEAR(cheap.cost_m, 3.0, 1e-9);  // straight through
  params.unknown_extra_cost = 5.0;
  const GlobalPathResult wary = plan_global_path(world.window(), start, goal, params);
  ASSERT_EQ(wary.status, GlobalPathStatus::kFound);
  for (const geometry::CellIndex& c : wary.cells) EXPECT_NE(world.at(c.ix, c.iy), '?') << c.ix << ", " << c.iy;
  EXPECT_GT(wary.cost_m, 6.0);        // up 2.5 m, across, down again
  EXPECT_LT(wary.cost_m, 3.0 * 6.0);  // still cheaper than 3 m of unknown at 6 times the cost
}

TEST(GlobalPath, InflationKeepsTheFootprintRadiusAndClosesNarrowGaps) {
  // A wall across the world at x = 2 m with one gap; footprint 0.25 m, so a cell centre must keep
  // 0.25 + 0.0707 m (half a cell diagonal) from the wall: a 0.7 m gap passes, a 0.6 m gap does not.
  for (const int gap_cells : {7, 6}) {
    World world(40, 30, '.');
    world.fill(20, 0, 20, 29, '#');
    world.fill(20, 12, 20, 11 + gap_cells, '.');
    GlobalPathParams params;
    params.footprint_radius_m = 0.25;
    const GlobalPathResult result = plan_global_path(world.window(), {0.55, 0.55}, {3.55, 2.55}, params);
    if (gap_cells == 7) {
      ASSERT_EQ(result.status, GlobalPathStatus::kFound) << to_string(result.status);
      EXPECT_GE(wall_clearance(result.waypoints_W, world), params.footprint_radius_m - 1e-9);
      EXPECT_LT(wall_clearance(result.waypoints_W, world), 0.36);  // it does use the gap, through its middle
    } else {
      EXPECT_EQ(result.status, GlobalPathStatus::kNoPath) << to_string(result.status);
      EXPECT_GT(result.expansions, 100U);  // the whole start side was searched
    }
  }
}

// The largest distance from a wall any point of the path keeps, sampled every centimetre.
double farthest_from_wall(const std::vector<Eigen::Vector2d>& path, double wall_top_y) {
  double best = 0.0;
  for (std::size_t i = 0; i + 1 < path.size(); ++i) {
    for (int k = 0; k <= 100; ++k) {
      const Eigen::Vector2d p = path[i] + (path[i + 1] - path[i]) * (k / 100.0);
      best = std::max(best, p.y() - wall_top_y);
    }
  }
  return best;
}

TEST(GlobalPath, CostGradientKeepsOffWallsWhereThereIsRoomAndStillPassesNarrowGaps) {
  // A wall along y = 1.0..1.1 m; start and goal 0.55 m above it, 5 m apart, open space above.
  World world(60, 40, '.');
  world.fill(0, 10, 59, 10, '#');
  const Eigen::Vector2d start(0.55, 1.65);
  const Eigen::Vector2d goal(5.45, 1.65);
  GlobalPathParams params;
  params.footprint_radius_m = 0.3;
  const GlobalPathResult hugging = plan_global_path(world.window(), start, goal, params);
  ASSERT_EQ(hugging.status, GlobalPathStatus::kFound) << to_string(hugging.status);
  EXPECT_LT(farthest_from_wall(hugging.waypoints_W, 1.1), 0.6);  // straight along the wall
  params.cost_radius_m = 1.0;
  params.near_obstacle_extra_cost = 2.0;
  const GlobalPathResult clear = plan_global_path(world.window(), start, goal, params);
  ASSERT_EQ(clear.status, GlobalPathStatus::kFound) << to_string(clear.status);
  EXPECT_GT(farthest_from_wall(clear.waypoints_W, 1.1), 0.9);  // out into the room, away from the wall
  EXPECT_GE(wall_clearance(clear.waypoints_W, world), params.footprint_radius_m - 1e-9);

  // The 0.7 m gap that a 0.25 m hard radius passes stays open with a gradient out to 0.64 m (a Bearcat's
  // circumscribed radius): the only way through is taken, just at a higher cost.
  World wall(40, 30, '.');
  wall.fill(20, 0, 20, 29, '#');
  wall.fill(20, 12, 20, 18, '.');
  GlobalPathParams bearcat;
  bearcat.footprint_radius_m = 0.25;
  const GlobalPathResult plain = plan_global_path(wall.window(), {0.55, 0.55}, {3.55, 2.55}, bearcat);
  bearcat.cost_radius_m = 0.64;
  const GlobalPathResult graded = plan_global_path(wall.window(), {0.55, 0.55}, {3.55, 2.55}, bearcat);
  ASSERT_EQ(plain.status, GlobalPathStatus::kFound) << to_string(plain.status);
  ASSERT_EQ(graded.status, GlobalPathStatus::kFound) << to_string(graded.status);
  EXPECT_GE(wall_clearance(graded.waypoints_W, wall), bearcat.footprint_radius_m - 1e-9);
  EXPECT_LT(wall_clearance(graded.waypoints_W, wall), 0.36);
  EXPECT_GT(graded.cost_m, plain.cost_m);

  // The extra cost itself: full at the hard limit, none beyond the cost radius, never negative.
  const std::vector<float> extra = obstacle_cost(wall.window(), bearcat);
  const auto at = [&](int x, int y) { return extra[static_cast<std::size_t>(y) * 40 + x]; };
  EXPECT_FLOAT_EQ(at(17, 5), 2.0F);  // centre 0.25 m from the wall's square: within the hard radius
  EXPECT_GT(at(14, 5), 0.0F);        // 0.55 m: on the slope
  EXPECT_LT(at(14, 5), 2.0F);
  EXPECT_FLOAT_EQ(at(5, 5), 0.0F);  // 1.45 m: beyond it
  bearcat.cost_radius_m = -0.1;
  EXPECT_THROW(static_cast<void>(obstacle_cost(wall.window(), bearcat)), std::invalid_argument);
}

TEST(GlobalPath, ReportsWhyThereIsNoPath) {
  // The goal inside a closed ring of wall.
  World world(30, 30, '.');
  world.fill(15, 15, 25, 15, '#');
  world.fill(15, 25, 25, 25, '#');
  world.fill(15, 15, 15, 25, '#');
  world.fill(25, 15, 25, 25, '#');
  GlobalPathParams params;
  params.footprint_radius_m = 0.1;
  EXPECT_EQ(plan_global_path(world.window(), {0.55, 0.55}, {2.05, 2.05}, params).status, GlobalPathStatus::kNoPath);
  EXPECT_EQ(plan_global_path(world.window(), {0.55, 0.55}, {1.45, 1.95}, params).status,
            GlobalPathStatus::kGoalBlocked);  // 0.05 m from the wall
  EXPECT_EQ(plan_global_path(world.window(), {1.55, 1.55}, {0.55, 0.55}, params).status,
            GlobalPathStatus::kStartOccupied);
  params.max_expansions = 10;
  EXPECT_EQ(plan_global_path(world.window(), {0.55, 0.55}, {2.75, 0.55}, params).status,
            GlobalPathStatus::kExpansionLimit);
  const auto snapshot = world.snapshot();
  params = GlobalPathParams{};
  params.max_window_cells = 50;  // 0.5 + 2 * 5 m margin is already 105 cells
  EXPECT_EQ(plan_global_path(*snapshot, {0.55, 0.55}, {1.05, 0.55}, params).status, GlobalPathStatus::kWindowTooLarge);
  EXPECT_EQ(to_string(GlobalPathStatus::kGoalBlocked), "goal_blocked");
}

TEST(GlobalPath, LeavesAnInflatedStartAndNeverReturns) {
  World world(30, 20, '.');
  world.fill(0, 10, 29, 10, '#');  // a wall along y = 1 m
  GlobalPathParams params;
  params.footprint_radius_m = 0.3;
  const auto window = world.window();
  const std::vector<bool> blocked = inflate(window, params.footprint_radius_m);
  // The robot 0.15 m below the wall, inside the inflated zone.
  const GlobalPathResult result = plan_global_path(window, {0.55, 0.85}, {2.55, 0.25}, params);
  ASSERT_EQ(result.status, GlobalPathStatus::kFound) << to_string(result.status);
  bool left = false;
  for (const geometry::CellIndex& c : result.cells) {
    const bool in_zone = blocked[static_cast<std::size_t>(c.iy) * world.width + c.ix];
    EXPECT_FALSE(left && in_zone) << "re-entered at " << c.ix << ", " << c.iy;
    left = left || !in_zone;
  }
  EXPECT_TRUE(left);
}

// The reference: blocked cells by brute force over all occupied cells, then Dijkstra over all cells by linear scans,
// with the planner's rules (8-connected, a step costs its length times the entered cell's weight, occupied cells
// never entered, blocked cells only from blocked cells).
struct Reference {
  GlobalPathStatus status = GlobalPathStatus::kNoPath;
  double cost_m = kInfinity;
  std::vector<bool> blocked;
};

std::vector<bool> brute_force_blocked(const World& world, double radius_m) {
  std::vector<bool> blocked(world.cells.size(), false);
  for (int y = 0; y < world.height; ++y) {
    for (int x = 0; x < world.width; ++x) {
      const Eigen::Vector2d centre((x + 0.5) * kCell, (y + 0.5) * kCell);
      for (int oy = 0; oy < world.height; ++oy) {
        for (int ox = 0; ox < world.width; ++ox) {
          // A centre exactly at the limit is free; 1e-12 m absorbs the rounding of the metric distances.
          if (world.at(ox, oy) == '#' && distance_to_cell(centre, ox, oy) < radius_m + kCell * std::sqrt(0.5) - 1e-12) {
            blocked[static_cast<std::size_t>(y * world.width + x)] = true;
          }
        }
      }
    }
  }
  return blocked;
}

Reference brute_force(const World& world, const std::vector<bool>& blocked, const Eigen::Vector2d& start,
                      const Eigen::Vector2d& goal, double unknown_extra_cost) {
  Reference reference;
  const int n = world.width * world.height;
  reference.blocked = blocked;
  const int start_index = static_cast<int>(start.y() / kCell) * world.width + static_cast<int>(start.x() / kCell);
  const int goal_index = static_cast<int>(goal.y() / kCell) * world.width + static_cast<int>(goal.x() / kCell);
  const auto occupied = [&](int i) { return world.cells[static_cast<std::size_t>(i)] == '#'; };
  if (occupied(start_index)) {
    reference.status = GlobalPathStatus::kStartOccupied;
    return reference;
  }
  if (reference.blocked[static_cast<std::size_t>(goal_index)]) {
    reference.status = GlobalPathStatus::kGoalBlocked;
    return reference;
  }
  std::vector<double> cost(static_cast<std::size_t>(n), kInfinity);
  std::vector<bool> done(static_cast<std::size_t>(n), false);
  cost[static_cast<std::size_t>(start_index)] = 0.0;
  while (true) {
    int best = -1;
    for (int i = 0; i < n; ++i) {
      if (!done[static_cast<std::size_t>(i)] && cost[static_cast<std::size_t>(i)] < kInfinity &&
          (best < 0 || cost[static_cast<std::size_t>(i)] < cost[static_cast<std::size_t>(best)])) {
        best = i;
      }
    }
    if (best < 0) break;
    done[static_cast<std::size_t>(best)] = true;
    const int bx = best % world.width;
    const int by = best / world.width;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int x = bx + dx;
        const int y = by + dy;
        if ((dx == 0 && dy == 0) || x < 0 || y < 0 || x >= world.width || y >= world.height) continue;
        const int next = y * world.width + x;
        if (occupied(next)) continue;
        if (!reference.blocked[static_cast<std::size_t>(best)] && reference.blocked[static_cast<std::size_t>(next)]) {
          continue;
        }
        const double weight = world.cells[static_cast<std::size_t>(next)] == '?' ? 1.0 + unknown_extra_cost : 1.0;
        const double step = (dx != 0 && dy != 0 ? std::sqrt(2.0) : 1.0) * kCell * weight;
        cost[static_cast<std::size_t>(next)] =
            std::min(cost[static_cast<std::size_t>(next)], cost[static_cast<std::size_t>(best)] + step);
      }
    }
  }
  reference.cost_m = cost[static_cast<std::size_t>(goal_index)];
  reference.status = reference.cost_m < kInfinity ? GlobalPathStatus::kFound : GlobalPathStatus::kNoPath;
  return reference;
}

TEST(GlobalPath, MatchesBruteForceDijkstraOnRandomGrids) {
  std::mt19937_64 rng(20261201);
  const auto uniform = [&](double low, double high) {
    return low + (high - low) * static_cast<double>(rng() >> 11) * 0x1.0p-53;
  };
  const auto below = [&](int n) { return static_cast<int>(rng() % static_cast<std::uint64_t>(n)); };
  int found = 0;
  int no_path = 0;
  int blocked_start = 0;
  constexpr int kGrids = 500;
  for (int trial = 0; trial < kGrids; ++trial) {
    World world(3 + below(14), 3 + below(14), '.');
    // One grid in five is mostly wall, so inflation meets solid blobs (only their edge cells spread the margin).
    const double occupied_share = trial % 5 == 1 ? uniform(0.5, 0.8) : uniform(0.0, 0.25);
    const double unknown_share = uniform(0.0, 0.4);
    for (char& c : world.cells) {
      const double draw = uniform(0.0, 1.0);
      c = draw < occupied_share ? '#' : (draw < occupied_share + unknown_share ? '?' : '.');
    }
    GlobalPathParams params;
    params.footprint_radius_m = trial % 3 == 0 ? 0.0 : uniform(0.0, 0.15);
    params.unknown_extra_cost = uniform(0.0, 3.0);
    params.smooth = trial % 2 == 0;
    const std::vector<bool> blocked = brute_force_blocked(world, params.footprint_radius_m);
    // A point in a random cell; mostly (seven trials in eight) a start off the walls and a goal the footprint fits.
    const auto point_in = [&](const std::function<bool(std::size_t)>& acceptable) {
      for (int attempt = 0; attempt < 100; ++attempt) {
        const Eigen::Vector2d p(uniform(0.0, world.width * kCell), uniform(0.0, world.height * kCell));
        const auto index =
            static_cast<std::size_t>(static_cast<int>(p.y() / kCell) * world.width + static_cast<int>(p.x() / kCell));
        if (trial % 8 == 0 || acceptable(index)) return p;
      }
      return Eigen::Vector2d(uniform(0.0, world.width * kCell), uniform(0.0, world.height * kCell));
    };
    const Eigen::Vector2d start = point_in([&](std::size_t i) { return world.cells[i] != '#'; });
    const Eigen::Vector2d goal = point_in([&](std::size_t i) { return !blocked[i]; });
    SCOPED_TRACE("trial " + std::to_string(trial));
    const Reference reference = brute_force(world, blocked, start, goal, params.unknown_extra_cost);
    const PlanningWindow window = world.window();
    ASSERT_EQ(inflate(window, params.footprint_radius_m), reference.blocked);
    const GlobalPathResult result = plan_global_path(window, start, goal, params);
    ASSERT_EQ(result.status, reference.status) << to_string(result.status) << " vs " << to_string(reference.status);
    if (result.status != GlobalPathStatus::kFound) {
      no_path += result.status == GlobalPathStatus::kNoPath ? 1 : 0;
      continue;
    }
    ++found;
    // Sums in another order: equal to rounding.
    ASSERT_NEAR(result.cost_m, reference.cost_m, 1e-9);
    // The cells form an 8-connected chain from the start's cell to the goal's.
    ASSERT_FALSE(result.cells.empty());
    EXPECT_EQ(result.cells.front().ix, static_cast<int>(start.x() / kCell));
    EXPECT_EQ(result.cells.front().iy, static_cast<int>(start.y() / kCell));
    EXPECT_EQ(result.cells.back().ix, static_cast<int>(goal.x() / kCell));
    EXPECT_EQ(result.cells.back().iy, static_cast<int>(goal.y() / kCell));
    for (std::size_t i = 1; i < result.cells.size(); ++i) {
      ASSERT_LE(std::max(std::abs(result.cells[i].ix - result.cells[i - 1].ix),
                         std::abs(result.cells[i].iy - result.cells[i - 1].iy)),
                1);
    }
    const bool start_blocked =
        reference.blocked[static_cast<std::size_t>(result.cells.front().iy * world.width + result.cells.front().ix)];
    blocked_start += start_blocked ? 1 : 0;
    if (!start_blocked && result.waypoints_W.size() > 2) {
      // Between the first and the last cell centre every point keeps the footprint radius.
      std::vector<Eigen::Vector2d> inner(result.waypoints_W.begin() + 1, result.waypoints_W.end() - 1);
      inner.insert(inner.begin(), {(result.cells.front().ix + 0.5) * kCell, (result.cells.front().iy + 0.5) * kCell});
      inner.push_back({(result.cells.back().ix + 0.5) * kCell, (result.cells.back().iy + 0.5) * kCell});
      EXPECT_GE(wall_clearance(inner, world), params.footprint_radius_m - 1e-9);
    }
  }
  // The random grids exercise every outcome.
  std::printf("random grids: %d found, %d no path, %d with a start in the inflated zone\n", found, no_path,
              blocked_start);
  EXPECT_GE(found, 200);
  EXPECT_GT(no_path, 10);
  EXPECT_GT(blocked_start, 5);
}

// Unicycle kinematics, integrated in 10 ms steps.
Pose2 drive(Pose2 pose, double linear_mps, double angular_radps, double duration_s) {
  constexpr double kStep_s = 0.01;
  for (double t = 0.0; t < duration_s - 1e-12; t += kStep_s) {
    pose.x += linear_mps * std::cos(pose.theta) * kStep_s;
    pose.y += linear_mps * std::sin(pose.theta) * kStep_s;
    pose.theta += angular_radps * kStep_s;
  }
  return pose;
}

TEST(PurePursuit, FollowsThePlannedPathOutOfTheTrap) {
  const World world = u_trap('.');
  const GlobalPathResult plan = plan_global_path(*world.snapshot(), {3.25, 2.05}, {5.25, 2.05}, GlobalPathParams{});
  ASSERT_EQ(plan.status, GlobalPathStatus::kFound);
  const PurePursuitParams params;
  Pose2 pose{3.25, 2.05, 0.0};  // facing the closed end: it must turn round first
  std::size_t segment = 0;
  bool reached = false;
  double worst_off_m = 0.0;
  double t = 0.0;
  for (; t < 120.0 && !reached; t += 0.1) {
    const PurePursuitCommand command = pure_pursuit(pose, plan.waypoints_W, params, segment);
    segment = command.segment;
    reached = command.reached;
    // Cross-track error: distance to the path.
    double off_m = kInfinity;
    for (std::size_t i = 0; i + 1 < plan.waypoints_W.size(); ++i) {
      const Eigen::Vector2d a = plan.waypoints_W[i];
      const Eigen::Vector2d along = plan.waypoints_W[i + 1] - a;
      const Eigen::Vector2d p(pose.x, pose.y);
      const double s = std::clamp((p - a).dot(along) / along.squaredNorm(), 0.0, 1.0);
      off_m = std::min(off_m, (a + s * along - p).norm());
    }
    worst_off_m = std::max(worst_off_m, off_m);
    pose = drive(pose, command.linear_mps, command.angular_radps, 0.1);
  }
  ASSERT_TRUE(reached);
  EXPECT_LT(t, 60.0);  // about 8 m at 0.3 m/s with slow corners
  // It cuts corners by less than the footprint radius the path keeps from the walls.
  EXPECT_LT(worst_off_m, GlobalPathParams{}.footprint_radius_m);
}

TEST(PurePursuit, TurnsOnTheSpotTowardAnAimPointBehind) {
  const std::vector<Eigen::Vector2d> path{{0.0, 0.0}, {2.0, 0.0}};
  const PurePursuitParams params;
  const PurePursuitCommand command = pure_pursuit(Pose2{0.0, 0.0, std::numbers::pi - 0.1}, path, params);
  EXPECT_EQ(command.linear_mps, 0.0);
  EXPECT_DOUBLE_EQ(std::abs(command.angular_radps), params.max_angular_radps);
  EXPECT_LT(command.angular_radps, 0.0);  // clockwise is the short way round from just under pi
  const PurePursuitCommand ahead = pure_pursuit(Pose2{0.0, 0.1, 0.0}, path, params);
  EXPECT_GT(ahead.linear_mps, 0.0);
  EXPECT_LT(ahead.angular_radps, 0.0);  // left of the path: steer right
  EXPECT_NEAR(ahead.aim_W.x(), 0.5, 1e-9);
  EXPECT_TRUE(pure_pursuit(Pose2{1.95, 0.0, 0.0}, path, params).reached);
}

// Re-planning hysteresis. An 8 m x 6 m field with a block (x 3-4 m, y 1.5-4.5 m) between start and goal: the ways
// over and under it are equally long, 1.5 m wide each.
World block_between(char fill) {
  World world(80, 60, fill);
  world.fill(30, 15, 39, 44, '#');
  return world;
}
const Eigen::Vector2d kBlockStart(1.05, 3.05);
const Eigen::Vector2d kBlockGoal(7.05, 3.05);

double lowest_y(const std::vector<Eigen::Vector2d>& path) {
  double y = kInfinity;
  for (const Eigen::Vector2d& p : path) y = std::min(y, p.y());
  return y;
}

TEST(GlobalPath, PathCostIsTheLengthWeightedByCellsAndNoneThroughABlockedCell) {
  const World world = block_between('.');
  const GlobalPathParams params;
  const std::vector<Eigen::Vector2d> under{kBlockStart, {2.5, 0.75}, {4.5, 0.75}, kBlockGoal};
  const std::optional<double> cost = path_cost(world.window(), under, params);
  ASSERT_TRUE(cost);
  EXPECT_NEAR(*cost, length(under), 1e-9);  // all seen free, no gradient: the length
  World unknown = block_between('?');
  const std::optional<double> unknown_cost = path_cost(unknown.window(), under, params);
  ASSERT_TRUE(unknown_cost);
  EXPECT_NEAR(*unknown_cost, (1.0 + params.unknown_extra_cost) * length(under), 1e-9);
  EXPECT_FALSE(path_cost(world.window(), std::vector<Eigen::Vector2d>{kBlockStart, kBlockGoal}, params));
  // A start inside the inflated zone may leave it, but a later leg may not touch it.
  EXPECT_TRUE(path_cost(world.window(), std::vector<Eigen::Vector2d>{{2.85, 3.05}, {1.05, 3.05}}, params));
  EXPECT_FALSE(
      path_cost(world.window(), std::vector<Eigen::Vector2d>{{1.05, 3.05}, {2.85, 3.05}, {1.05, 3.05}}, params));
}

TEST(GlobalPath, KeepsTheCurrentWayRoundUnlessTheNewOneIsClearlyCheaper) {
  const World world = block_between('.');
  GlobalPathParams params;
  const GlobalPathResult fresh = plan_global_path(world.window(), kBlockStart, kBlockGoal, params);
  ASSERT_EQ(fresh.status, GlobalPathStatus::kFound);
  // The robot follows the other way round, a little longer than the fresh path's: kept.
  const bool fresh_goes_under = lowest_y(fresh.waypoints_W) < 1.5;
  const double side_y = fresh_goes_under ? 5.0 : 1.1;
  params.current_path_W = {kBlockStart, {2.6, side_y}, {4.4, side_y}, kBlockGoal};
  const GlobalPathResult kept = plan_global_path(world.window(), kBlockStart, kBlockGoal, params);
  ASSERT_EQ(kept.status, GlobalPathStatus::kFound);
  EXPECT_TRUE(kept.kept_current);
  EXPECT_EQ(kept.waypoints_W, params.current_path_W);
  ASSERT_TRUE(kept.current_cost_m);
  EXPECT_GT(*kept.current_cost_m, fresh.smoothed_cost_m);
  // A long detour on that side (out to the field's edge and back) is replaced.
  const double far_y = fresh_goes_under ? 5.8 : 0.2;
  params.current_path_W = {kBlockStart, {0.3, far_y}, {7.7, far_y}, kBlockGoal};
  const GlobalPathResult replaced = plan_global_path(world.window(), kBlockStart, kBlockGoal, params);
  ASSERT_EQ(replaced.status, GlobalPathStatus::kFound);
  EXPECT_FALSE(replaced.kept_current);
  EXPECT_EQ(replaced.waypoints_W, fresh.waypoints_W);
  EXPECT_GE(wall_clearance(replaced.waypoints_W, world), params.footprint_radius_m - 1e-9);
}

TEST(GlobalPath, ABlockedCurrentPathKeepsItsClearPartAndItsSideUnlessTheOtherIsClearlyCheaper) {
  // The robot goes over the block; a pillar comes into view on the last leg (x 5.0-5.4, y 4.0-4.6). Going past it
  // costs a little more than going under the block now, but not clearly more: the robot stays on its side.
  World world = block_between('.');
  world.fill(50, 40, 53, 45, '#');
  GlobalPathParams params;
  const std::vector<Eigen::Vector2d> over{kBlockStart, {2.7, 4.9}, {4.3, 4.9}, kBlockGoal};
  ASSERT_FALSE(path_cost(world.window(), over, params));
  const GlobalPathResult fresh = plan_global_path(world.window(), kBlockStart, kBlockGoal, params);
  ASSERT_EQ(fresh.status, GlobalPathStatus::kFound);
  EXPECT_LT(lowest_y(fresh.waypoints_W), 1.5) << "without a current path: under the block";
  params.current_path_W = over;
  const GlobalPathResult kept = plan_global_path(world.window(), kBlockStart, kBlockGoal, params);
  ASSERT_EQ(kept.status, GlobalPathStatus::kFound);
  EXPECT_TRUE(kept.kept_current);
  ASSERT_GE(kept.waypoints_W.size(), 4U);
  EXPECT_TRUE(std::equal(over.begin(), over.begin() + 3, kept.waypoints_W.begin())) << "the clear part is kept";
  EXPECT_GT(lowest_y(kept.waypoints_W), 3.0) << "over the block";
  EXPECT_TRUE(kept.waypoints_W.back().isApprox(kBlockGoal));
  EXPECT_GE(wall_clearance(kept.waypoints_W, world), params.footprint_radius_m - 1e-9);

  // A wall closing the way over (x 4.6-4.7 from the block's height to the field's edge, with the pillar): going back
  // round is clearly dearer.
  world.fill(46, 40, 47, 59, '#');
  const GlobalPathResult turned = plan_global_path(world.window(), kBlockStart, kBlockGoal, params);
  ASSERT_EQ(turned.status, GlobalPathStatus::kFound);
  EXPECT_FALSE(turned.kept_current);
  EXPECT_LT(lowest_y(turned.waypoints_W), 1.5);
  EXPECT_GE(wall_clearance(turned.waypoints_W, world), params.footprint_radius_m - 1e-9);
}

TEST(GlobalPath, RejectsBadInputNamingTheField) {
  const World world(10, 10, '.');
  GlobalPathParams params;
  params.footprint_radius_m = -0.1;
  try {
    plan_global_path(world.window(), {0.5, 0.5}, {0.7, 0.5}, params);
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("footprint_radius_m"), std::string::npos) << error.what();
  }
  try {
    plan_global_path(world.window(), {0.5, 0.5}, {5.0, 0.5}, GlobalPathParams{});
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("goal_W"), std::string::npos) << error.what();
  }
  // On a grid, a point with no cell (2^30 cells out, not finite) is refused by name, not wrapped to another cell.
  const auto grid = world.snapshot();
  for (const Eigen::Vector2d& far : {Eigen::Vector2d(1.0e12, 0.5), Eigen::Vector2d(0.5, -1.0e12)}) {
    try {
      plan_global_path(*grid, far, {0.7, 0.5}, GlobalPathParams{});
      ADD_FAILURE() << "accepted";
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find("start_W"), std::string::npos) << error.what();
    }
  }
  EXPECT_THROW(static_cast<void>(segment_clear(*grid, {0.5, 0.5}, {1.0e12, 0.5}, 0.2)), std::invalid_argument);
  try {
    pure_pursuit(Pose2{}, std::vector<Eigen::Vector2d>{}, PurePursuitParams{});
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("path_W"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace occgeo::service::control
