#include "occgeo/geometry/convex_polygon.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

namespace occgeo::geometry {

namespace {

// z of the cross product (b - a) x (c - a): positive when a, b, c turn left.
double turn(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const Eigen::Vector2d ab = b - a;
  const Eigen::Vector2d ac = c - a;
  return ab.x() * ac.y() - ab.y() * ac.x();
}

Eigen::Vector2d closest_point_on_segment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& p) {
  const Eigen::Vector2d ab = b - a;
  const double length_sq = ab.squaredNorm();
  if (length_sq == 0.0) return a;
  const double s = std::clamp((p - a).dot(ab) / length_sq, 0.0, 1.0);
  return a + s * ab;
}

}  // namespace

std::string convex_polygon_problem(const std::vector<Eigen::Vector2d>& vertices, Orientation orientation) {
  const std::size_t n = vertices.size();
  if (n < 3) return "vertices needs at least 3 vertices, got " + std::to_string(n);
  if (n > kMaxPolygonVertices) {
    return "vertices holds " + std::to_string(n) + " vertices, at most " + std::to_string(kMaxPolygonVertices) +
           " allowed";
  }
  for (std::size_t k = 0; k < n; ++k) {
    if (!vertices[k].allFinite()) return "vertices[" + std::to_string(k) + "] must be finite";
  }
  const double area = twice_signed_area(vertices);
  if (!(std::abs(area) > 0.0)) return "vertices must enclose a non-zero area";
  if (orientation == Orientation::counter_clockwise && area < 0.0) return "vertices must be counter-clockwise";
  const double side = area > 0.0 ? 1.0 : -1.0;
  // Every turn strictly to the same side (less than half a turn each), and the edge directions winding once around:
  // a convex, simple outline. Turning that way, the direction crosses the x axis upwards (or, clockwise, downwards)
  // once per full turn.
  int crossings = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector2d& previous = vertices[(k + n - 1) % n];
    const Eigen::Vector2d& vertex = vertices[k];
    const Eigen::Vector2d& next = vertices[(k + 1) % n];
    if (vertex == next) return "vertices[" + std::to_string(k) + "] repeats the next vertex";
    if (!(side * turn(previous, vertex, next) > 0.0)) {
      return "vertices[" + std::to_string(k) + "] makes the outline non-convex (or is collinear with its neighbours)";
    }
    const double in_y = side * (vertex.y() - previous.y());
    const double out_y = side * (next.y() - vertex.y());
    crossings += in_y < 0.0 && out_y >= 0.0 ? 1 : 0;
  }
  if (crossings != 1) return "vertices wind around more than once: the outline crosses itself";
  return {};
}

double twice_signed_area(const std::vector<Eigen::Vector2d>& vertices) {
  double area = 0.0;
  const std::size_t n = vertices.size();
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector2d& a = vertices[k];
    const Eigen::Vector2d& b = vertices[(k + 1) % n];
    area += a.x() * b.y() - a.y() * b.x();
  }
  return area;
}

Eigen::Vector2d vertex_centroid(const std::vector<Eigen::Vector2d>& vertices) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& v : vertices) sum += v;
  return vertices.empty() ? sum : Eigen::Vector2d(sum / static_cast<double>(vertices.size()));
}

std::vector<Eigen::Vector2d> placed_vertices(const ConvexPolygonFootprint& polygon, const Pose2& X_WB) {
  std::vector<Eigen::Vector2d> vertices_W;
  vertices_W.reserve(polygon.vertices_B.size());
  for (const Eigen::Vector2d& vertex_B : polygon.vertices_B) vertices_W.push_back(X_WB.transform(vertex_B));
  return vertices_W;
}

bool convex_polygon_contains(const std::vector<Eigen::Vector2d>& vertices, const Eigen::Vector2d& p) {
  const std::size_t n = vertices.size();
  for (std::size_t k = 0; k < n; ++k) {
    if (turn(vertices[k], vertices[(k + 1) % n], p) < 0.0) return false;
  }
  return n >= 3;
}

