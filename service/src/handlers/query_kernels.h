#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <span>

#include "../core.h"
#include "occgeo/geometry/collision.h"
#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/v1/query.pb.h"

// The answer to one entry of each query kind (one pose, ray, point or motion) on one world snapshot. The single and
// batch handlers both call these, so a batch answers exactly like the single form; they allocate nothing per entry
// beyond the reply message itself.

namespace occgeo::service {

// Motions per SweptQuery, and poses per motion path.
inline constexpr std::size_t kMaxSweptMotions = 1000;
inline constexpr std::size_t kMaxSweptPathPoses = 100000;
// Longest SweptMotion.duration_s, seconds.
inline constexpr double kMaxSweptDuration_s = 3600.0;
// A swept footprint within this distance of an obstacle is in contact, metres.
inline constexpr double kSweptContact_m = 0.005;
// Height of planar rays above the floor for the OctoMap when the query gives none, metres.
inline constexpr double kDefaultRayHeight_m = 0.3;
// Step of the PTEM ray march, metres.
inline constexpr double kPtemRayStep_m = 0.01;
// Most octree voxels in one OctreeWindowReply.
inline constexpr std::size_t kMaxOctreeWindowVoxels = 1000000;

// The HIMM grid's answer to a collision check, shortcut by the distance field where it decides: when the cell under
// base_link is farther than the footprint's bounding radius (plus a cell diagonal and a cell of margin) from every
// occupied cell, nothing can touch (no cell tested); when base_link lies inside the footprint and on an occupied
// cell, that cell touches. Otherwise geometry::check_collision decides exactly. `hit` always equals
// geometry::check_collision's; `cell` is an occupied cell in contact. field may be null (no shortcut).
geometry::CollisionResult grid_collision(const mapping::GridSnapshot& grid, const mapping::DistanceFieldSnapshot* field,
                                         const geometry::Footprint& footprint, double bounding_radius_m,
                                         const geometry::Pose2& X_WB);

// CollisionReply for one pose; models in the order to check.
void answer_collision(const WorldSnapshot& snapshot, const geometry::Footprint& footprint, double bounding_radius_m,
                      const geometry::Pose2& X_WB, std::span<const v1::Model> models, v1::CollisionReply& out);

// ClearanceReply for one pose, with its gradient.
void answer_clearance(const WorldSnapshot& snapshot, const geometry::Footprint& footprint, const geometry::Pose2& X_WB,
                      double max_distance_m, std::span<const v1::Model> models, v1::ClearanceReply& out);

// The range along the ray from origin_W in unit direction_W at which it enters the closed square of `cell` (0 when
// it starts inside), or a negative value when it misses it. Metres.
double ray_cell_entry(const Eigen::Vector2d& origin_W, const Eigen::Vector2d& direction_W, double cell_size,
                      const geometry::CellIndex& cell);

// RaycastResult for one ray (origin and heading), per model.
void answer_raycast(const WorldSnapshot& snapshot, const geometry::Pose2& ray_W, double max_range_m, double height_m,
                    std::span<const v1::Model> models, v1::RaycastResult& out);

// OccupancySample at one point, for the models asked.
void answer_occupancy(const WorldSnapshot& snapshot, const Eigen::Vector3d& p_W, std::span<const v1::Model> models,
                      v1::OccupancySample& out);

// SweptResult for one motion (already validated): conservative advancement on the clearance over the models.
void answer_swept(const WorldSnapshot& snapshot, const geometry::Footprint& footprint,
                  std::span<const v1::Model> models, const v1::SweptMotion& motion, v1::SweptResult& out);

}  // namespace occgeo::service
