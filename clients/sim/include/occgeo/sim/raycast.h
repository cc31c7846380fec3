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
};

// Casts a ray from p_W along the unit vector direction_W (world frame, metres) and returns the exact point where it
// first enters the interior of the union of the closed obstacle pixel squares, or nullopt when that is not closer than
// max_range_m. So a ray that only touches a pixel's corner, or runs along the edge between an obstacle pixel and a free
// one, passes, while a ray along the shared edge of two obstacle pixels hits both. A ray starting inside an obstacle
// hits at distance 0. Throws std::invalid_argument unless the inputs are finite and max_range_m >= 0.
std::optional<RayHit> cast_ray(const World& world, const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W,
                               double max_range_m);

}  // namespace occgeo::sim
