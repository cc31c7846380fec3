#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>

#include "occgeo/geometry/pose.h"
#include "occgeo/sim/laser.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/robot.h"
#include "occgeo/sim/sim_world.h"
#include "occgeo/sim/world.h"
#include "occgeo/v1/session.pb.h"

namespace occgeo::sim {

// The odometry and laser scan for one scan time, to be sent in this order.
struct ScanMessages {
  std::uint64_t seq = 0;  // the scan's seq, shared by the odometry; motion commands answer it
  v1::ClientMessage odometry;
  v1::ClientMessage laser_scan;
};

// One simulated run without the network: the world, the robot, its laser on a fixed scan schedule, and the counts
// the summary reports. Deterministic for a seed. Not copyable or movable (the robot refers to the world it holds).
class Simulation {
 public:
  // Throws std::invalid_argument when the robot collides at the start pose X_WB_start or the laser's scan period is not
  // a positive whole number of physics steps.
  Simulation(World world, const RobotPreset& preset, const geometry::Pose2& X_WB_start, std::uint64_t seed);
  // The same for any world (pixel or shape world); throws std::invalid_argument when world is null.
  Simulation(std::unique_ptr<SimWorld> world, const RobotPreset& preset, const geometry::Pose2& X_WB_start,
             std::uint64_t seed);
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;

  // True when the current sim time is a scan time (every scan period from t = 0) whose scan was not taken yet.
  [[nodiscard]] bool scan_due() const;
  // Takes the scan due now: the true pose and velocity as odometry, then the laser sweep; seqs count from 1.
  ScanMessages take_scan();
  // Applies a motion command received now and records it for the summary.
  void apply_command(const v1::MotionCommand& command);
  // Advances sim time by one physics step.
  void step() { robot_.step(); }

  [[nodiscard]] const SimWorld& world() const { return *world_; }
  [[nodiscard]] const SimulatedRobot& robot() const { return robot_; }
  // Scans taken so far.
  [[nodiscard]] std::uint64_t scan_count() const { return scan_count_; }
  // Motion commands applied so far.
  [[nodiscard]] std::uint64_t command_count() const { return command_count_; }
  // True once any applied command's behaviour state was "deadlock".
  [[nodiscard]] bool deadlock_reported() const { return state_counts_.contains("deadlock"); }
  // How many applied commands carried each behaviour state.
  [[nodiscard]] const std::map<std::string, std::uint64_t>& state_counts() const { return state_counts_; }
  // The behaviour state of the last applied command; empty before the first.
  [[nodiscard]] const std::string& last_state() const { return last_state_; }
  // Every obstacle pixel a noise-free beam of any scan so far entered; always empty for shape worlds.
  [[nodiscard]] const std::set<Pixel>& visible_pixels() const { return visible_pixels_; }

 private:
  std::unique_ptr<SimWorld> world_;
  std::string sensor_name_;
  std::int64_t scan_period_steps_;
  SimulatedRobot robot_;
  LaserSimulator laser_;
  std::int64_t last_scan_step_ = -1;
  std::uint64_t scan_count_ = 0;
  std::uint64_t command_count_ = 0;
  std::map<std::string, std::uint64_t> state_counts_;
  std::string last_state_;
  std::set<Pixel> visible_pixels_;
};

}  // namespace occgeo::sim
