#pragma once

#include <variant>

namespace occgeo::geometry {

// A box in base_link: centred at (center_x, 0), length along x, width along y, from z = 0 up to
// height. Metres.
struct BoxFootprint {
  double length = 1.0;
  double width = 0.8;
  double height = 1.0;
  double center_x = 0.0;
};

// A vertical cylinder centred on the base_link origin, from z = 0 up to height. Metres.
struct CylinderFootprint {
  double radius = 0.5;
  double height = 1.0;
};

using Footprint = std::variant<BoxFootprint, CylinderFootprint>;

// Radius of the smallest circle about the base_link origin that holds the footprint, metres.
double bounding_radius(const Footprint& footprint);

}  // namespace occgeo::geometry
