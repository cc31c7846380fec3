#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <span>

#include "occgeo/geometry/collision.h"
#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/mapping/ptem.h"
#include "occgeo/mapping/terrain.h"

// Collision and clearance of a robot's footprint against the models other than the HIMM grid: the
// OctoMap (in the footprint's height band) and the PTEM's restricted region. Used by the query
// handlers (queries.cc).

namespace occgeo::service {

// The OctoMap's voxels below this height are the floor for footprint queries, metres: a depth
// camera sees the floor as occupied voxels in [0, resolution) (and, with noise, the one above), so
// the footprint is checked over z in [ground_band, height]: max(terrain.ground_band_m, resolution) + 0.01 m, under
// the octree's own terrain rule (OctoMapSnapshot::terrain).
double octomap_ground_band_m(const mapping::OctoMapSnapshot& octomap);

// The terrain of the cells of cell_size_m covering the box [lo_W, hi_W] (world frame, metres) for a robot of
// height_m standing at robot_W, under the octree's terrain rule (OctoMapSnapshot::terrain).
mapping::TerrainMap terrain_around(const mapping::OctoMapSnapshot& octomap, double cell_size_m,
                                   const Eigen::Vector2d& lo_W, const Eigen::Vector2d& hi_W, double height_m,
                                   const std::optional<Eigen::Vector2d>& robot_W);

// The occupied cells of a grid (or any cell source of the terrain's cell size) less those whose drivable surface
// explains them (TerrainMap::explains_returns): a laser plane meeting a ramp, a depth camera's points on it.
class TerrainMaskedCells final : public geometry::OccupiedCellSource {
 public:
  // Both must outlive this; terrain.cell_size() must equal cells.cell_size().
  TerrainMaskedCells(const geometry::OccupiedCellSource& cells, const mapping::TerrainMap& terrain)
      : cells_(cells), terrain_(terrain) {}
  [[nodiscard]] double cell_size() const override { return cells_.cell_size(); }
  void for_each_occupied(geometry::CellIndex min, geometry::CellIndex max,
                         const std::function<bool(const geometry::CellIndex&)>& visit) const override;

 private:
  const geometry::OccupiedCellSource& cells_;
  const mapping::TerrainMap& terrain_;
};

// A disc on the ground, world frame, metres.
struct GroundDisc {
  Eigen::Vector2d centre_W = Eigen::Vector2d::Zero();
  double radius_m = 0.0;
};

// The cells (of cell_size_m) holding a return of the PTEM clusters made within max_age_s of the snapshot's latest scan
// (PtemCluster::age_s) that lies within one of `within` (2 cm of margin): what the laser sees now of the people and
// carts tracked as moving, whose returns the grid does not keep. A cell is visited once per return in it.
class RecentReturnCells final : public geometry::OccupiedCellSource {
 public:
  // ptem and within must outlive this.
  RecentReturnCells(const mapping::PtemSnapshot& ptem, double max_age_s, double cell_size_m,
                    std::span<const GroundDisc> within)
      : ptem_(ptem), max_age_s_(max_age_s), cells_(cell_size_m), within_(within) {}
  [[nodiscard]] double cell_size() const override { return cells_.cell_size(); }
  void for_each_occupied(geometry::CellIndex min, geometry::CellIndex max,
                         const std::function<bool(const geometry::CellIndex&)>& visit) const override;

 private:
  const mapping::PtemSnapshot& ptem_;
  double max_age_s_;
  geometry::GridGeometry cells_;
  std::span<const GroundDisc> within_;
};

// The OctoMap's occupied voxels whose z range overlaps [ground_band, top_m], projected on the
// ground as grid cells of the octree's resolution (cell (ix, iy) covers [ix r, (ix+1) r) x
// [iy r, (iy+1) r), the same squares as the voxels' columns), so that geometry::compute_clearance
// and check_collision can measure against them exactly as against the HIMM grid. A pruned voxel
// covers several cells; a column holding several voxels is visited once per voxel. With a terrain,
// the band over a drivable cell is measured from its surface (TerrainMap::obstacle_band): the
// surface itself is no obstacle, what stands on it up to top_m above it is.
class OctoMapColumns final : public geometry::OccupiedCellSource {
 public:
  // octomap and terrain (when given) must outlive the columns. plausible_surfaces: measure over the terrain's
  // plausible cells from their surface too (for planning; see TerrainMap::bridge_unseen_gaps).
  OctoMapColumns(const mapping::OctoMapSnapshot& octomap, double top_m, const mapping::TerrainMap* terrain = nullptr,
                 bool plausible_surfaces = false);
  [[nodiscard]] double cell_size() const override { return octomap_.resolution(); }
  void for_each_occupied(geometry::CellIndex min, geometry::CellIndex max,
                         const std::function<bool(const geometry::CellIndex&)>& visit) const override;