Eigen::Vector2d closest_point_in_convex_polygon(const std::vector<Eigen::Vector2d>& vertices,
                                                const Eigen::Vector2d& p) {
  if (convex_polygon_contains(vertices, p)) return p;
  const std::size_t n = vertices.size();
  Eigen::Vector2d best = vertices.empty() ? p : vertices.front();
  double best_sq = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector2d q = closest_point_on_segment(vertices[k], vertices[(k + 1) % n], p);
    const double sq = (q - p).squaredNorm();
    if (sq < best_sq) {
      best_sq = sq;
      best = q;
    }
  }
  return best;
}

PolygonSquareDistance convex_polygon_square_distance(const std::vector<Eigen::Vector2d>& vertices,
                                                     const Eigen::Vector2d& square_center, double half_side) {
  const Eigen::Vector2d lo = square_center - Eigen::Vector2d::Constant(half_side);
  const Eigen::Vector2d hi = square_center + Eigen::Vector2d::Constant(half_side);
  // Separating axes: the square's (both ways) and each polygon edge's outward normal.
  Eigen::AlignedBox2d aabb;
  for (const Eigen::Vector2d& v : vertices) aabb.extend(v);
  bool separated =
      aabb.min().x() > hi.x() || aabb.max().x() < lo.x() || aabb.min().y() > hi.y() || aabb.max().y() < lo.y();
  const std::size_t n = vertices.size();
  for (std::size_t k = 0; k < n && !separated; ++k) {
    const Eigen::Vector2d edge = vertices[(k + 1) % n] - vertices[k];
    const Eigen::Vector2d outward(edge.y(), -edge.x());
    const double square_low = outward.dot(square_center) - half_side * (std::abs(outward.x()) + std::abs(outward.y()));
    separated = square_low > outward.dot(vertices[k]);
  }
  if (!separated) return {true, 0.0, Eigen::Vector2d::Zero()};
  // Disjoint convex polygons: the closest pair includes a vertex of one of them.
  double best_sq = std::numeric_limits<double>::infinity();
  Eigen::Vector2d best_point = square_center;
  for (const Eigen::Vector2d& v : vertices) {
    const Eigen::Vector2d on_square = v.cwiseMax(lo).cwiseMin(hi);
    const double sq = (v - on_square).squaredNorm();
    if (sq < best_sq) {
      best_sq = sq;
      best_point = on_square;
    }
  }
  for (const Eigen::Vector2d& corner : {lo, hi, Eigen::Vector2d(lo.x(), hi.y()), Eigen::Vector2d(hi.x(), lo.y())}) {
    const double sq = (closest_point_in_convex_polygon(vertices, corner) - corner).squaredNorm();
    if (sq < best_sq) {
      best_sq = sq;
      best_point = corner;
    }
  }
  return {false, std::sqrt(best_sq), best_point};
}

double farthest_along(const std::vector<Eigen::Vector2d>& vertices, const Eigen::Vector2d& direction) {
  double farthest = -std::numeric_limits<double>::infinity();
  for (const Eigen::Vector2d& v : vertices) farthest = std::max(farthest, v.dot(direction));
  return vertices.empty() ? 0.0 : farthest;
}

double extent_along(const std::vector<Eigen::Vector2d>& vertices, const Eigen::Vector2d& direction) {
  return vertices.empty() ? 0.0 : farthest_along(vertices, direction) + farthest_along(vertices, -direction);
}

double origin_inscribed_radius(const std::vector<Eigen::Vector2d>& vertices) {
  if (!convex_polygon_contains(vertices, Eigen::Vector2d::Zero())) return 0.0;
  double radius = std::numeric_limits<double>::infinity();
  const std::size_t n = vertices.size();
  for (std::size_t k = 0; k < n; ++k) {
    radius =
        std::min(radius, closest_point_on_segment(vertices[k], vertices[(k + 1) % n], Eigen::Vector2d::Zero()).norm());
  }
  return std::isfinite(radius) ? radius : 0.0;
}

}  // namespace occgeo::geometry
