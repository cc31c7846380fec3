#include "occgeo/sim/shape_world.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <utility>

#include "separating_axis.h"

namespace occgeo::sim {

namespace {

using detail::Interval;
using detail::overlaps;
using detail::project;

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

// The polygon's outward edge normals (counter-clockwise winding), not normalised.
Eigen::Vector2d outward_normal(const std::vector<Eigen::Vector2d>& points, std::size_t i) {
  const Eigen::Vector2d edge = points[(i + 1) % points.size()] - points[i];
  return {edge.y(), -edge.x()};
}

std::vector<Eigen::Vector2d> footprint_corners(const geometry::BoxFootprint& footprint, const geometry::Pose2& X_WB) {
  const double half_length = footprint.length / 2.0;
  const double half_width = footprint.width / 2.0;
  return {X_WB.transform({footprint.center_x + half_length, half_width}),
          X_WB.transform({footprint.center_x - half_length, half_width}),
          X_WB.transform({footprint.center_x - half_length, -half_width}),
          X_WB.transform({footprint.center_x + half_length, -half_width})};
}

}  // namespace

Shape Shape::circle(const Eigen::Vector2d& center, double radius_m) {
  if (!(std::isfinite(radius_m) && radius_m > 0.0)) {
    throw WorldError("circle radius must be positive and finite, got " + std::to_string(radius_m));
  }
  if (!center.allFinite()) throw WorldError("circle center must be finite");
  Shape shape;
  shape.kind = Kind::circle;
  shape.center = center;
  shape.radius_m = radius_m;
  return shape;
}

Shape Shape::box(const Eigen::Vector2d& center, double length_m, double width_m, double yaw_rad) {
  if (!(std::isfinite(length_m) && length_m > 0.0 && std::isfinite(width_m) && width_m > 0.0)) {
    throw WorldError("box size must be positive and finite, got [" + std::to_string(length_m) + ", " +
                     std::to_string(width_m) + "]");
  }
  if (!center.allFinite() || !std::isfinite(yaw_rad)) throw WorldError("box center and yaw must be finite");
  const geometry::Pose2 X_WO{center.x(), center.y(), yaw_rad};
  const double hl = length_m / 2.0;
  const double hw = width_m / 2.0;
  Shape shape = polygon(
      {X_WO.transform({hl, hw}), X_WO.transform({-hl, hw}), X_WO.transform({-hl, -hw}), X_WO.transform({hl, -hw})});
  shape.center = center;
  return shape;
}

Shape Shape::polygon(std::vector<Eigen::Vector2d> points) {
  if (points.size() < 3) throw WorldError("polygon needs at least 3 points, got " + std::to_string(points.size()));
  for (const Eigen::Vector2d& point : points) {
    if (!point.allFinite()) throw WorldError("polygon points must be finite");
  }
  double twice_area = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) twice_area += cross(points[i], points[(i + 1) % points.size()]);
  if (!(std::abs(twice_area) > 0.0)) throw WorldError("polygon has zero area");
  if (twice_area < 0.0) std::reverse(points.begin(), points.end());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2d& a = points[i];
    const Eigen::Vector2d& b = points[(i + 1) % points.size()];
    const Eigen::Vector2d& c = points[(i + 2) % points.size()];
    if (cross(b - a, c - b) < 0.0) throw WorldError("polygon is not convex (at point " + std::to_string(i + 1) + ")");
  }
  Shape shape;
  shape.kind = Kind::polygon;
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& point : points) sum += point;
  shape.center = sum / static_cast<double>(points.size());
  shape.points = std::move(points);
  return shape;
}

Shape Shape::ramp(const Eigen::Vector2d& center, double length_m, double width_m, double yaw_rad) {
  Shape shape = box(center, length_m, width_m, yaw_rad);
  shape.solid = false;
  shape.slope_direction = {std::cos(yaw_rad), std::sin(yaw_rad)};
  shape.slope_start_m = shape.slope_direction.dot(center) - length_m / 2.0;
  shape.slope_rise = 1.0;  // set from the heights once they are known (see the parser)
  return shape;
}

