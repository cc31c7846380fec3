#include "occgeo/sim/simulation.h"

#include <cmath>
#include <stdexcept>
#include <utility>

#include "occgeo/sim/messages.h"

namespace occgeo::sim {

namespace {

// The laser's scan period in physics steps; throws unless it is a positive whole number of them.
std::int64_t scan_period_steps(const LaserPreset& laser) {
  const double steps = laser.scan_period_s / kPhysicsStep_s;
  const std::int64_t whole_steps = std::llround(steps);
  if (!(whole_steps >= 1 && std::abs(steps - static_cast<double>(whole_steps)) < 1e-9)) {
    throw std::invalid_argument("laser '" + laser.name + "': scan period " + std::to_string(laser.scan_period_s) +
                                " s is not a whole number of " + std::to_string(kPhysicsStep_s) + " s physics steps");
  }
  return whole_steps;
}

}  // namespace

Simulation::Simulation(World world, const RobotPreset& preset, const geometry::Pose2& X_WB_start, std::uint64_t seed)
    : Simulation(std::make_unique<PixelWorld>(std::move(world)), preset, X_WB_start, seed) {}

Simulation::Simulation(std::unique_ptr<SimWorld> world, const RobotPreset& preset, const geometry::Pose2& X_WB_start,
                       std::uint64_t seed)
    : world_(world ? std::move(world) : throw std::invalid_argument("Simulation: the world must not be null")),
      sensor_name_(preset.laser.name),
      scan_period_steps_(scan_period_steps(preset.laser)),
      robot_(*world_, preset, X_WB_start),
      laser_(preset.laser, seed) {}

bool Simulation::scan_due() const {
  return robot_.step_count() % scan_period_steps_ == 0 && robot_.step_count() != last_scan_step_;
}

ScanMessages Simulation::take_scan() {
  last_scan_step_ = robot_.step_count();
  ++scan_count_;
  SimulatedScan scan = laser_.scan(*world_, robot_.pose(), robot_.time_s());
  visible_pixels_.insert(scan.hit_pixels.begin(), scan.hit_pixels.end());
  return ScanMessages{.seq = scan_count_,
                      .odometry = make_odometry_message(scan_count_, robot_.time_s(), robot_.pose(), robot_.velocity()),
                      .laser_scan = make_laser_scan_message(sensor_name_, scan_count_, robot_.time_s(), scan.ranges_m)};
}

void Simulation::apply_command(const v1::MotionCommand& command) {
  robot_.command(to_wheel_command(command));
  ++command_count_;
  ++state_counts_[command.state()];
  last_state_ = command.state();
}

}  // namespace occgeo::sim
