// Checks that queries, hellos and robot specs share: names, footprints and poses.
#include "validation.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "occgeo/geometry/convex_polygon.h"
#include "validation_helpers.h"

namespace occgeo::service {

bool valid_name(const std::string& name) {
  if (name.empty() || name.size() > 64) return false;
  for (const char c : name) {
    const bool ok =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-' || c == '.';
    if (!ok) return false;
  }
  return true;
}

std::optional<geometry::Footprint> footprint_from_proto(const v1::Footprint& footprint, const std::string& prefix,
                                                        FieldError& error) {
  if (footprint.has_box()) {
    const auto& box = footprint.box();
    const std::pair<const char*, double> lengths[] = {
        {".box.length_m", box.length_m()}, {".box.width_m", box.width_m()}, {".box.height_m", box.height_m()}};
    for (const auto& [name, value] : lengths) {
      if (!finite_positive(value)) {
        error = field_error(prefix + name, "must be a positive length");
        return std::nullopt;
      }
    }
    if (!std::isfinite(box.center_x_m())) {
      error = field_error(prefix + ".box.center_x_m", "must be finite");
      return std::nullopt;
    }
    return geometry::BoxFootprint{box.length_m(), box.width_m(), box.height_m(), box.center_x_m()};
  }
  if (footprint.has_cylinder()) {
    const auto& cylinder = footprint.cylinder();
    if (!finite_positive(cylinder.radius_m())) {
      error = field_error(prefix + ".cylinder.radius_m", "must be a positive length");
    } else if (!finite_positive(cylinder.height_m())) {
      error = field_error(prefix + ".cylinder.height_m", "must be a positive length");
    } else {
      return geometry::CylinderFootprint{cylinder.radius_m(), cylinder.height_m()};
    }
    return std::nullopt;
  }
  if (footprint.has_polygon()) {
    const auto& polygon = footprint.polygon();
    // Checked before copying, so an oversized list costs nothing.
    if (static_cast<std::size_t>(polygon.vertices_size()) > geometry::kMaxPolygonVertices) {
      error = field_error(prefix + ".polygon.vertices", "holds " + std::to_string(polygon.vertices_size()) +
                                                            " vertices, at most " +
                                                            std::to_string(geometry::kMaxPolygonVertices) + " allowed");
      return std::nullopt;
    }
    std::vector<Eigen::Vector2d> vertices_B;
    vertices_B.reserve(static_cast<std::size_t>(polygon.vertices_size()));
    for (const auto& vertex : polygon.vertices()) vertices_B.emplace_back(vertex.x(), vertex.y());
    // Checked in the client's order so that a named vertex is the client's; clockwise outlines are then reversed.
    if (const std::string problem = geometry::convex_polygon_problem(vertices_B, geometry::Orientation::either);
        !problem.empty()) {
      const auto space = problem.find(' ');
      error = field_error(prefix + ".polygon." + problem.substr(0, space), problem.substr(space + 1));
      return std::nullopt;
    }
    if (!finite_positive(polygon.height_m())) {
      error = field_error(prefix + ".polygon.height_m", "must be a positive length");
      return std::nullopt;
    }
    if (geometry::twice_signed_area(vertices_B) < 0.0) std::reverse(vertices_B.begin(), vertices_B.end());
    return geometry::ConvexPolygonFootprint{std::move(vertices_B), polygon.height_m()};
  }
  error = field_error(prefix, "must be a box, a cylinder or a polygon");
  return std::nullopt;
}

std::optional<FieldError> check_pose(const v1::Pose2D& pose, const std::string& field, const LimitsConfig& limits) {
  if (!std::isfinite(pose.x()) || std::abs(pose.x()) > limits.max_abs_coordinate_m) {
    return field_error(field + ".x",
                       "must be finite and within ±" + std::to_string(limits.max_abs_coordinate_m) + " m");
  }
  if (!std::isfinite(pose.y()) || std::abs(pose.y()) > limits.max_abs_coordinate_m) {
    return field_error(field + ".y",
                       "must be finite and within ±" + std::to_string(limits.max_abs_coordinate_m) + " m");
  }
  if (!std::isfinite(pose.theta())) return field_error(field + ".theta", "must be finite");
  return std::nullopt;
}

}  // namespace occgeo::service
