#pragma once

#include <cstdint>
#include <functional>
#include <string_view>

#include "../ingest/model_ingest.h"
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
    world_.publish_staged_on_strand();
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
// With after_command, the publication is only staged (World::stage_on_strand): the caller computes and sends the
// robot's command from the staged grid and PTEM first, and the holder brings the distance field in step and publishes
// when it goes out of scope, so readers still see every model of one message together. With an octree lane too, the
// message's octree work and its ack are handed to the holder as well (the command does not read this message's octree
// update, and waking the lane first let it take the core from the strand); it passes both on after the publication.
bool ingest_sensor_message_on_strand(
    const SessionPtr& session, Robot& robot, const SensorMessageHeader& header,
    const std::function<void(const geometry::Pose2& X_WB, IngestTarget& target)>& insert,
    WorkAfterCommand* after_command = nullptr);

}  // namespace occgeo::service
