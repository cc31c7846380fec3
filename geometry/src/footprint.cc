#include "occgeo/geometry/footprint.h"

#include <algorithm>
#include <cmath>
#include <variant>

namespace occgeo::geometry {

double footprint_height(const Footprint& footprint) {
  return std::visit([](const auto& shape) { return shape.height; }, footprint);
}

double bounding_radius(const Footprint& footprint) {
  if (const auto* box = std::get_if<BoxFootprint>(&footprint)) {
    const double far_x = std::max(std::abs(box->center_x + box->length / 2), std::abs(box->center_x - box->length / 2));
    return std::sqrt(far_x * far_x + box->width * box->width / 4);  // no overflow to guard against: hypot is slower
  }
  if (const auto* cylinder = std::get_if<CylinderFootprint>(&footprint)) return cylinder->radius;
  double radius = 0.0;
  for (const Eigen::Vector2d& vertex_B : std::get<ConvexPolygonFootprint>(footprint).vertices_B) {
    radius = std::max(radius, vertex_B.norm());
  }
  return radius;
}

PrismMesh prism_mesh(const ConvexPolygonFootprint& polygon) {
  const int n = static_cast<int>(polygon.vertices_B.size());
  PrismMesh mesh;
  mesh.vertices_B.reserve(2 * polygon.vertices_B.size());
  for (const double z : {0.0, polygon.height}) {
    for (const Eigen::Vector2d& vertex_B : polygon.vertices_B)
      mesh.vertices_B.emplace_back(vertex_B.x(), vertex_B.y(), z);
  }
  // Bottom face, seen from below: the ring in reverse.
  mesh.faces.push_back(n);
  for (int k = n - 1; k >= 0; --k) mesh.faces.push_back(k);
  // Top face, seen from above: the ring in order.
  mesh.faces.push_back(n);
  for (int k = 0; k < n; ++k) mesh.faces.push_back(n + k);
  // One side face per edge k -> k + 1.
  for (int k = 0; k < n; ++k) {
    const int next = (k + 1) % n;
    mesh.faces.insert(mesh.faces.end(), {4, k, next, n + next, n + k});
  }
  mesh.face_count = n + 2;
  return mesh;
}

}  // namespace occgeo::geometry
