#include "sensor_ingest.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "../durability/journal.h"
#include "../metrics.h"
#include "occgeo/service/log.h"
#include "robot_control.h"

namespace occgeo::service {

void reject_sensor_message(const SessionPtr& session, Robot& robot, const FieldError& error, std::uint64_t seq) {
  robot.update_state([](RobotState& state) { ++state.scans_rejected; });
  robot.counters().scans_rejected.inc();
  session->send_error(v1::ERROR_INVALID_ARGUMENT, error.field, error.message + "; the message was discarded", 0, seq);
}

namespace {

// The event that hands an accepted sensor message to the observers recording the session: a copy, with where it was
// placed and which cells it may have changed; nullptr for a kind they are not sent. Posting it is all that happens
// later; a slow observer's queue drops, never this strand.
std::shared_ptr<v1::WatchEvent> accepted_event(World& world, const SensorMessageHeader& header,
                                               const geometry::Pose2& X_WB,
                                               const std::optional<mapping::CellBox>& touched) {
  auto event = std::make_shared<v1::WatchEvent>();
  event->set_seq(header.seq);
  event->set_world_version(world.grid_on_strand().version());
  event->set_cell_size_m(world.grid_on_strand().params().cell_size_m);
  event->mutable_pose()->set_x(X_WB.x);
  event->mutable_pose()->set_y(X_WB.y);
  event->mutable_pose()->set_theta(X_WB.theta);
  if (touched) {
    event->mutable_changed_cells()->mutable_min()->set_ix(touched->min.ix);
    event->mutable_changed_cells()->mutable_min()->set_iy(touched->min.iy);
    event->mutable_changed_cells()->mutable_max()->set_ix(touched->max.ix);
    event->mutable_changed_cells()->mutable_max()->set_iy(touched->max.iy);
  }
  const google::protobuf::MessageLite& message = *header.message;
  if (header.kind == "laser_scan") {
    event->mutable_laser_scan()->CheckTypeAndMergeFrom(message);
  } else if (header.kind == "range_array") {
    event->mutable_range_array()->CheckTypeAndMergeFrom(message);
  } else if (header.kind == "servo_range") {
    event->mutable_servo_range()->CheckTypeAndMergeFrom(message);
  } else if (header.kind == "point_cloud") {
    event->mutable_point_cloud()->CheckTypeAndMergeFrom(message);
  } else {
    return nullptr;
  }
  return event;
}

}  // namespace

bool ingest_sensor_message_on_strand(
    const SessionPtr& session, Robot& robot, const SensorMessageHeader& header,
    const std::function<void(const geometry::Pose2& X_WB, IngestTarget& target)>& insert,
    WorkAfterCommand* after_command) {
  const RobotState before = robot.state();
  const std::string kind(header.kind);
  World& world_of_robot = robot.world();
  durability::WorldJournal* const world_journal = header.message ? world_of_robot.journal() : nullptr;
  if (world_journal && world_journal->already_delivered(robot.model().id, header.seq, kind, *header.message)) {
    // The same message (robot, seq and content) is already in the journal: a driver resending it after losing its ack
    // (a dropped connection, a server restart). It is acknowledged as durable again, once the record is, and not
    // applied twice; the robot's order moves past it.
    robot.update_state([&](RobotState& state) {
      state.last_scan_seq = std::max(state.last_scan_seq.value_or(0), header.seq);
      state.last_scan_stamp_s = std::max(state.last_scan_stamp_s.value_or(header.stamp_s), header.stamp_s);
    });
    robot.counters().scans_duplicate.inc();
    v1::ServerMessage ack;
    ack.mutable_scan_ack()->set_seq(header.seq);
    ack.mutable_scan_ack()->set_world_version(world_of_robot.grid_on_strand().version());
    ack.mutable_scan_ack()->set_duplicate(true);
    world_of_robot.after_publications_on_strand(
        [world_journal, lsn = world_journal->last_lsn(), session, ack = std::move(ack)]() mutable {
          world_journal->when_durable(lsn, [session, ack = std::move(ack)](const std::string* error) mutable {
            if (!error) {
              session->send(ack);
              return;
            }
            session->send_error(v1::ERROR_INTERNAL, "durability", *error + "; the resent message is not acknowledged",
                                0, ack.scan_ack().seq());
          });
        });
    return false;
  }
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
    robot.counters().scans_rejected.inc();
    auto send_rejection = [session, order_field, message = order_error + "; the message was discarded",
                           seq = header.seq](const std::string* /*sync_error*/) {
      session->send_error(v1::ERROR_OUT_OF_ORDER, order_field, message, 0, seq);
    };
    // Replies to a driver's sensor messages keep the messages' order: under the batch policy the acks of earlier
    // messages may still wait for their fsync, and this rejection must not overtake them.
    // Nor may it overtake the acks still waiting for their publication.
    if (durability::WorldJournal* journal = robot.world().journal()) {
      robot.world().after_publications_on_strand(
          [journal, lsn = journal->last_lsn(), send_rejection = std::move(send_rejection)]() mutable {
            journal->when_durable(lsn, std::move(send_rejection));
          });
    } else {
      robot.world().after_publications_on_strand(
          [send_rejection = std::move(send_rejection)] { send_rejection(nullptr); });
    }
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
    journal->note_delivered(model->id, header.seq, appended.fingerprint);
  }
  IngestTarget target{world.grid_on_strand(), world.octomap_params(), std::nullopt, {}};
  insert(*before.X_WB, target);
  // Without a lane the octree is updated here, in step with the grid, as lockstep runs expect.
  const bool defer_to_after_command = after_command && world.octree_has_lane();
  if (!defer_to_after_command) world.apply_octree_work_on_strand(std::move(target.octree_work));
  if (after_command) {
    world.stage_on_strand(target.touched);
  } else {
    world.publish_on_strand(target.touched);
  }
  // Sent once published, like the ack: an observer that asks for the grid's changes since the event's world_version
  // must find them.
  std::shared_ptr<v1::WatchEvent> watch_event =
      header.message && session->data_watched() ? accepted_event(world, header, *before.X_WB, target.touched) : nullptr;

