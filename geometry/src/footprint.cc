#include "occgeo/geometry/footprint.h"

#include <algorithm>
#include <cmath>

namespace occgeo::geometry {

double bounding_radius(const Footprint& footprint) {
  if (const auto* box = std::get_if<BoxFootprint>(&footprint)) {
    const double far_x = std::max(std::abs(box->center_x + box->length / 2), std::abs(box->center_x - box->length / 2));
    return std::hypot(far_x, box->width / 2);
  }
  return std::get<CylinderFootprint>(footprint).radius;
}

}  // namespace occgeo::geometry
