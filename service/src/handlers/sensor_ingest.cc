#include "sensor_ingest.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "../metrics.h"
#include "../durability/journal.h"
#include "occgeo/service/log.h"
#include "robot_control.h"

namespace occgeo::service {

void reject_sensor_message(const SessionPtr& session, Robot& robot, const FieldError& error, std::uint64_t seq) {
  robot.update_state([](RobotState& state) { ++state.scans_rejected; });
  metrics::counter("occgeo_scans_rejected_total", {{"robot", robot.model().id}}).inc();
  session->send_error(v1::ERROR_INVALID_ARGUMENT, error.field, error.message + "; the message was discarded", 0, seq);
}

bool ingest_sensor_message_on_strand(
    const SessionPtr& session, Robot& robot, const SensorMessageHeader& header,
    const std::function<void(const geometry::Pose2& X_WB, IngestTarget& target)>& insert) {
  const RobotState before = robot.state();
  const std::string kind(header.kind);
  std::string order_error;
  std::string order_field;
  if (!before.X_WB) {
    order_field = kind;
    order_error = "no odometry or wheel encoders received yet: the message cannot be placed in the world";
  } else if (before.last_scan_stamp_s && header.stamp_s < *before.last_scan_stamp_s) {
    order_field = kind + ".stamp_s";
    order_error = "timestamp went backwards (the last sensor message of this robot had " +
                  std::to_string(*before.last_scan_stamp_s) + " s)";
  } else if (before.last_scan_seq && header.seq <= *before.last_scan_seq) {
    order_field = kind + ".seq";
    order_error = "sequence number did not increase (the last sensor message of this robot had " +
                  std::to_string(*before.last_scan_seq) + ")";
  }
  if (!order_error.empty()) {
    robot.update_state([](RobotState& state) { ++state.scans_rejected; });
    metrics::counter("occgeo_scans_rejected_total", {{"robot", robot.model().id}}).inc();
    session->send_error(v1::ERROR_OUT_OF_ORDER, order_field, order_error + "; the message was discarded", 0,
                        header.seq);
    return false;
  }

  World& world = robot.world();
  // Written ahead of the map: what the map holds is in the journal, and a message that cannot be made durable is not
  // applied at all.
  durability::WorldJournal* journal = header.message ? world.journal() : nullptr;
  std::uint64_t lsn = 0;
  if (journal) {
    const auto model = robot.model_ptr();
    const auto appended = journal->append_sensor(model->id, model, model->spec, *before.X_WB, kind, *header.message);
    if (!appended.error.empty()) {
      robot.update_state([](RobotState& state) { ++state.scans_rejected; });
      log::error("journal_write_failed", {{"world", world.name()}, {"robot", model->id}, {"error", appended.error}});
      session->send_error(v1::ERROR_INTERNAL, "durability",
                          appended.error + "; the message was not applied and is not acknowledged", 0, header.seq);
      return false;
    }
    lsn = appended.lsn;
  }
  IngestTarget target{world.grid_on_strand(), world.octomap_on_strand(), std::nullopt};
  insert(*before.X_WB, target);
  world.publish_on_strand(target.touched, before.X_WB->position());

  // The robot's state first: a client that saw the ack and then asks for the status must find the message counted.
  robot.update_state([&](RobotState& state) {
    state.last_scan_stamp_s = header.stamp_s;
    state.last_scan_seq = header.seq;
    ++state.scans_ingested;
  });
  metrics::counter("occgeo_scans_ingested_total", {{"robot", robot.model().id}, {"world", world.name()}, {"kind", kind}})
      .inc();
  note_sensor_message_on_strand(robot, session->core().config().control);

  v1::ServerMessage ack;
  ack.mutable_scan_ack()->set_seq(header.seq);
  ack.mutable_scan_ack()->set_world_version(world.grid_on_strand().version());
  if (!journal) {
    session->send(std::move(ack));
    return true;
  }
  journal->when_durable(lsn, [session, ack = std::move(ack), seq = header.seq](const std::string* error) mutable {
    if (!error) {
      session->send(std::move(ack));
      return;
    }
    session->send_error(v1::ERROR_INTERNAL, "durability",
                        *error + "; the message is in the live map but was not made durable, so it is not acknowledged",
                        0, seq);
  });
  return true;
}

void IngestTarget::touch(const Eigen::Vector2d& p_W, double radius_m) {
  const geometry::GridGeometry cells(grid.params().cell_size_m);
  const Eigen::Vector2d reach(radius_m, radius_m);
  geometry::CellIndex lo = cells.cell_of(p_W - reach);
  geometry::CellIndex hi = cells.cell_of(p_W + reach);
  lo = {lo.ix - 1, lo.iy - 1};
  hi = {hi.ix + 1, hi.iy + 1};
  if (touched) {
    lo = {std::min(lo.ix, touched->min.ix), std::min(lo.iy, touched->min.iy)};
    hi = {std::max(hi.ix, touched->max.ix), std::max(hi.iy, touched->max.iy)};
  }
  touched = mapping::CellBox{lo, hi};
}

void insert_beam_3d(IngestTarget& target, const geometry::Pose3& X_WE, double reading_m, double range_min_m,
                    double range_max_m) {
  target.touch(X_WE.translation().head<2>(), range_max_m);
  if (reading_m < range_min_m) return;
  target.octomap.insert_ray(X_WE, reading_m, range_max_m);
}

geometry::Pose2 planar_beam_pose(const geometry::Pose2& X_WB, const geometry::Pose3& X_BS,
                                 const geometry::Pose2& X_SE) {
  return geometry::Pose3::from_pose2(X_WB).compose(X_BS).compose(geometry::Pose3::from_pose2(X_SE)).to_pose2();
}

void insert_beam(mapping::HimmGrid& grid, const geometry::Pose2& X_WE, double reading_m, double range_min_m,
                 double range_max_m) {
  if (reading_m < range_min_m) return;
  const double range = std::min(reading_m, range_max_m);
  const Eigen::Vector2d origin = X_WE.position();
  const Eigen::Vector2d end = origin + range * Eigen::Vector2d(std::cos(X_WE.theta), std::sin(X_WE.theta));
  grid.insert_ray(origin, end, reading_m < range_max_m);
}

}  // namespace occgeo::service