  // The robot's state first: a client that saw the ack and then asks for the status must find the message counted.
  robot.update_state([&](RobotState& state) {
    state.last_scan_stamp_s = header.stamp_s;
    state.last_scan_seq = header.seq;
    ++state.scans_ingested;
  });
  robot.ingested_counter_on_strand(session->core().metrics(), kind).inc();
  note_sensor_message_on_strand(robot, session->core().config().control);

  v1::ServerMessage ack;
  ack.mutable_scan_ack()->set_seq(header.seq);
  ack.mutable_scan_ack()->set_world_version(world.grid_on_strand().version());
  auto acknowledge_once_published = [journal, lsn, session, ack = std::move(ack), seq = header.seq]() mutable {
    if (!journal) {
      session->send(ack);
      return;
    }
    journal->when_durable(lsn, [session, ack = std::move(ack), seq](const std::string* error) mutable {
      if (!error) {
        session->send(ack);
        return;
      }
      session->send_error(
          v1::ERROR_INTERNAL, "durability",
          *error + "; the message is in the live map but was not made durable, so it is not acknowledged", 0, seq);
    });
  };
  auto acknowledge = [&world, session, watch_event = std::move(watch_event),
                      reply = std::move(acknowledge_once_published)]() mutable {
    world.after_publications_on_strand(
        [session, watch_event = std::move(watch_event), reply = std::move(reply)]() mutable {
          if (watch_event) session->publish_data(std::move(watch_event));
          reply();
        });
  };
  if (after_command) {
    // Acknowledged once published: a client that saw the ack reads this message in every model but the octree.
    after_command->hold(defer_to_after_command ? std::move(target.octree_work) : std::vector<OctreeWork>{},
                        std::move(acknowledge));
  } else {
    acknowledge();
  }
  return true;
}

}  // namespace occgeo::service
