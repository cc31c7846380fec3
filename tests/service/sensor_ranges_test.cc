// Per-sensor ranges (SensorSpec.ranges over the config's `sensors:`): how far a long-range laser's readings change
// the grid and the octree, through the real laser-scan handler and a real ServerCore (no sockets).
#include <gtest/gtest.h>

#include <optional>

#include "fake_session.h"
#include "sensor_robot_spec.h"
#include "test_robots.h"
#include "validation.h"

namespace occgeo::service {
namespace {

constexpr double kLaserHeight_m = 0.3;  // the laser probe's mount
constexpr double kY_m = 0.05;           // the robot's y: every beam runs along y = kY_m

ServerConfig long_range_config() {
  ServerConfig config;
  config.octomap.max_range_m = 100.0;  // the octree's own cap out of the way: only the sensor's ranges cut
  config.sensors.max_insert_range_m = 30.0;
  config.sensors.max_free_range_m = 30.0;
  config.sensors.no_return_clear_m = 5.0;
  return config;
}

// A one-beam laser looking along +x from 0.3 m up, reading to 80 m, with optional ranges of its own.
v1::RobotSpec long_range_laser(std::optional<v1::SensorRanges> ranges = std::nullopt) {
  testing::LaserProbe probe;
  probe.beam_count = 1;
  probe.angle_min_rad = 0.0;
  probe.range_max_m = 80.0;
  v1::RobotSpec spec = testing::laser_probe_spec(probe);
  if (ranges) *spec.mutable_sensors(0)->mutable_ranges() = *ranges;
  return spec;
}

class SensorRanges : public ::testing::Test {
 protected:
  SensorRanges() : core_(long_range_config()) {}

  // A driver of `spec` at (0.05, kY_m) facing +x, its laser having read `reading` (metres) on its one beam.
  void scan_once(const v1::RobotSpec& spec, float reading) {
    auto session = testing::driver_session(core_, "r1", spec);
    ASSERT_NE(core_.find_robot("r1"), nullptr) << "the spec was refused";
    handle_odometry(session, testing::odometry(0.05, kY_m, 0.0, 0.0));
    v1::LaserScan scan;
    scan.set_sensor("laser");
    scan.set_seq(1);
    scan.set_stamp_s(0.1);
    scan.add_ranges(reading);
    handle_laser_scan(session, scan);
    const auto ack = session->next_of(v1::ServerMessage::kScanAck);
    ASSERT_TRUE(ack) << "the scan was not acknowledged";
  }

  [[nodiscard]] geometry::CellIndex cell(double x) const {
    return geometry::GridGeometry(core_.config().himm.cell_size_m).cell_of({x, kY_m});
  }
  [[nodiscard]] bool grid_occupied(double x) { return core_.world("default")->snapshot()->occupied(cell(x)); }
  [[nodiscard]] bool grid_observed(double x) { return core_.world("default")->snapshot()->observed(cell(x)); }
  // The octree's occupancy probability on the beam, x metres out; nullopt where it was never observed.
  [[nodiscard]] std::optional<double> octree(double x) {
    std::optional<double> occupancy;
    core_.world("default")->with_octree_on_strand([&](mapping::OctoMapModel& octomap) {
      occupancy = octomap.occupancy({x, kY_m, kLaserHeight_m});
    });
    return occupancy;
  }

