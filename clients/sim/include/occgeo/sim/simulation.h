#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <variant>
#include <vector>

#include "occgeo/geometry/pose.h"
#include "occgeo/sim/depth_sensor.h"
#include "occgeo/sim/laser.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/range_sensors.h"
#include "occgeo/sim/robot.h"
#include "occgeo/sim/sim_world.h"
#include "occgeo/sim/world.h"
#include "occgeo/v1/session.pb.h"

namespace occgeo::sim {

// One body-velocity segment of a --drive script.
struct DriveSegment {
  double linear_mps = 0.0;     // forward speed, m/s
  double angular_radps = 0.0;  // yaw rate, rad/s, counter-clockwise positive
  double duration_s = 0.0;     // how long the segment lasts, seconds, positive
};

// Segments driven one after the other and round again from the first.
using DriveScript = std::vector<DriveSegment>;

// Time between WheelEncoders messages of an encoder robot without a servo sensor, seconds.
inline constexpr double kEncoderPeriod_s = 0.02;

// The messages due at one sim time, to be sent in this order: the pose (Odometry, or WheelEncoders for an encoder
// robot) first, then the sensor messages.
struct SensorBatch {
  std::vector<v1::ClientMessage> messages;
  // seq of the last sensor message (LaserScan, RangeArray, ServoRange, PointCloud) in the batch, whose ScanAck closes
  // it; 0 when the batch has none.
  std::uint64_t last_sensor_seq = 0;
  // seq of the steering sensor's message (the first laser's scan, else the first range array's firing) when the batch
  // holds it: the server answers it with a MotionCommand.
  std::optional<std::uint64_t> steering_scan_seq;

  // The batch's LaserScan from the named sensor (the first laser when sensor is empty), or nullptr.
  [[nodiscard]] const v1::LaserScan* laser_scan(const std::string& sensor = "") const;
};

// One simulated run without the network: the world, the robot, its sensors each on its own schedule, and the counts
// the summary reports. Deterministic for a seed. Not copyable or movable (the robot refers to the world it holds).
class Simulation {
 public:
  // Throws std::invalid_argument when the robot collides at the start pose X_WB_start or a sensor's period is not a
  // positive whole number of physics steps (the message names the sensor).
  Simulation(World world, const RobotPreset& preset, const geometry::Pose2& X_WB_start, std::uint64_t seed);
  // The same for any world (pixel or shape world); throws std::invalid_argument when world is null.
  Simulation(std::unique_ptr<SimWorld> world, const RobotPreset& preset, const geometry::Pose2& X_WB_start,
             std::uint64_t seed);
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;

  // Makes the robot follow script (looped from sim time 0, each segment rounded to whole physics steps) instead of the
  // server's motion commands, which are then counted as ignored. Throws std::invalid_argument for an empty script or a
  // segment that is not finite or shorter than one physics step.
  void set_drive_script(DriveScript script);
  [[nodiscard]] bool has_drive_script() const { return !script_.empty(); }

  // True when some sensor (or the encoders) is due at the current sim time and this time's batch was not taken yet.
  // Every sensor fires at t = 0 and then every period.
  [[nodiscard]] bool batch_due() const;
  // Takes the batch due now: the pose message, then each due sensor's message in the preset's sensor order, seqs of
  // sensor messages counting from 1 in one sequence.
  SensorBatch take_batch();
  // Delays every motion command received from now on by latency_s of sim time before it reaches the wheels: the
  // loop latency of a real robot (scan transfer, processing, the command's way to the motor controller), which lockstep
  // otherwise leaves at zero. The robot's watchdog and the command's expiry count from when it takes effect. Throws
  // std::invalid_argument unless latency_s is finite, non-negative and a whole number of physics steps.
  void set_command_latency(double latency_s);
  // The delay set by set_command_latency, seconds (0 by default).
  [[nodiscard]] double command_latency_s() const {
    return static_cast<double>(command_latency_steps_) * kPhysicsStep_s;
  }
  // Takes a motion command received now: it takes effect after the command latency (at once without one), and is then
  // recorded for the summary (or only counted when a drive script steers the robot).
  void apply_command(const v1::MotionCommand& command);
  // Commands received and not yet in effect (only with a command latency).
  [[nodiscard]] std::size_t pending_command_count() const { return pending_commands_.size(); }
  // Advances sim time by one physics step (following the drive script, if any), after the delayed commands due at the
  // current step have taken effect.
  void step();

