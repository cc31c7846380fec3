#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>

#include "occgeo/geometry/cell.h"
#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/pose.h"

namespace occgeo::geometry {

// Where the occupied cells come from (the HIMM grid's snapshot implements this).
class OccupiedCellSource {
 public:
  virtual ~OccupiedCellSource() = default;
  virtual double cell_size() const = 0;
  // Calls visit for every occupied cell with min.ix<=ix<=max.ix and min.iy<=iy<=max.iy; visit returns false to stop
  // early.
  virtual void for_each_occupied(CellIndex min, CellIndex max,
                                 const std::function<bool(const CellIndex&)>& visit) const = 0;
};

// Is the footprint at this pose in contact with any occupied cell? Each occupied cell is a closed square prism as
// tall as the footprint, so the test is 2D; touching counts as contact.
struct CollisionRequest {
  Footprint footprint;
  Pose2 pose;  // X_WB: base_link in world, metres and radians.
};

struct CollisionResult {
  bool hit = false;
  std::optional<CellIndex> cell;  // An occupied cell in contact with the footprint, set when hit.
  int cells_tested = 0;           // Occupied cells inside the footprint's world AABB that were examined.
};

// Answers a CollisionRequest; throws std::invalid_argument naming the field when the pose is not finite, a footprint
// dimension is not positive, or the pose is so far out that cell indices would overflow int32.
CollisionResult check_collision(const CollisionRequest& request, const OccupiedCellSource& source);

// How far is the footprint at this pose from the nearest occupied cell, looking no farther than max_distance_m?
struct ClearanceRequest {
  Footprint footprint;
  Pose2 pose;                   // X_WB: base_link in world, metres and radians.
  double max_distance_m = 5.0;  // Search radius beyond the footprint, metres; must be finite and >= 0.
};

struct ClearanceResult {
  bool found = false;        // An occupied cell lies within max_distance_m of the footprint.
  double clearance_m = 0.0;  // Footprint-to-nearest-cell distance: 0 in contact, max_distance_m when not found.
  std::optional<CellIndex> nearest_cell;  // The nearest occupied cell, set when found.
  // The point of nearest_cell closest to the footprint, in world (metres); when in contact, the point of the cell
  // closest to the footprint's centre; zero when not found.
  Eigen::Vector2d nearest_point_W = Eigen::Vector2d::Zero();
};

// Answers a ClearanceRequest, searching outwards ring by ring of cells (so the cost over empty space grows with
// (max_distance_m / cell_size)^2); throws std::invalid_argument naming the field like check_collision, and for a
// negative or non-finite max_distance_m.
ClearanceResult compute_clearance(const ClearanceRequest& request, const OccupiedCellSource& source);

}  // namespace occgeo::geometry
