#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "occgeo/sim/world.h"

namespace occgeo::sim {

// Where a ray first enters the world's obstacles.
struct RayHit {
  // Distance from the ray's origin to the entry point, metres.
  double distance_m = 0.0;
  // The obstacle pixels entered there: one, or two when the ray runs exactly along the edge they share.
  std::vector<Pixel> pixels;
  // Unit normal of the obstacle surface at the entry point, world frame, pointing out of the obstacle towards the side
  // the ray came from (so its dot product with the ray's direction is <= 0). A specular sensor such as a sonar needs
  // it: an echo returns only when the ray meets the surface nearly head-on.
  Eigen::Vector2d normal_W{0.0, 0.0};
};

// Casts a ray from p_W along the unit vector direction_W (world frame, metres) and returns the exact point where it
// first enters the interior of the union of the closed obstacle pixel squares, or nullopt when that is not closer than
// max_range_m. So a ray that only touches a pixel's corner, or runs along the edge between an obstacle pixel and a free
// one, passes, while a ray along the shared edge of two obstacle pixels hits both. A ray starting inside an obstacle
// hits at distance 0. Throws std::invalid_argument unless the inputs are finite and max_range_m >= 0.
//
// Pixel surfaces are axis-aligned, so RayHit::normal_W is always one of (±1, 0), (0, ±1): the normal of the pixel edge
// the ray entered through (entering through a left edge gives (-1, 0), through a bottom edge (0, -1)). Where no single
// edge was entered -- the ray enters exactly through a pixel corner, or starts inside (or on the boundary of) an
// obstacle -- it is the axis normal the ray's direction most opposes: the x edge's when |dx| >= |dy|, else the y
// edge's. Entering through a corner, the ray meets both edges equally obliquely; picking the more head-on one matches
// what the ray would meet if it were shifted slightly.
std::optional<RayHit> cast_ray(const World& world, const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W,
                               double max_range_m);

}  // namespace occgeo::sim
