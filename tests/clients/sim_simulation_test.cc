#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <optional>
#include <sstream>

#include "occgeo/proto/labels.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/report.h"
#include "occgeo/sim/simulation.h"

namespace occgeo::sim {
namespace {

// 0.1 m pixels from (-5, -5), 10 m x 10 m; a wall at x 3.0..3.1.
World wall_ahead() {
  std::vector<std::string> rows(100, std::string(100, '.'));
  for (std::string& row : rows) row[80] = '#';
  return World::from_rows(std::vector<std::string_view>(rows.begin(), rows.end()), 0.1, {-5.0, -5.0});
}

const RobotPreset& bearcat() { return *find_robot_preset("bearcat"); }

v1::MotionCommand command_for(std::uint64_t scan_seq, double left_mps, double right_mps, const std::string& state) {
  v1::MotionCommand command;
  command.set_answers_scan_seq(scan_seq);
  command.set_left_wheel_mps(left_mps);
  command.set_right_wheel_mps(right_mps);
  command.set_state(proto::behaviour_state_from_label(state).value_or(v1::BEHAVIOUR_STATE_UNSPECIFIED));
  return command;
}

// Runs a lockstep session against a stand-in server that answers every scan with a gentle left turn.
RunSummary run_lockstep(std::uint64_t seed, int steps, std::optional<double> command_latency_s = std::nullopt) {
  Simulation simulation(wall_ahead(), bearcat(), {}, seed);
  if (command_latency_s) simulation.set_command_latency(*command_latency_s);
  for (int i = 0; i < steps; ++i) {
    if (simulation.batch_due()) {
      const SensorBatch batch = simulation.take_batch();
      const v1::LaserScan& laser = *batch.laser_scan();
      const double nearest = *std::min_element(laser.ranges().begin(), laser.ranges().end());
      simulation.apply_command(command_for(batch.last_sensor_seq, 0.5 + nearest * 0.01, 0.6, "wander"));
    }
    simulation.step();
  }
  return summarize(simulation, "bearcat-1", "wall.yaml");
}

TEST(Simulation, ScansEveryPeriodWithOdometryFirstAndIncreasingSeqs) {
  Simulation simulation(wall_ahead(), bearcat(), {1.0, 0.5, 0.1}, 1);
  int scans = 0;
  for (int step = 0; step < 100; ++step) {
    if (simulation.batch_due()) {
      const SensorBatch batch = simulation.take_batch();
      const v1::ClientMessage& odometry = batch.messages.front();
      const v1::LaserScan& laser = *batch.laser_scan();
      ++scans;
      EXPECT_EQ(step % 10, 0) << "every 0.1 s";
      EXPECT_FALSE(simulation.batch_due()) << "one scan per scan time";
      EXPECT_EQ(batch.last_sensor_seq, static_cast<std::uint64_t>(scans));
      ASSERT_TRUE(odometry.has_odometry());
      EXPECT_EQ(odometry.odometry().seq(), batch.last_sensor_seq);
      EXPECT_NEAR(odometry.odometry().stamp_s(), step * 0.01, 1e-12);
      EXPECT_EQ(odometry.odometry().pose().x(), 1.0);
      EXPECT_EQ(odometry.odometry().pose().theta(), 0.1);
      ASSERT_NE(batch.laser_scan(), nullptr);
      EXPECT_EQ(laser.sensor(), "front_laser");
      EXPECT_EQ(laser.seq(), batch.last_sensor_seq);
      EXPECT_EQ(laser.stamp_s(), odometry.odometry().stamp_s());
      EXPECT_EQ(laser.ranges_size(), 181);
    }
    simulation.step();
  }
  EXPECT_EQ(scans, 10);
  EXPECT_EQ(simulation.scan_count(), 10U);
  EXPECT_FALSE(simulation.visible_pixels().empty());
}

TEST(Simulation, RecordsCommandsForTheSummary) {
  Simulation simulation(wall_ahead(), bearcat(), {}, 1);
  simulation.apply_command(command_for(1, 0.5, 0.5, "straight"));
  simulation.apply_command(command_for(2, 0.0, 0.0, "deadlock"));
  simulation.apply_command(command_for(3, 0.2, -0.2, "steer_gap"));
  EXPECT_EQ(simulation.command_count(), 3U);
  EXPECT_TRUE(simulation.deadlock_reported());
  EXPECT_EQ(simulation.last_state(), "steer_gap");
}

TEST(Simulation, LockstepRunsAreDeterministicForASeed) {
  const RunSummary first = run_lockstep(5, 500);
  const RunSummary again = run_lockstep(5, 500);
  const RunSummary other_seed = run_lockstep(6, 500);
  EXPECT_EQ(to_json(first), to_json(again));
  EXPECT_NE(first.final_pose.x, other_seed.final_pose.x) << "the noise reaches the wheels through the stand-in server";
  EXPECT_EQ(first.scans_sent, 50U);
  EXPECT_EQ(first.commands_received, 50U);
  EXPECT_NEAR(first.sim_time_s, 5.0, 1e-12);
  EXPECT_GT(first.distance_m, 2.0);
}

// Steps the simulation until its clock reads time_s.
void step_until(Simulation& simulation, double time_s) {
  while (simulation.robot().time_s() < time_s - 1e-9) simulation.step();
}

TEST(CommandLatency, ACommandReceivedAtTTakesEffectAtTPlusTheLatency) {
  Simulation simulation(wall_ahead(), bearcat(), {}, 1);
  simulation.set_command_latency(0.3);
  EXPECT_DOUBLE_EQ(simulation.command_latency_s(), 0.3);
  step_until(simulation, 0.5);
  // Received at t = 0.5 s, lockstep: the wheels still stand at t = 0.8 s and drive from then on.
  simulation.apply_command(command_for(6, 0.5, 0.5, "clear"));
  EXPECT_EQ(simulation.pending_command_count(), 1U);
  EXPECT_EQ(simulation.command_count(), 0U) << "counted once it takes effect";
  step_until(simulation, 0.8);
  EXPECT_EQ(simulation.robot().pose().x, 0.0) << "not before t + latency";
  EXPECT_EQ(simulation.last_state(), "");
  simulation.step();
  EXPECT_NEAR(simulation.robot().pose().x, 0.5 * kPhysicsStep_s, 1e-12) << "the step starting at t + latency drives";
  EXPECT_EQ(simulation.pending_command_count(), 0U);
  EXPECT_EQ(simulation.command_count(), 1U);
  EXPECT_EQ(simulation.last_state(), "clear");
}

TEST(CommandLatency, TheWatchdogCountsFromWhenTheCommandTakesEffect) {
  Simulation simulation(wall_ahead(), bearcat(), {}, 1);
  simulation.set_command_latency(0.3);
  simulation.apply_command(command_for(1, 0.5, 0.5, "clear"));
  step_until(simulation, 2.0);
  // The preset's 0.5 s watchdog from t = 0.3 s: 0.5 s at 0.5 m/s. Counted from receipt it would be 0.2 s of driving.
  EXPECT_NEAR(simulation.robot().pose().x, 0.25, 1e-9);
}

TEST(CommandLatency, CommandsKeepTheirOrderAndSpacing) {
  Simulation simulation(wall_ahead(), bearcat(), {}, 1);
  simulation.set_command_latency(0.2);
  simulation.apply_command(command_for(1, 0.5, 0.5, "clear"));
  step_until(simulation, 0.1);
  simulation.apply_command(command_for(2, 0.0, 0.0, "deadlock"));
  step_until(simulation, 0.3);
  EXPECT_EQ(simulation.last_state(), "clear");
  EXPECT_NEAR(simulation.robot().pose().x, 0.05, 1e-9) << "driving since t = 0.2 s";
  simulation.step();
  EXPECT_EQ(simulation.last_state(), "deadlock") << "the second command, 0.1 s after the first";
  step_until(simulation, 1.0);
  EXPECT_NEAR(simulation.robot().pose().x, 0.05, 1e-9) << "stopped by it at t = 0.3 s";
}

TEST(CommandLatency, ZeroLatencyLeavesLockstepRunsUnchanged) {
  const RunSummary plain = run_lockstep(5, 500);
  EXPECT_EQ(to_json(run_lockstep(5, 500, 0.0)), to_json(plain));
  const RunSummary delayed = run_lockstep(5, 500, 0.3);
  EXPECT_NE(delayed.final_pose.x, plain.final_pose.x);
  EXPECT_EQ(delayed.commands_received, 50U - 3U) << "the last three commands were still on their way at the end";
}

TEST(CommandLatency, RefusesALatencyThatIsNotWholeSteps) {
  Simulation simulation(wall_ahead(), bearcat(), {}, 1);
  EXPECT_THROW(simulation.set_command_latency(-0.01), std::invalid_argument);
  EXPECT_THROW(simulation.set_command_latency(0.015), std::invalid_argument);
  EXPECT_THROW(simulation.set_command_latency(std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
  EXPECT_DOUBLE_EQ(simulation.command_latency_s(), 0.0) << "a refused latency changes nothing";
}

TEST(Simulation, RefusesABadStartOrScanPeriod) {
  EXPECT_THROW(Simulation(wall_ahead(), bearcat(), {3.0, 0.0, 0.0}, 1), std::invalid_argument);
  RobotPreset odd_period = bearcat();
  odd_period.laser()->scan_period_s = 0.015;
  EXPECT_THROW(Simulation(wall_ahead(), odd_period, {}, 1), std::invalid_argument);
}

TEST(Messages, RobotSpecDescribesTheBearcat) {
  const v1::RobotSpec spec = make_robot_spec(bearcat());
  EXPECT_EQ(spec.model(), "bearcat");
  EXPECT_EQ(spec.kinematics().differential().wheel_separation_m(), 0.7);
  EXPECT_EQ(spec.kinematics().differential().wheel_radius_m(), 0.2);
  EXPECT_EQ(spec.kinematics().differential().max_wheel_speed_mps(), 1.2);
  EXPECT_EQ(spec.footprint().box().length_m(), 1.0);
  EXPECT_EQ(spec.footprint().box().width_m(), 0.8);
  EXPECT_EQ(spec.footprint().box().height_m(), 1.2);
  EXPECT_EQ(spec.footprint().box().center_x_m(), 0.0);
  ASSERT_EQ(spec.sensors_size(), 1);
  const v1::SensorSpec& sensor = spec.sensors(0);
  EXPECT_EQ(sensor.name(), "front_laser");
  EXPECT_EQ(sensor.mount().position().x(), 0.45);
  EXPECT_EQ(sensor.mount().position().z(), 0.6);
  EXPECT_EQ(sensor.mount().yaw(), 0.0);
  EXPECT_EQ(sensor.laser().beam_count(), 181U);
  EXPECT_DOUBLE_EQ(sensor.laser().angle_min_rad(), -M_PI / 2.0);
  EXPECT_DOUBLE_EQ(sensor.laser().angle_increment_rad(), M_PI / 180.0);
  EXPECT_EQ(sensor.laser().range_min_m(), 0.0);
  EXPECT_EQ(sensor.laser().range_max_m(), 8.0);
  EXPECT_EQ(sensor.laser().scan_period_s(), 0.1);
  EXPECT_EQ(spec.command_timeout_s(), 0.5);
}

TEST(Messages, HelloIntroducesADriver) {
  const v1::Hello hello = make_driver_hello("bearcat-1", "default");
  EXPECT_EQ(hello.protocol_version(), proto::kProtocolVersion);
  EXPECT_EQ(hello.role(), v1::ROLE_DRIVER);
  EXPECT_EQ(hello.robot_id(), "bearcat-1");
  EXPECT_EQ(hello.world(), "default");
  EXPECT_EQ(hello.client_name(), "occgeo-sim");
}

TEST(Report, JsonHasEveryField) {
  const RunSummary summary{.robot_id = "bc \"1\"",
                           .world_file = "worlds/open_field.yaml",
                           .distance_m = 12.5,
                           .collisions = 3,
                           .collisions_moving = 1,
                           .collisions_at_rest = 1,
                           .collisions_hit_moving = 1,
                           .sim_time_s = 60.0,
                           .scans_sent = 600,
                           .commands_received = 598,
                           .final_pose = {1.25, -2.0, 0.5},
                           .deadlock_reported = true,
                           .last_state = "deadlock",
                           .state_counts = {{"clear", 590}, {"deadlock", 8}},
                           .messages_sent = {{"laser_scan", 600}, {"odometry", 600}},
                           .commands_ignored = 3,
                           .collision_events = {{{.time_s = 4.5,
                                                  .X_WB = {1.0, 0.5, 0.25},
                                                  .wheels = {-0.1, -0.1},
                                                  .moving = true,
                                                  .ran_into_robot = true,
                                                  .obstacle = "moving[0]"},
                                                 "yield_aside"}}};
  EXPECT_EQ(to_json(summary),
            "{\"robot\": \"bc \\\"1\\\"\", \"world\": \"worlds/open_field.yaml\", \"distance_m\": 12.5, "
            "\"collisions\": 3, \"collisions_moving\": 1, \"collisions_at_rest\": 1, \"collisions_hit_moving\": 1, "
            "\"sim_time_s\": 60, "
            "\"scans_sent\": 600, \"commands_received\": 598, "
            "\"final_pose\": {\"x\": 1.25, \"y\": -2, \"theta\": 0.5}, \"deadlock_reported\": true, "
            "\"last_state\": \"deadlock\", \"state_counts\": {\"clear\": 590, \"deadlock\": 8}, "
            "\"messages_sent\": {\"laser_scan\": 600, \"odometry\": 600}, \"commands_ignored\": 3, "
            "\"collision_events\": [{\"t_s\": 4.5, \"x\": 1, \"y\": 0.5, \"theta\": 0.25, \"left_mps\": -0.1, "
            "\"right_mps\": -0.1, \"moving\": true, \"ran_into_robot\": true, \"obstacle\": \"moving[0]\", "
            "\"state\": \"yield_aside\"}]}");
  const std::string text = to_text(summary);
  EXPECT_NE(text.find("collisions  3 (1 moving, 1 hit at rest, 1 hit while moving)"), std::string::npos) << text;
  EXPECT_NE(text.find("hit while moving by moving[0] (state yield_aside)"), std::string::npos) << text;
}

TEST(Report, WritesVisiblePixelsAndTraceRows) {
  std::ostringstream out;
  write_visible_pixels(out, {{3, 4}, {1, 2}});
  EXPECT_EQ(out.str(), "1 2\n3 4\n");
  EXPECT_EQ(trace_csv_row(0.5, {1.0, -2.25, 0.125}), "0.5,1,-2.25,0.125");
}

}  // namespace
}  // namespace occgeo::sim
