#pragma once

// A simulated robot the load tool drives: its own driver session streaming the simulator's scans, timing each answer.

#include <memory>
#include <optional>
#include <string>
#include <unordered_map>

#include "load_common.h"
#include "occgeo/client/connection.h"
#include "occgeo/load/load_run.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/robot.h"
#include "occgeo/sim/sim_world.h"
#include "occgeo/sim/simulation.h"

namespace occgeo::load::internal {

// ---- simulated robots ---------------------------------------------------------------------------------------------

struct RobotResult {
  std::uint64_t scans = 0;
  Samples ingest;   // send of a sensor batch to the ScanAck of its last sensor message
  Samples command;  // send of a steering scan to the MotionCommand answering it (the control loop)
};

// Drives one simulated robot until `stop` (or for `scan_limit` batches when set), recording ingest latency.
class RobotDriver {
 public:
  RobotDriver(const LoadOptions& options, const client::Endpoint& endpoint, std::string robot_id, std::uint64_t seed,
              double heading_rad, ErrorLog& errors)
      : options_(options), robot_id_(std::move(robot_id)), errors_(errors) {
    const sim::RobotPreset* preset = sim::find_robot_preset(options.robot_preset);
    if (preset == nullptr) {
      throw LoadArgsError("--robot: unknown preset '" + options.robot_preset + "' (" + sim::robot_preset_names() + ")");
    }
    const geometry::Pose2 start{0.0, 0.0, heading_rad};
    simulation_ = std::make_unique<sim::Simulation>(sim::load_sim_world(options.world_file), *preset, start, seed);
    connection_.emplace(client::Connection::open(endpoint));
    connection_->hello(sim::make_driver_hello(robot_id_, ""));
    v1::ClientMessage spec;
    *spec.mutable_robot_spec() = sim::make_robot_spec(*preset, start);
    connection_->send(spec);
  }

  // Lockstep batches until `batches` sensor batches were answered.
  void run_lockstep_batches(std::uint32_t batches, const std::atomic<bool>& stop) {
    std::uint32_t sent = 0;
    while (sent < batches && !stop.load()) {
      if (simulation_->batch_due()) {
        send_batch(true);
        ++sent;
      }
      simulation_->step();
    }
  }

  void run(const std::atomic<bool>& stop) {
    const bool lockstep = options_.robot_pace == RobotPace::lockstep;
    const auto wall_start = Clock::now();
    while (!stop.load()) {
      if (simulation_->batch_due()) send_batch(lockstep);
      if (!lockstep) {
        const auto step_end =
            wall_start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(
                             static_cast<double>(simulation_->robot().step_count() + 1) * sim::kPhysicsStep_s));
        do {
          const auto wait = std::chrono::duration_cast<milliseconds>(step_end - Clock::now());
          const auto message = connection_->receive(std::max(wait, milliseconds(0)));
          if (!message) break;
          handle(*message);
        } while (Clock::now() < step_end);
        std::this_thread::sleep_until(step_end);
      }
      simulation_->step();
    }
  }

  void close() { connection_->close(); }
  RobotResult& result() { return result_; }

 private:
  void send_batch(bool await_answer) {
    const sim::SensorBatch batch = simulation_->take_batch();
    const auto sent_at = Clock::now();
    for (const v1::ClientMessage& message : batch.messages) connection_->send(message);
    if (batch.last_sensor_seq != 0) sent_at_[batch.last_sensor_seq] = sent_at;
    if (batch.steering_scan_seq) command_sent_at_[*batch.steering_scan_seq] = sent_at;
    if (!await_answer) return;
    // Lockstep: the ScanAck of the batch's last sensor message and the command answering the steering scan.
    answered_ = !batch.steering_scan_seq.has_value();
    awaited_command_seq_ = batch.steering_scan_seq.value_or(0);
    const auto deadline = Clock::now() + kLockstepAnswerTimeout;
    while ((sent_at_.contains(batch.last_sensor_seq) || !answered_) && Clock::now() < deadline) {
      const auto message = connection_->receive(std::chrono::duration_cast<milliseconds>(deadline - Clock::now()));
      if (message) handle(*message);
    }
    if (sent_at_.contains(batch.last_sensor_seq) || !answered_) {
      errors_.add(robot_id_ + ": no answer to sensor batch " + std::to_string(batch.last_sensor_seq) + " within " +
                  std::to_string(kLockstepAnswerTimeout.count()) + " s");
      sent_at_.clear();
      command_sent_at_.clear();
      answered_ = true;
    }
  }

  void handle(const v1::ServerMessage& message) {
    if (message.has_scan_ack()) {
      // A resend of a scan the server already journalled (a simulation replaying an earlier run's scans to a server
      // that outlived it) is acknowledged but not applied: no command will answer it.
      if (message.scan_ack().duplicate() && message.scan_ack().seq() == awaited_command_seq_) answered_ = true;
      const auto found = sent_at_.find(message.scan_ack().seq());
      if (found != sent_at_.end()) {
        add_sample(result_.ingest, Clock::now() - found->second);
        ++result_.scans;
        sent_at_.erase(found);
      }
    } else if (message.has_motion_command()) {
      const std::uint64_t answers = message.motion_command().answers_scan_seq();
      const auto found = command_sent_at_.find(answers);
      if (found != command_sent_at_.end()) add_sample(result_.command, Clock::now() - found->second);
      // Commands come in scan order: steering scans before this one that got none never will.
      if (answers != 0)
        std::erase_if(command_sent_at_, [answers](const auto& entry) { return entry.first <= answers; });
      simulation_->apply_command(message.motion_command());
      if (message.motion_command().answers_scan_seq() == awaited_command_seq_) answered_ = true;
    } else if (message.has_error()) {
      errors_.add(robot_id_ + ": " + client::describe(message.error()));
    }
  }

  const LoadOptions& options_;
  std::string robot_id_;
  ErrorLog& errors_;
  std::unique_ptr<sim::Simulation> simulation_;
  std::optional<client::Connection> connection_;
  std::unordered_map<std::uint64_t, Clock::time_point> sent_at_;
  std::unordered_map<std::uint64_t, Clock::time_point> command_sent_at_;  // steering scans awaiting their command
  bool answered_ = true;
  std::uint64_t awaited_command_seq_ = 0;
  RobotResult result_;
};

}  // namespace occgeo::load::internal