std::optional<Shape> Shape::slice_at(double height_m) const {
  if (!spans_height(height_m)) return std::nullopt;
  if (slope_rise == 0.0) return *this;
  // Keep the polygon's part where slope_direction · p >= the distance at which the surface reaches height_m
  // (Sutherland-Hodgman against one half-plane).
  const double from_m = slope_start_m + (height_m - base_height_m) / slope_rise;
  std::vector<Eigen::Vector2d> kept;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2d& a = points[i];
    const Eigen::Vector2d& b = points[(i + 1) % points.size()];
    const double da = slope_direction.dot(a) - from_m;
    const double db = slope_direction.dot(b) - from_m;
    if (da >= 0.0) kept.push_back(a);
    if ((da >= 0.0) != (db >= 0.0)) kept.push_back(a + (b - a) * (da / (da - db)));
  }
  if (kept.size() < 3) return std::nullopt;
  try {
    Shape slice = polygon(std::move(kept));
    slice.name = name;
    slice.base_height_m = base_height_m;
    slice.top_height_m = top_height_m;
    slice.solid = solid;
    return slice;
  } catch (const WorldError&) {
    return std::nullopt;  // a sliver of no area at the very top edge
  }
}

Shape Shape::translated(const Eigen::Vector2d& offset) const {
  Shape shape = *this;
  shape.center += offset;
  for (Eigen::Vector2d& point : shape.points) point += offset;
  return shape;
}

Eigen::Vector2d MovingObstacle::center_at(double sim_time_s) const {
  const double time_s = sim_time_s - start_s;
  if (waypoints.size() < 2 || !(time_s > 0.0) || !(speed_mps > 0.0)) return waypoints.front();
  const std::size_t segments = loop ? waypoints.size() : waypoints.size() - 1;
  double total_m = 0.0;
  for (std::size_t i = 0; i < segments; ++i) {
    total_m += (waypoints[(i + 1) % waypoints.size()] - waypoints[i]).norm();
  }
  if (!(total_m > 0.0)) return waypoints.front();
  double s = speed_mps * time_s;
  if (loop) {
    s = std::fmod(s, total_m);
  } else if (s >= total_m) {
    return waypoints.back();
  }
  for (std::size_t i = 0; i < segments; ++i) {
    const Eigen::Vector2d& a = waypoints[i];
    const Eigen::Vector2d& b = waypoints[(i + 1) % waypoints.size()];
    const double length_m = (b - a).norm();
    if (s <= length_m && length_m > 0.0) return a + (b - a) * (s / length_m);
    s -= length_m;
  }
  return loop ? waypoints.front() : waypoints.back();
}

