#pragma once

// A family of dynamic worlds generated from a seed number: aisles with bays, open halls with pillars and two rooms
// joined by a doorway, each with people and carts crossing the robot's way, walking along or against it, looping or
// stopping, setting off at different times. The robot starts at the origin facing +x; its goal lies straight ahead at
// the far end. A layout nobody tuned the behaviours for is the point: the family is judged by its rates.

#include <Eigen/Core>
#include <cstdint>
#include <string>

namespace occgeo::testing {

struct DynamicWorld {
  std::string name;         // "aisle-7": layout and seed
  std::string layout;       // aisle | hall | doorway
  std::string yaml;         // the occgeo-sim shape world, with its moving obstacles
  std::string yaml_static;  // the same world without them (the reference run's)
  Eigen::Vector2d goal_W;   // world frame, metres
  int moving_obstacles = 0;
  std::string description;  // one line: what moves where, how fast, from when
};

// The world of this seed; the same seed always gives the same world.
DynamicWorld make_dynamic_world(std::uint32_t seed);

}  // namespace occgeo::testing
