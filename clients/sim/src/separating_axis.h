#pragma once

#include <Eigen/Core>
#include <algorithm>

namespace occgeo::sim::detail {

// The extent of a convex shape's points along one axis.
struct Interval {
  double lo;
  double hi;
};

// Projects points (any range of Eigen::Vector2d, at least one) onto axis.
template <typename Points>
Interval project(const Points& points, const Eigen::Vector2d& axis) {
  const double first = points[0].dot(axis);
  Interval interval{first, first};
  for (const Eigen::Vector2d& point : points) {
    interval.lo = std::min(interval.lo, point.dot(axis));
    interval.hi = std::max(interval.hi, point.dot(axis));
  }
  return interval;
}

// True when the open intervals share a point, i.e. the closed ones overlap by more than touching.
inline bool overlaps(const Interval& a, const Interval& b) { return a.lo < b.hi && b.lo < a.hi; }

}  // namespace occgeo::sim::detail
