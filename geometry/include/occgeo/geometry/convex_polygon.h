#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <string>
#include <vector>

#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/pose.h"

// Exact 2D geometry of convex polygons, shared by every query that takes a polygon footprint. Polygons are vertex
// lists in counter-clockwise order without the first vertex repeated.

namespace occgeo::geometry {

// Most vertices a polygon footprint may have.
inline constexpr std::size_t kMaxPolygonVertices = 64;

enum class Orientation { counter_clockwise, either };

// Why these vertices are not a valid polygon footprint outline (3 to kMaxPolygonVertices finite vertices, strictly
// convex, non-zero area, in the given orientation), naming the offending element as "vertices[k]"; empty when valid.
std::string convex_polygon_problem(const std::vector<Eigen::Vector2d>& vertices, Orientation orientation);

// Twice the signed area (positive when counter-clockwise), square metres.
double twice_signed_area(const std::vector<Eigen::Vector2d>& vertices);

// The mean of the vertices: a point strictly inside a strictly convex polygon.
Eigen::Vector2d vertex_centroid(const std::vector<Eigen::Vector2d>& vertices);

// The polygon's vertices in world, given base_link's pose X_WB.
std::vector<Eigen::Vector2d> placed_vertices(const ConvexPolygonFootprint& polygon, const Pose2& X_WB);

// Is p inside or on the boundary of the counter-clockwise convex polygon?
bool convex_polygon_contains(const std::vector<Eigen::Vector2d>& vertices, const Eigen::Vector2d& p);

// The polygon's point nearest p (p itself when inside), same frame as the vertices.
Eigen::Vector2d closest_point_in_convex_polygon(const std::vector<Eigen::Vector2d>& vertices, const Eigen::Vector2d& p);

// Exact distance between the counter-clockwise convex polygon and the closed axis-aligned square (centre, half
// side), metres, with the square's point where it is attained; overlapping (touching included) gives distance 0.
struct PolygonSquareDistance {
  bool overlap = false;
  double distance_m = 0.0;
  Eigen::Vector2d point_on_square = Eigen::Vector2d::Zero();  // Unset when they overlap.
};
PolygonSquareDistance convex_polygon_square_distance(const std::vector<Eigen::Vector2d>& vertices,
                                                     const Eigen::Vector2d& square_center, double half_side);

// The largest projection of a vertex on the unit direction, and the width of the projections: max - min. Metres.
double farthest_along(const std::vector<Eigen::Vector2d>& vertices, const Eigen::Vector2d& direction);
double extent_along(const std::vector<Eigen::Vector2d>& vertices, const Eigen::Vector2d& direction);

// The radius of the largest circle about the frame's origin that fits inside the polygon, metres; 0 when the origin
// is outside.
double origin_inscribed_radius(const std::vector<Eigen::Vector2d>& vertices);

}  // namespace occgeo::geometry