 private:
  const mapping::OctoMapSnapshot& octomap_;
  double bottom_m_;
  double top_m_;
  const mapping::TerrainMap* terrain_;
  bool plausible_surfaces_;
};

// The 3D footprint (box or cylinder standing on base_link's z = 0) at the planar pose X_WB against
// the OctoMap's occupied voxels with FCL, over z in [octomap_ground_band_m, height] (the footprint is
// lifted and shortened accordingly; a footprint no taller than the band hits nothing).
mapping::OctoCollision collide_octomap(const mapping::OctoMapSnapshot& octomap, const geometry::Footprint& footprint,
                                       const geometry::Pose2& X_WB);

// The point of the footprint (its filled outline on the ground) nearest to p_W, world frame; p_W itself when inside.
Eigen::Vector2d nearest_footprint_point(const geometry::Footprint& footprint, const geometry::Pose2& X_WB,
                                        const Eigen::Vector2d& p_W);

// The centre of the footprint's outline, world frame (the box's centre or the cylinder's axis).
Eigen::Vector2d footprint_center(const geometry::Footprint& footprint, const geometry::Pose2& X_WB);

// Spacing of the points of the footprint sampled against the PTEM's restricted test, metres.
inline constexpr double kPtemSampleStep_m = 0.05;

// Where a footprint meets the PTEM's restricted region (threat >= f_r, see ptem.h).
struct PtemContact {
  bool hit = false;
  Eigen::Vector2d point_W = Eigen::Vector2d::Zero();  // a restricted point of the footprint, world, metres
};

// Does the footprint at X_WB overlap the PTEM's restricted region? Exact for each cluster on its
// own (its circle is where its own PDF equals f_r, or is wholly restricted when f_r is unreachable:
// a circle–box or circle–circle overlap test); the sum of several PDFs can reach f_r outside the
// circles, which is caught by testing restricted() on the footprint's boundary and interior every
// kPtemSampleStep_m (so a restricted sliver thinner than that between sample points can be
// missed). Nothing is restricted while f_r is not fixed.
PtemContact collide_ptem(const mapping::PtemSnapshot& ptem, const geometry::Footprint& footprint,
                         const geometry::Pose2& X_WB);
// The same, given geometry::bounding_radius(footprint) already worked out.
PtemContact collide_ptem(const mapping::PtemSnapshot& ptem, const geometry::Footprint& footprint,
                         const geometry::Pose2& X_WB, double bounding_radius_m);

// Distance from the footprint at X_WB to the PTEM's restricted region, looking no farther than
// max_distance_m: 0 when collide_ptem hits, else the distance to the nearest cluster circle
// (exact for separate clusters; overlapping PDFs can make the true region larger, so then this is
// an upper bound).
struct PtemClearance {
  bool found = false;
  double clearance_m = 0.0;
  Eigen::Vector2d nearest_point_W = Eigen::Vector2d::Zero();  // of the restricted region, world, metres
};
PtemClearance ptem_clearance(const mapping::PtemSnapshot& ptem, const geometry::Footprint& footprint,
                             const geometry::Pose2& X_WB, double max_distance_m);

// Matter, not threat: does the footprint at X_WB (closed) hold one of the returns a cluster gathered
// (PtemCluster::extent_W)? A cluster's circle reaches into free floor beside and behind its returns, and the summed
// PDFs' region beyond the circles even more: both are collide_ptem's keep-out, not a contact.
PtemContact collide_ptem_extent(const mapping::PtemSnapshot& ptem, const geometry::Footprint& footprint,
                                const geometry::Pose2& X_WB, double bounding_radius_m);
// Distance from the footprint at X_WB to the nearest return of any cluster's extent, no farther than max_distance_m;
// 0 when the footprint holds one.
PtemClearance ptem_extent_clearance(const mapping::PtemSnapshot& ptem, const geometry::Footprint& footprint,
                                    const geometry::Pose2& X_WB, double max_distance_m);

}  // namespace occgeo::service
