#pragma once

// The benchmarks' shared scene: a 20 x 20 m room with six boxes, scanned by a noise-free SICK LMS200 (181 beams over
// 180 degrees, 1 degree apart, 8 m max range) along an elliptic loop through the room.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include "occgeo/geometry/pose.h"

namespace occgeo::bench {

inline constexpr int kBeams = 181;
inline constexpr float kAngleMin = -std::numbers::pi_v<float> / 2;
inline constexpr float kAngleIncrement = std::numbers::pi_v<float> / 180;
inline constexpr float kRangeMax = 8.0F;

// An axis-aligned box, metres.
struct Box {
  double min_x, min_y, max_x, max_y;
};

// The room's inside and the boxes standing in it.
inline constexpr Box kRoom{0.0, 0.0, 20.0, 20.0};
inline constexpr Box kObstacles[] = {{3.0, 3.0, 4.0, 5.0},   {8.0, 12.0, 10.0, 13.0},  {14.0, 4.0, 15.5, 5.5},
                                     {5.0, 15.0, 5.6, 17.0}, {16.0, 14.0, 17.0, 18.0}, {11.0, 7.0, 11.4, 7.4}};

// Distances along origin + t * direction at which the ray enters and leaves box (t_enter > t_leave: it misses).
inline std::pair<double, double> slab_interval(const Box& box, const Eigen::Vector2d& origin,
                                               const Eigen::Vector2d& direction) {
  double t_enter = -std::numeric_limits<double>::infinity();
  double t_leave = std::numeric_limits<double>::infinity();
  const double lows[] = {box.min_x, box.min_y};
  const double highs[] = {box.max_x, box.max_y};
  for (int axis = 0; axis < 2; ++axis) {
    if (direction[axis] == 0.0) {
      if (origin[axis] < lows[axis] || origin[axis] > highs[axis]) return {1.0, 0.0};
      continue;
    }
    const double t0 = (lows[axis] - origin[axis]) / direction[axis];
    const double t1 = (highs[axis] - origin[axis]) / direction[axis];
    t_enter = std::max(t_enter, std::min(t0, t1));
    t_leave = std::min(t_leave, std::max(t0, t1));
  }
  return {t_enter, t_leave};
}

// Range (metres) a perfect sensor at origin measures along direction (unit vector): the nearest box or room wall.
inline double cast_ray(const Eigen::Vector2d& origin, const Eigen::Vector2d& direction) {
  double range = slab_interval(kRoom, origin, direction).second;
  for (const Box& box : kObstacles) {
    const auto [t_enter, t_leave] = slab_interval(box, origin, direction);
    if (t_enter <= t_leave && t_enter > 0.0) range = std::min(range, t_enter);
  }
  return range;
}

struct Scan {
  geometry::Pose2 X_WS;
  std::vector<float> ranges;
};

// `count` scans taken poses_per_loop to a lap of a loop through the room (laps repeat); the laser sits 0.2 m ahead of
// the robot centre.
inline std::vector<Scan> make_scans(int count, int poses_per_loop) {
  const geometry::Pose2 X_BS{0.2, 0.0, 0.0};
  std::vector<Scan> scans;
  for (int i = 0; i < count; ++i) {
    const double phase = 2.0 * std::numbers::pi * i / poses_per_loop;
    const geometry::Pose2 X_WB{10.0 + 6.5 * std::cos(phase), 10.0 + 4.5 * std::sin(phase),
                               phase + std::numbers::pi / 2};
    Scan scan{X_WB.compose(X_BS), std::vector<float>(kBeams)};
    for (int beam = 0; beam < kBeams; ++beam) {
      const double angle =
          scan.X_WS.theta + static_cast<double>(kAngleMin) + beam * static_cast<double>(kAngleIncrement);
      const double range = cast_ray(scan.X_WS.position(), {std::cos(angle), std::sin(angle)});
      scan.ranges[static_cast<std::size_t>(beam)] =
          range >= static_cast<double>(kRangeMax) ? kRangeMax : static_cast<float>(range);
    }
    scans.push_back(std::move(scan));
  }
  return scans;
}

}  // namespace occgeo::bench
