#pragma once

#include <Eigen/Core>
#include <variant>
#include <vector>

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

// A convex polygon in base_link's xy plane, extruded from z = 0 up to height. Metres. vertices_B are in
// counter-clockwise order, strictly convex, without repeating the first vertex (service validation normalises
// clockwise input and rejects anything else).
struct ConvexPolygonFootprint {
  std::vector<Eigen::Vector2d> vertices_B;
  double height = 1.0;
};

using Footprint = std::variant<BoxFootprint, CylinderFootprint, ConvexPolygonFootprint>;

// Radius of the smallest circle about the base_link origin that holds the footprint, metres.
double bounding_radius(const Footprint& footprint);

// Height of the footprint's top above base_link's ground plane, metres, whatever its shape.
double footprint_height(const Footprint& footprint);

// A polygon footprint as a closed convex mesh in base_link, in FCL's fcl::Convex encoding (kept free of FCL types so
// this header stays FCL-free): vertices_B[0, n) is the ring at z = 0, vertices_B[n, 2n) the ring at z = height;
// faces holds, per face, its vertex count then its vertex indices, counter-clockwise seen from outside.
struct PrismMesh {
  std::vector<Eigen::Vector3d> vertices_B;
  std::vector<int> faces;
  int face_count = 0;
};
PrismMesh prism_mesh(const ConvexPolygonFootprint& polygon);

}  // namespace occgeo::geometry