  ServerCore core_;
};

TEST_F(SensorRanges, ReturnBeyondTheInsertRangeIsNotMarkedAndCarvesOnlyUpToIt) {
  scan_once(long_range_laser(), 60.0F);
  // The laser sits 0.05 m ahead of x = 0: the return lies at x = 60.05.
  EXPECT_FALSE(grid_occupied(60.05)) << "a return beyond max_insert_range_m must not be marked";
  EXPECT_FALSE(grid_observed(60.05));
  EXPECT_FALSE(octree(60.05).has_value()) << "the octree must not hold the far return either";
  // Free space up to the insert range, nothing beyond it.
  for (const double x : {1.0, 15.0, 29.5}) {
    EXPECT_TRUE(grid_observed(x)) << "grid carved at x = " << x;
    EXPECT_FALSE(grid_occupied(x));
    ASSERT_TRUE(octree(x).has_value()) << "octree carved at x = " << x;
    EXPECT_LT(*octree(x), 0.5);
  }
  for (const double x : {30.5, 45.0, 59.5}) {
    EXPECT_FALSE(grid_observed(x)) << "grid carved beyond the insert range at x = " << x;
    EXPECT_FALSE(octree(x).has_value()) << "octree carved beyond the insert range at x = " << x;
  }
}

TEST_F(SensorRanges, ReturnWithinTheInsertRangeIsMarked) {
  scan_once(long_range_laser(), 20.0F);
  EXPECT_TRUE(grid_occupied(20.05));
  ASSERT_TRUE(octree(20.05).has_value());
  EXPECT_GT(*octree(20.05), 0.5);
  EXPECT_TRUE(grid_observed(19.5));
}

TEST_F(SensorRanges, TheRobotSpecsRangesOverrideTheServersDefaults) {
  v1::SensorRanges ranges;
  ranges.set_max_insert_range_m(70.0);  // marks the 60 m return
  ranges.set_max_free_range_m(10.0);    // but carves only the first 10 m of its beam
  scan_once(long_range_laser(ranges), 60.0F);
  EXPECT_TRUE(grid_occupied(60.05));
  ASSERT_TRUE(octree(60.05).has_value());
  EXPECT_GT(*octree(60.05), 0.5);
  EXPECT_TRUE(grid_observed(9.5));
  ASSERT_TRUE(octree(9.5).has_value());
  for (const double x : {10.5, 30.0, 59.5}) {
    EXPECT_FALSE(grid_observed(x)) << "carved beyond max_free_range_m at x = " << x;
    EXPECT_FALSE(octree(x).has_value()) << "carved beyond max_free_range_m at x = " << x;
  }
}

TEST_F(SensorRanges, NoReturnBeamClearsOnlyUpToNoReturnClear) {
  scan_once(long_range_laser(), 80.0F);  // at range_max: no return
  for (const double x : {1.0, 4.5}) {
    EXPECT_TRUE(grid_observed(x)) << "grid cleared at x = " << x;
    ASSERT_TRUE(octree(x).has_value()) << "octree cleared at x = " << x;
    EXPECT_LT(*octree(x), 0.5);
  }
  for (const double x : {5.6, 20.0, 79.0}) {
    EXPECT_FALSE(grid_observed(x)) << "grid cleared beyond no_return_clear_m at x = " << x;
    EXPECT_FALSE(octree(x).has_value()) << "octree cleared beyond no_return_clear_m at x = " << x;
  }
  EXPECT_EQ(core_.world("default")->snapshot()->occupied_cell_count(), 0U);
}

TEST_F(SensorRanges, NoReturnClearOfZeroLeavesTheMapsAlone) {
  v1::SensorRanges ranges;
  ranges.set_no_return_clear_m(0.0);
  scan_once(long_range_laser(ranges), 80.0F);
  EXPECT_FALSE(grid_observed(1.0));
  EXPECT_FALSE(octree(1.0).has_value());
}

// A point cloud has no "no return": a point beyond its sensor's insert range only carves up to that range.
TEST_F(SensorRanges, CloudPointBeyondTheInsertRangeIsNotMarked) {
  using R = testing::SensorRobot;
  v1::RobotSpec spec = testing::sensor_robot_spec();
  for (auto& sensor : *spec.mutable_sensors()) {
    if (sensor.name() == "depth") sensor.mutable_ranges()->set_max_insert_range_m(2.0);
  }
  auto session = testing::driver_session(core_, "r1", spec);
  ASSERT_NE(core_.find_robot("r1"), nullptr) << "the spec was refused";
  handle_odometry(session, testing::odometry(0.05, kY_m, 0.0, 0.0));
  v1::PointCloud cloud;
  cloud.set_sensor("depth");
  cloud.set_seq(1);
  cloud.set_stamp_s(0.1);
  // Sensor frame: one point 1 m ahead and 1 m left, one 3 m straight ahead (on separate lines of sight).
  for (const float v : {1.0F, 1.0F, 0.0F, 3.0F, 0.0F, 0.0F}) cloud.add_xyz(v);
  handle_point_cloud(session, cloud);
  ASSERT_TRUE(session->next_of(v1::ServerMessage::kScanAck)) << "the cloud was not acknowledged";
  const double sensor_x = 0.05 + R::kDepthMountX_m;
  const auto grid = core_.world("default")->snapshot();
  const geometry::GridGeometry cells(core_.config().himm.cell_size_m);
  EXPECT_TRUE(grid->occupied(cells.cell_of({sensor_x + 1.0, kY_m + 1.0}))) << "the point within 2 m is marked";
  EXPECT_FALSE(grid->occupied(cells.cell_of({sensor_x + 3.0, kY_m}))) << "the point at 3 m must not be marked";
  EXPECT_FALSE(grid->observed(cells.cell_of({sensor_x + 3.0, kY_m})));
  EXPECT_TRUE(grid->observed(cells.cell_of({sensor_x + 1.5, kY_m}))) << "its ray carves up to 2 m";
  EXPECT_FALSE(grid->observed(cells.cell_of({sensor_x + 2.5, kY_m}))) << "and no farther";
}

TEST_F(SensorRanges, NegativeOrNonFiniteRangesAreRefusedNamingTheField) {
  v1::SensorRanges ranges;
  ranges.set_max_free_range_m(-1.0);
  FieldError error;
  EXPECT_EQ(robot_model_from_spec("r1", long_range_laser(ranges), LimitsConfig{}, error), nullptr);
  EXPECT_EQ(error.field, "robot_spec.sensors[0].ranges.max_free_range_m");
  ranges.Clear();
  ranges.set_max_insert_range_m(0.0);
  EXPECT_EQ(robot_model_from_spec("r1", long_range_laser(ranges), LimitsConfig{}, error), nullptr);
  EXPECT_EQ(error.field, "robot_spec.sensors[0].ranges.max_insert_range_m");
}

}  // namespace
}  // namespace occgeo::service