  [[nodiscard]] const SimWorld& world() const { return *world_; }
  [[nodiscard]] const SimulatedRobot& robot() const { return robot_; }
  [[nodiscard]] SimulatedRobot& robot() { return robot_; }
  // Sensor messages (all kinds) sent so far.
  [[nodiscard]] std::uint64_t scan_count() const { return sensor_seq_; }
  // Messages taken so far per kind: "odometry", "laser_scan", "range_array", "servo_range",
  // "point_cloud", "wheel_encoders".
  [[nodiscard]] const std::map<std::string, std::uint64_t>& message_counts() const { return message_counts_; }
  // Motion commands that took effect so far (with a command latency, those still pending are not counted).
  [[nodiscard]] std::uint64_t command_count() const { return command_count_; }
  // Motion commands received and not applied because a drive script steers the robot.
  [[nodiscard]] std::uint64_t ignored_command_count() const { return ignored_command_count_; }
  // True once any applied command's behaviour state was "deadlock".
  [[nodiscard]] bool deadlock_reported() const { return state_counts_.contains("deadlock"); }
  // How many applied commands carried each behaviour state.
  [[nodiscard]] const std::map<std::string, std::uint64_t>& state_counts() const { return state_counts_; }
  // The behaviour state of the last applied command; empty before the first.
  [[nodiscard]] const std::string& last_state() const { return last_state_; }
  // The behaviour state in effect when each of the robot's collision_events() began.
  [[nodiscard]] const std::vector<std::string>& collision_states() const { return collision_states_; }
  // Every obstacle pixel a noise-free beam of any sensor so far entered (laser beams, the servo beam, and sonar
  // acoustic axes whose own echo the specular rule accepted, see RangeArraySimulator::fire); always empty for shape
  // worlds.
  [[nodiscard]] const std::set<Pixel>& visible_pixels() const { return visible_pixels_; }

 private:
  // One sensor and its schedule.
  struct ScheduledSensor {
    std::string name;
    std::int64_t period_steps = 0;
    std::variant<LaserSimulator, RangeArraySimulator, ServoRangeSimulator, DepthSensorSimulator> simulator;
  };

  std::unique_ptr<SimWorld> world_;
  KinematicsPreset kinematics_;
  std::string steering_sensor_;  // the first laser's name, else the first range array's; empty when neither
  bool has_encoders_;
  std::optional<geometry::EncoderParams> encoders_;  // for commands in encoder ticks
  std::uint64_t drive_goto_id_ = 0;                  // the last drive_goto started
  std::int64_t encoder_period_steps_ = 0;            // 0 when the robot has no encoders
  std::vector<ScheduledSensor> sensors_;
  SimulatedRobot robot_;
  DriveScript script_;
  std::vector<std::int64_t> script_segment_steps_;  // each segment's length in physics steps
  std::int64_t script_period_steps_ = 0;
  // A received command and the physics step at whose start it takes effect.
  struct PendingCommand {
    std::int64_t effect_step = 0;
    v1::MotionCommand command;
  };
  // Puts a command into effect now and records it.
  void take_effect(const v1::MotionCommand& command);

  std::int64_t command_latency_steps_ = 0;
  std::deque<PendingCommand> pending_commands_;  // in order of receipt, so in order of effect_step
  std::int64_t last_batch_step_ = -1;
  std::uint64_t sensor_seq_ = 0;
  std::uint64_t odometry_seq_ = 0;
  std::uint64_t encoder_seq_ = 0;
  std::map<std::string, std::uint64_t> message_counts_;
  std::uint64_t command_count_ = 0;
  std::uint64_t ignored_command_count_ = 0;
  std::map<std::string, std::uint64_t> state_counts_;
  std::string last_state_;
  std::vector<std::string> collision_states_;
  std::set<Pixel> visible_pixels_;
};

}  // namespace occgeo::sim