std::optional<RayHit> ray_hit(const Shape& shape, const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W) {
  if (shape.kind == Shape::Kind::circle) {
    const Eigen::Vector2d m = p_W - shape.center;
    const double b = m.dot(direction_W);
    const double c = m.squaredNorm() - shape.radius_m * shape.radius_m;
    const double discriminant = b * b - c;
    if (!(discriminant > 0.0)) return std::nullopt;  // misses or only touches
    const double root = std::sqrt(discriminant);
    const double exit = -b + root;
    if (!(exit > 0.0)) return std::nullopt;
    const double enter = -b - root;
    if (!(enter > 0.0)) return RayHit{.distance_m = 0.0, .pixels = {}, .normal_W = -direction_W};
    const Eigen::Vector2d radial = p_W + enter * direction_W - shape.center;
    return RayHit{.distance_m = enter, .pixels = {}, .normal_W = radial.normalized()};
  }
  // Cyrus-Beck clipping against the open half-planes of a counter-clockwise convex polygon; the edge that sets the
  // entry distance is the one entered.
  double enter = 0.0;
  double exit = std::numeric_limits<double>::infinity();
  std::optional<Eigen::Vector2d> entered_normal;
  for (std::size_t i = 0; i < shape.points.size(); ++i) {
    const Eigen::Vector2d normal = outward_normal(shape.points, i);
    const double offset = normal.dot(p_W - shape.points[i]);  // < 0 inside this edge's half-plane
    const double rate = normal.dot(direction_W);
    if (rate == 0.0) {
      if (offset >= 0.0) return std::nullopt;  // parallel, outside or along the edge
    } else if (rate < 0.0) {
      const double t = -offset / rate;
      const Eigen::Vector2d unit_normal = normal.normalized();
      // On a tie (through a vertex, or a start on an edge line) keep the edge the ray meets more head-on.
      if (t > enter ||
          (t == enter && (!entered_normal || unit_normal.dot(direction_W) < entered_normal->dot(direction_W)))) {
        enter = t;
        entered_normal = unit_normal;
      }
    } else {
      exit = std::min(exit, -offset / rate);
    }
  }
  if (!(enter < exit)) return std::nullopt;
  return RayHit{.distance_m = enter, .pixels = {}, .normal_W = entered_normal.value_or(-direction_W)};
}

std::optional<double> ray_distance(const Shape& shape, const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W) {
  const auto hit = ray_hit(shape, p_W, direction_W);
  if (!hit) return std::nullopt;
  return hit->distance_m;
}

std::optional<double> ray_entry_3d(const Shape& shape, const Eigen::Vector3d& p_W, const Eigen::Vector3d& direction_W) {
  // The ray's parameter interval inside the prism: the outline's (in the plane, with the horizontal part of the
  // direction, which may be zero for a vertical ray) intersected with the height slab's.
  double enter = 0.0;
  double exit = std::numeric_limits<double>::infinity();
  const auto clip = [&](double offset, double rate) {  // keeps the t where offset + rate t < 0
    if (rate == 0.0) return offset < 0.0;
    const double t = -offset / rate;
    if (rate < 0.0) {
      enter = std::max(enter, t);
    } else {
      exit = std::min(exit, t);
    }
    return true;
  };
  if (!clip(shape.base_height_m - p_W.z(), -direction_W.z()) || !clip(p_W.z() - shape.top_height_m, direction_W.z())) {
    return std::nullopt;
  }
  if (shape.slope_rise != 0.0) {
    // Below the ramp's surface: z <= base + rise (slope_direction · p - slope_start).
    const double surface_offset = p_W.z() - shape.base_height_m -
                                  shape.slope_rise * (shape.slope_direction.dot(p_W.head<2>()) - shape.slope_start_m);
    const double surface_rate = direction_W.z() - shape.slope_rise * shape.slope_direction.dot(direction_W.head<2>());
    if (!clip(surface_offset, surface_rate)) return std::nullopt;
  }
  const Eigen::Vector2d p_xy = p_W.head<2>();
  const Eigen::Vector2d d_xy = direction_W.head<2>();
  if (shape.kind == Shape::Kind::circle) {
    const Eigen::Vector2d m = p_xy - shape.center;
    const double a = d_xy.squaredNorm();
    const double c = m.squaredNorm() - shape.radius_m * shape.radius_m;
    if (a == 0.0) {
      if (!(c < 0.0)) return std::nullopt;
    } else {
      const double b = m.dot(d_xy);
      const double discriminant = b * b - a * c;
      if (!(discriminant > 0.0)) return std::nullopt;
      const double root = std::sqrt(discriminant);
      enter = std::max(enter, (-b - root) / a);
      exit = std::min(exit, (-b + root) / a);
    }
  } else {
    for (std::size_t i = 0; i < shape.points.size(); ++i) {
      const Eigen::Vector2d normal = outward_normal(shape.points, i);
      if (!clip(normal.dot(p_xy - shape.points[i]), normal.dot(d_xy))) return std::nullopt;
    }
  }
  if (!(enter < exit)) return std::nullopt;
  return enter;
}

