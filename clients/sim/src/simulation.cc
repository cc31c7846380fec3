#include "occgeo/sim/simulation.h"

#include <cmath>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "occgeo/proto/labels.h"
#include "occgeo/sim/messages.h"

namespace occgeo::sim {

namespace {

// period_s in physics steps; throws naming the sensor unless it is a positive whole number of them.
std::int64_t period_steps(const std::string& sensor, double period_s) {
  const double steps = period_s / kPhysicsStep_s;
  const std::int64_t whole_steps = std::llround(steps);
  if (!(whole_steps >= 1 && std::abs(steps - static_cast<double>(whole_steps)) < 1e-9)) {
    throw std::invalid_argument("sensor '" + sensor + "': period " + std::to_string(period_s) +
                                " s is not a whole number of " + std::to_string(kPhysicsStep_s) + " s physics steps");
  }
  return whole_steps;
}

// Each sensor's noise stream gets its own seed; the first sensor keeps the run's seed, so a one-laser robot's noise
// is what it was before robots had several sensors.
std::uint64_t sensor_seed(std::uint64_t seed, std::size_t index) {
  constexpr std::uint64_t kGoldenRatio64 = 0x9e3779b97f4a7c15ULL;
  return seed ^ (static_cast<std::uint64_t>(index) * kGoldenRatio64);
}

// The sensor whose messages the server answers with motion commands: the first laser, else the first range array
// (a sonar robot steers by its ring), else the first servo-swept beam (seed 003's ActivityBot, one command per
// reading); none otherwise.
std::string steering_sensor_of(const RobotPreset& preset) {
  if (preset.laser() != nullptr) return preset.laser()->name;
  for (const SensorPreset& sensor : preset.sensors) {
    if (const auto* array = std::get_if<RangeArrayPreset>(&sensor)) return array->name;
  }
  for (const SensorPreset& sensor : preset.sensors) {
    if (const auto* servo = std::get_if<ServoRangePreset>(&sensor)) return servo->name;
  }
  return {};
}

}  // namespace

const v1::LaserScan* SensorBatch::laser_scan(const std::string& sensor) const {
  for (const v1::ClientMessage& message : messages) {
    if (message.has_laser_scan() && (sensor.empty() || message.laser_scan().sensor() == sensor)) {
      return &message.laser_scan();
    }
  }
  return nullptr;
}

Simulation::Simulation(World world, const RobotPreset& preset, const geometry::Pose2& X_WB_start, std::uint64_t seed)
    : Simulation(std::make_unique<PixelWorld>(std::move(world)), preset, X_WB_start, seed) {}

Simulation::Simulation(std::unique_ptr<SimWorld> world, const RobotPreset& preset, const geometry::Pose2& X_WB_start,
                       std::uint64_t seed)
    : world_(world ? std::move(world) : throw std::invalid_argument("Simulation: the world must not be null")),
      kinematics_(preset.kinematics),
      steering_sensor_(steering_sensor_of(preset)),
      has_encoders_(preset.encoders.has_value()),
      encoders_(preset.encoders),
      robot_(*world_, preset, X_WB_start) {
  for (std::size_t i = 0; i < preset.sensors.size(); ++i) {
    const std::uint64_t noise_seed = sensor_seed(seed, i);
    std::visit(
        [&](const auto& sensor) {
          using Preset = std::decay_t<decltype(sensor)>;
          if constexpr (std::is_same_v<Preset, LaserPreset>) {
            sensors_.push_back(
                {sensor.name, period_steps(sensor.name, sensor.scan_period_s), LaserSimulator(sensor, noise_seed)});
          } else if constexpr (std::is_same_v<Preset, RangeArrayPreset>) {
            sensors_.push_back(
                {sensor.name, period_steps(sensor.name, sensor.period_s), RangeArraySimulator(sensor, noise_seed)});
          } else if constexpr (std::is_same_v<Preset, DepthSensorPreset>) {
            sensors_.push_back(
                {sensor.name, period_steps(sensor.name, sensor.period_s), DepthSensorSimulator(sensor, noise_seed)});
          } else {
            sensors_.push_back({sensor.name, period_steps(sensor.name, sensor.step_period_s),
                                ServoRangeSimulator(sensor, noise_seed)});
          }
        },
        preset.sensors[i]);
  }
  if (has_encoders_) {
    // The encoders are read with every servo step (the ActivityBot reads them between LIDAR readings), else at 50 Hz.
    encoder_period_steps_ = period_steps("wheel encoders", kEncoderPeriod_s);
    for (const SensorPreset& sensor : preset.sensors) {
      if (const auto* servo = std::get_if<ServoRangePreset>(&sensor)) {
        encoder_period_steps_ = period_steps(servo->name, servo->step_period_s);
        break;
      }
    }
  }
}

void Simulation::set_drive_script(DriveScript script) {
  if (script.empty()) throw std::invalid_argument("drive script: has no segments");
  std::vector<std::int64_t> segment_steps;
  std::int64_t period_steps = 0;
  for (std::size_t i = 0; i < script.size(); ++i) {
    const DriveSegment& segment = script[i];
    if (!std::isfinite(segment.linear_mps) || !std::isfinite(segment.angular_radps) ||
        !std::isfinite(segment.duration_s) || segment.duration_s <= 0.0) {
      throw std::invalid_argument("drive script: segment " + std::to_string(i + 1) +
                                  " needs finite speeds and a positive duration");
    }
    // Whole physics steps, so segment boundaries do not drift with floating-point time.
    const std::int64_t steps = std::llround(segment.duration_s / kPhysicsStep_s);
    if (steps < 1) {
      throw std::invalid_argument("drive script: segment " + std::to_string(i + 1) + " is shorter than one " +
                                  std::to_string(kPhysicsStep_s) + " s physics step");
    }
    segment_steps.push_back(steps);
    period_steps += steps;
  }
  script_ = std::move(script);
  script_segment_steps_ = std::move(segment_steps);
  script_period_steps_ = period_steps;
}

bool Simulation::batch_due() const {
  const std::int64_t step = robot_.step_count();
  if (step == last_batch_step_) return false;
  if (encoder_period_steps_ > 0 && step % encoder_period_steps_ == 0) return true;
  for (const ScheduledSensor& sensor : sensors_) {
    if (step % sensor.period_steps == 0) return true;
  }
  return false;
}

SensorBatch Simulation::take_batch() {
  const std::int64_t step = robot_.step_count();
  const double stamp_s = robot_.time_s();
  last_batch_step_ = step;
  SensorBatch batch;
  if (has_encoders_) {
    if (step % encoder_period_steps_ == 0) {
      batch.messages.push_back(make_wheel_encoders_message(++encoder_seq_, stamp_s, robot_.encoder_ticks()));
      ++message_counts_["wheel_encoders"];
    }
  } else {
    batch.messages.push_back(make_odometry_message(++odometry_seq_, stamp_s, robot_.pose(), robot_.velocity()));
    ++message_counts_["odometry"];
  }
  for (ScheduledSensor& sensor : sensors_) {
    if (step % sensor.period_steps != 0) continue;
    const std::uint64_t seq = ++sensor_seq_;
    batch.last_sensor_seq = seq;
    if (auto* laser = std::get_if<LaserSimulator>(&sensor.simulator)) {
      const SimulatedScan scan = laser->scan(*world_, robot_.pose(), stamp_s);
      visible_pixels_.insert(scan.hit_pixels.begin(), scan.hit_pixels.end());
      batch.messages.push_back(make_laser_scan_message(sensor.name, seq, stamp_s, scan.ranges_m));
      ++message_counts_["laser_scan"];
      if (sensor.name == steering_sensor_) batch.steering_scan_seq = seq;
    } else if (auto* array = std::get_if<RangeArraySimulator>(&sensor.simulator)) {
      const SimulatedScan scan = array->fire(*world_, robot_.pose(), stamp_s);
      visible_pixels_.insert(scan.hit_pixels.begin(), scan.hit_pixels.end());
      batch.messages.push_back(make_range_array_message(sensor.name, seq, stamp_s, scan.ranges_m));
      if (sensor.name == steering_sensor_) batch.steering_scan_seq = seq;
      ++message_counts_["range_array"];
    } else if (auto* depth = std::get_if<DepthSensorSimulator>(&sensor.simulator)) {
      batch.messages.push_back(
          make_point_cloud_message(sensor.name, seq, stamp_s, depth->capture(*world_, robot_.pose(), stamp_s)));
      ++message_counts_["point_cloud"];
    } else {
      auto& servo = std::get<ServoRangeSimulator>(sensor.simulator);
      const ServoReading reading = servo.measure(*world_, robot_.pose(), stamp_s);
      visible_pixels_.insert(reading.hit_pixels.begin(), reading.hit_pixels.end());
      batch.messages.push_back(
          make_servo_range_message(sensor.name, seq, stamp_s, reading.servo_angle_rad, reading.range_m));
      if (sensor.name == steering_sensor_) batch.steering_scan_seq = seq;
      ++message_counts_["servo_range"];
    }
  }
  return batch;
}

void Simulation::set_command_latency(double latency_s) {
  const double steps = latency_s / kPhysicsStep_s;
  const std::int64_t whole_steps = std::isfinite(steps) ? std::llround(steps) : -1;
  if (!(whole_steps >= 0 && std::abs(steps - static_cast<double>(whole_steps)) < 1e-9)) {
    throw std::invalid_argument("command latency " + std::to_string(latency_s) +
                                " s must be a non-negative whole number of " + std::to_string(kPhysicsStep_s) +
                                " s physics steps");
  }
  command_latency_steps_ = whole_steps;
}

void Simulation::apply_command(const v1::MotionCommand& command) {
  if (has_drive_script()) {
    ++ignored_command_count_;
    return;
  }
  if (command_latency_steps_ > 0) {
    pending_commands_.push_back({robot_.step_count() + command_latency_steps_, command});
    return;
  }
  take_effect(command);
}

void Simulation::take_effect(const v1::MotionCommand& command) {
  // The ActivityBot's own units (seed 003 §3.3.3, §3.4): drive_goto turns each wheel by its ticks, started once per
  // manoeuvre id and not interrupted by its repeats; drive_speed runs the wheels at ticks per second.
  if (encoders_ && !command.stop() && command.has_drive_goto()) {
    const v1::DriveGoto& drive_goto = command.drive_goto();
    if (drive_goto.id() != drive_goto_id_) {
      drive_goto_id_ = drive_goto.id();
      robot_.drive_goto(drive_goto.left_ticks(), drive_goto.right_ticks(),
                        drive_goto.max_ticks_per_s() * geometry::metres_per_tick(*encoders_));
    }
  } else if (encoders_ && !command.stop() && command.has_drive_speed()) {
    const double metres_per_tick = geometry::metres_per_tick(*encoders_);
    robot_.command(WheelCommand{.left_mps = command.drive_speed().left_ticks_per_s() * metres_per_tick,
                                .right_mps = command.drive_speed().right_ticks_per_s() * metres_per_tick,
                                .expires_after_s = command.expires_after_s()});
  } else {
    robot_.command(to_wheel_command(command));
  }
  ++command_count_;
  last_state_ = proto::behaviour_state_label(command.state());
  ++state_counts_[last_state_];
}

void Simulation::step() {
  while (!pending_commands_.empty() && pending_commands_.front().effect_step <= robot_.step_count()) {
    take_effect(pending_commands_.front().command);
    pending_commands_.pop_front();
  }
  if (has_drive_script()) {
    std::int64_t phase_steps = robot_.step_count() % script_period_steps_;
    const DriveSegment* current = &script_.back();
    for (std::size_t i = 0; i < script_.size(); ++i) {
      if (phase_steps < script_segment_steps_[i]) {
        current = &script_[i];
        break;
      }
      phase_steps -= script_segment_steps_[i];
    }
    const geometry::BodyVelocity body{current->linear_mps, current->angular_radps};
    const geometry::WheelSpeeds wheels =
        std::holds_alternative<SkidSteerPreset>(kinematics_)
            ? geometry::to_wheels(body, std::get<SkidSteerPreset>(kinematics_).params)
            : geometry::to_wheels(body, std::get<geometry::DifferentialDriveParams>(kinematics_));
    robot_.command(WheelCommand{.left_mps = wheels.left_mps, .right_mps = wheels.right_mps});
  }
  robot_.step();
  while (collision_states_.size() < robot_.collision_events().size()) collision_states_.push_back(last_state_);
}

}  // namespace occgeo::sim
