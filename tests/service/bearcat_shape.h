#pragma once

// The Bearcat as the behaviours see it (1.0 x 0.8 m box, laser 0.45 m ahead of the axle, 1.2 m/s), shared by the
// behaviour tests that drive it without a server.

#include "occgeo/service/control/behaviour.h"

namespace occgeo::service::control {

inline RobotShape bearcat_shape() {
  RobotShape shape;
  shape.footprint = geometry::BoxFootprint{.length = 1.0, .width = 0.8, .height = 1.2, .center_x = 0.0};
  shape.laser_x_m = 0.45;
  shape.max_linear_mps = 1.2;
  return shape;
}

}  // namespace occgeo::service::control