bool footprint_overlaps(const Shape& shape, const geometry::BoxFootprint& footprint, const geometry::Pose2& X_WB) {
  if (shape.kind == Shape::Kind::circle) {
    const Eigen::Vector2d q = X_WB.inverse().transform(shape.center) - Eigen::Vector2d(footprint.center_x, 0.0);
    const Eigen::Vector2d nearest(std::clamp(q.x(), -footprint.length / 2.0, footprint.length / 2.0),
                                  std::clamp(q.y(), -footprint.width / 2.0, footprint.width / 2.0));
    return (q - nearest).squaredNorm() < shape.radius_m * shape.radius_m;
  }
  const std::vector<Eigen::Vector2d> box = footprint_corners(footprint, X_WB);
  std::vector<Eigen::Vector2d> axes;
  for (std::size_t i = 0; i < 2; ++i) axes.push_back(outward_normal(box, i));
  for (std::size_t i = 0; i < shape.points.size(); ++i) axes.push_back(outward_normal(shape.points, i));
  return std::all_of(axes.begin(), axes.end(), [&](const Eigen::Vector2d& axis) {
    return overlaps(project(box, axis), project(shape.points, axis));
  });
}

std::optional<RayHit> ShapeWorld::cast(const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W,
                                       double max_range_m, double time_s, double height_m) const {
  if (!p_W.allFinite() || !direction_W.allFinite() || !(max_range_m >= 0.0) || !std::isfinite(time_s)) {
    throw std::invalid_argument("cast: inputs must be finite and max_range_m >= 0");
  }
  std::optional<RayHit> best;
  const auto consider = [&](const Shape& shape) {
    const std::optional<Shape> slice = shape.slice_at(height_m);
    if (!slice) return;
    auto hit = ray_hit(*slice, p_W, direction_W);
    if (hit && (!best || hit->distance_m < best->distance_m)) best = std::move(hit);
  };
  for (const Shape& shape : shapes_) consider(shape);
  for (const MovingObstacle& obstacle : moving_) consider(obstacle.shape_at(time_s));
  if (!best || !(best->distance_m < max_range_m)) return std::nullopt;
  return best;
}

std::optional<double> ShapeWorld::cast_3d(const Eigen::Vector3d& p_W, const Eigen::Vector3d& direction_W,
                                          double max_range_m, double time_s) const {
  if (!p_W.allFinite() || !direction_W.allFinite() || !(max_range_m >= 0.0) || !std::isfinite(time_s)) {
    throw std::invalid_argument("cast_3d: inputs must be finite and max_range_m >= 0");
  }
  std::optional<double> best;
  const auto consider = [&](const Shape& shape) {
    const auto t = ray_entry_3d(shape, p_W, direction_W);
    if (t && (!best || *t < *best)) best = t;
  };
  for (const Shape& shape : shapes_) consider(shape);
  for (const MovingObstacle& obstacle : moving_) consider(obstacle.shape_at(time_s));
  if (!best || !(*best < max_range_m)) return std::nullopt;
  return best;
}

std::optional<std::string> ShapeWorld::find_collision(const geometry::BoxFootprint& footprint,
                                                      const geometry::Pose2& X_WB, double time_s) const {
  for (const Shape& shape : shapes_) {
    if (shape.solid && shape.overlaps_heights(0.0, footprint.height) && footprint_overlaps(shape, footprint, X_WB)) {
      return shape.name;
    }
  }
  for (const MovingObstacle& obstacle : moving_) {
    const Shape shape = obstacle.shape_at(time_s);
    if (shape.overlaps_heights(0.0, footprint.height) && footprint_overlaps(shape, footprint, X_WB)) {
      std::ostringstream where;
      where << shape.name << " at (" << shape.center.x() << ", " << shape.center.y() << ") at t = " << time_s << " s";
      return where.str();
    }
  }
  return std::nullopt;
}

}  // namespace occgeo::sim
