#pragma once

// What each sensor message does to a world's models (grid, PTEM, the octree's work) once it is placed, shared by the
// protocol's ingest (handlers/) and the journal's replay (durability/), so a restored map equals the one ingest built.
// Below both: it knows worlds and sensors, not sessions.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "../core.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/mapping/beam_limits.h"
#include "occgeo/mapping/himm_grid.h"
#include "occgeo/v1/sensors.pb.h"

namespace occgeo::service {

// What one sensor message's insertion updates, on the world's strand: the 2D grid, the box of grid cells whose
// occupancy may have flipped (for the distance field), and the work the message does to the 3D OctoMap, which the
// world applies where its octree lives (World::apply_octree_work_on_strand) once the grid is updated. Octree work
// owns what it reads: it may run on another thread after the message is gone.
struct IngestTarget {
  mapping::HimmGrid& grid;
  const mapping::OctoMapParams& octomap_params;
  std::optional<mapping::CellBox> touched;
  std::vector<OctreeWork> octree_work;

  // Adds the cells within radius_m of p_W (world, metres), plus one for the growth-rate operator,
  // to `touched`: call it with a sensor's position and its range_max_m.
  void touch(const Eigen::Vector2d& p_W, double radius_m);
};

// The sensor's pose projected on the ground plane, and whether it is mounted upside down (its
// beams then sweep clockwise in the world).
struct PlanarSensorPose {
  geometry::Pose2 X_WS;
  bool mirrored = false;
};

// The ground-plane pose of a laser on a robot at X_WB.
PlanarSensorPose planar_sensor_pose(const geometry::Pose2& X_WB, const LaserModel& laser);

// What each sensor kind's ingest does to the maps once the message is placed at X_WB; replaying a
// journal calls the same functions, so a restored map equals the one ingest built. A laser scan's returns from
// clusters its laser's tracker follows as moving (World::moving_clusters_on_strand; robot_id and the laser's name
// name that tracker) clear the cells before them and mark nothing, in the grid and the octree.
void insert_laser_scan(World& world, IngestTarget& target, const std::string& robot_id, const geometry::Pose2& X_WB,
                       const LaserModel& laser, const v1::LaserScan& scan);
void insert_range_array(IngestTarget& target, const geometry::Pose2& X_WB, const RangeArrayModel& array,
                        const v1::RangeArray& message);
void insert_servo_range(IngestTarget& target, const geometry::Pose2& X_WB, const ServoRangeModel& servo,
                        const v1::ServoRange& message);
void insert_point_cloud(IngestTarget& target, const geometry::Pose2& X_WB, const RobotModel& model,
                        const PointCloudModel& cloud, const v1::PointCloud& message);

// The ground-plane pose of a beam that lies in a sensor's x-y plane at X_SE (metres, radians) and
// measures along its own x axis, for a robot at X_WB carrying the sensor at X_BS. Composed in 3D
// and then projected, so that an upside-down mount mirrors the beams as it does physically.
geometry::Pose2 planar_beam_pose(const geometry::Pose2& X_WB, const geometry::Pose3& X_BS,
                                 const geometry::Pose2& X_SE = {});

// Applies one single-beam reading taken from a beam at X_WE on the ground plane: readings below
// range_min_m carry no information and are skipped; the others change the grid as limits say
// (mapping::beam_use: a return within max_insert_range_m is marked, free space is carved up to the
// return, max_free_range_m or, for a reading at or beyond range_max_m, no_return_clear_m).
void insert_beam(mapping::HimmGrid& grid, const geometry::Pose2& X_WE, double reading_m, double range_min_m,
                 double range_max_m, const mapping::BeamLimits& limits = {});

// The same for one beam from origin_W along the unit direction_W in the grid.
void insert_limited_ray(mapping::HimmGrid& grid, const Eigen::Vector2d& origin_W, const Eigen::Vector2d& direction_W,
                        double reading_m, double range_max_m, const mapping::BeamLimits& limits);

// The same reading in the OctoMap, along the x axis of the beam's full 6-DoF pose X_WE (robot pose
// at z = 0 ∘ mount ∘ element), and marks the cells it may touch in target.touched.
void insert_beam_3d(IngestTarget& target, const geometry::Pose3& X_WE, double reading_m, double range_min_m,
                    double range_max_m, const mapping::BeamLimits& limits = {});

}  // namespace occgeo::service
