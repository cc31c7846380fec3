#pragma once

#include <filesystem>
#include <vector>

#include "occgeo/geometry/pose.h"
#include "occgeo/mapfile/map_picture.h"
#include "occgeo/sim/sim_world.h"

namespace occgeo::sim {

// Side of a picture pixel when a shape world is rasterised, metres.
inline constexpr double kShapePictureResolution_m = 0.05;
// Free ground shown around a shape world without bounds, beyond its shapes and the trajectory, metres.
inline constexpr double kShapePictureMargin_m = 1.0;

// A picture of the simulator's ground truth for --png-out: a pixel world's image (obstacle pixels black, the rest
// white, one picture pixel per world pixel), or a shape world rasterised at kShapePictureResolution_m (static shapes,
// and moving obstacles where they are at time_s, black) over its bounds or else the box around its shapes and the
// trajectory; with the trajectory (base_link poses, in order) drawn as a red line and its last pose marked. Throws
// std::runtime_error when a shape world's picture would exceed 20000 pixels a side.
mapfile::MapPicture run_picture(const SimWorld& world, const std::vector<geometry::Pose2>& trajectory, double time_s);

}  // namespace occgeo::sim
