#pragma once

#include <cstdint>
#include <functional>
#include <string_view>

#include "../validation.h"
#include "handlers.h"

namespace occgeo::service {

// What every sensor message (LaserScan, RangeArray, ServoRange, PointCloud) carries for ordering.
struct SensorMessageHeader {
  std::string_view kind;  // its ClientMessage field, e.g. "range_array"; errors name fields under it
  std::uint64_t seq = 0;
  double stamp_s = 0.0;
  // The message itself, written to the world's journal before it is applied (replay needs it whole).
  const google::protobuf::MessageLite* message = nullptr;
};

// A sensor message's octree work and its ack, held back until the strand task that ingested the message has sent the
// robot's command. On destruction (still within the same strand turn) the work goes to the world's octree lane
// (World::apply_octree_work_on_strand), in journal order, and only then is the ack released: a client that saw the ack
// and then reads the octree finds the message applied, as in every other model. Declare it before ingesting.
class WorkAfterCommand {
 public:
  explicit WorkAfterCommand(World& world) : world_(world) {}
  ~WorkAfterCommand() {
    if (!octree_work_.empty()) world_.apply_octree_work_on_strand(std::move(octree_work_));
    if (acknowledge_) acknowledge_();
  }
  WorkAfterCommand(const WorkAfterCommand&) = delete;
  WorkAfterCommand& operator=(const WorkAfterCommand&) = delete;
  void hold(std::vector<OctreeWork> octree_work, std::function<void()> acknowledge) {
    octree_work_ = std::move(octree_work);
    acknowledge_ = std::move(acknowledge);
  }

 private:
  World& world_;
  std::vector<OctreeWork> octree_work_;
  std::function<void()> acknowledge_;
};

// Answers a sensor message that failed validation: counts the rejection in the robot's status
// and sends ERROR_INVALID_ARGUMENT naming the field. Nothing reaches the map.
void reject_sensor_message(const SessionPtr& session, Robot& robot, const FieldError& error, std::uint64_t seq);

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

// Updates the map from one validated sensor message; runs on the robot's world strand. Sensor
// messages share one order per robot whatever their kind, so a range array cannot slip in
// between a laser scan and the next with a stale seq or stamp. When the robot has a pose and the
// message's seq increases and its stamp does not go backwards, calls insert(X_WB, target) with the
// robot's latest pose (the grid and the OctoMap to update), publishes one snapshot (bringing the
// distance field in step over target.touched), sends the ScanAck and records the message in the
// robot's state, then returns true. Otherwise sends ERROR_OUT_OF_ORDER naming the field, counts
// the rejection and returns false, leaving the map alone.
// Before insert runs, the message and the pose are written to the world's journal; the ScanAck
// goes out only once that record is durable under durability.policy. A journal that cannot be
// written (disk full, I/O error) gets ERROR_INTERNAL with field "durability" instead, and the
// message is not applied.
//
// With after_command and an octree lane, the message's octree work and its ack are handed to it: the caller computes
// and sends the robot's command first (the command does not read this message's octree update, and waking the lane
// first let it take the core from the strand), and the holder passes both on when it goes out of scope.
bool ingest_sensor_message_on_strand(
    const SessionPtr& session, Robot& robot, const SensorMessageHeader& header,
    const std::function<void(const geometry::Pose2& X_WB, IngestTarget& target)>& insert,
    WorkAfterCommand* after_command = nullptr);

// What each sensor kind's ingest does to the maps once the message is placed at X_WB; replaying a
// journal calls the same functions, so a restored map equals the one ingest built.
void insert_laser_scan(World& world, IngestTarget& target, const geometry::Pose2& X_WB, const LaserModel& laser,
                       const v1::LaserScan& scan);
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
