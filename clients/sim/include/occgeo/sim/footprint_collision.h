#pragma once

#include <optional>

#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/sim/world.h"

namespace occgeo::sim {

// The first obstacle pixel (in row, then column order) whose square overlaps the box footprint placed at base_link pose
// X_WB with positive area, or nullopt when the footprint is clear. Exact separating-axis test of the rotated box
// against each pixel square; touching along an edge or at a corner is not a collision.
std::optional<Pixel> find_collision(const World& world, const geometry::BoxFootprint& footprint,
                                    const geometry::Pose2& X_WB);

}  // namespace occgeo::sim
