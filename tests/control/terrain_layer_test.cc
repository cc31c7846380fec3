// The terrain rule where the planner, the goto look-ahead and the guard read obstacles: the ramp of seed 000 Fig 5.1
// (clients/sim/worlds/ramp.yaml) as a depth camera puts it into a real OctoMap, and the wall a laser plane at 0.6 m
// makes of it in a real HIMM grid. The path goes up the ramp and the guard lets the robot climb it, while a box
// standing on the ramp still blocks both, and with the rule off the ramp is a wall again.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "height_band_layer.h"
#include "model_geometry.h"
#include "occgeo/mapping/himm_grid.h"
#include "occgeo/service/control/safety_guard.h"

namespace occgeo::service::control {
namespace {

constexpr double kBearcatHeight_m = 1.2;
const geometry::Footprint kBearcat =
    geometry::BoxFootprint{.length = 1.0, .width = 0.8, .height = kBearcatHeight_m, .center_x = 0.0};

double ramp_height(double x) { return x < 3.0 ? 0.0 : x < 7.0 ? 0.2 * (x - 3.0) : 0.8; }

// The lane's floor, ramp and platform (x in [0, 11], y in [-1.4, 1.4]) sampled every 2 cm, the lane's walls, and
// optionally a box 0.4 m tall standing on the ramp across the lane's middle at x in [5, 5.4].
std::vector<Eigen::Vector3f> ramp_world(bool box_on_ramp) {
  std::vector<Eigen::Vector3f> points;
  for (double x = 0.0; x <= 11.0; x += 0.02) {
    for (double y = -1.4; y <= 1.4; y += 0.02) {
      const bool on_box = box_on_ramp && x >= 5.0 && x <= 5.4 && std::abs(y) <= 0.6;
      points.emplace_back(Eigen::Vector3d(x, y, ramp_height(x) + (on_box ? 0.4 : 0.0)).cast<float>());
    }
    for (double z = 0.0; z <= 2.0; z += 0.02) {
      points.emplace_back(Eigen::Vector3d(x, 1.42, z).cast<float>());
      points.emplace_back(Eigen::Vector3d(x, -1.42, z).cast<float>());
    }
  }
  if (box_on_ramp) {  // the box's near face
    for (double y = -0.6; y <= 0.6; y += 0.02) {
      for (double z = ramp_height(5.0); z <= ramp_height(5.0) + 0.4; z += 0.02) {
        points.emplace_back(Eigen::Vector3d(5.0, y, z).cast<float>());
      }
    }
  }
  return points;
}

// An octree of the points seen from 3 m above the ramp's middle, so every ray crosses free space first.
// The octree of points_W; terrain_enabled false builds it under the rule "every voxel in the band is an obstacle".
std::shared_ptr<const mapping::OctoMapSnapshot> octree_of(const std::vector<Eigen::Vector3f>& points_W,
                                                          bool terrain_enabled = true) {
  mapping::OctoMapParams params;
  params.outlier_filter_enabled = false;
  params.terrain.enabled = terrain_enabled;
  mapping::OctoMapModel model(params);
  const Eigen::Vector3f sensor_W(5.0F, 0.0F, 3.0F);
  std::vector<Eigen::Vector3f> points_S;
  for (const Eigen::Vector3f& p : points_W) points_S.emplace_back(p - sensor_W);
  model.insert_cloud(geometry::Pose3::from_xyz_rpy(5.0, 0.0, 3.0, 0.0, 0.0, 0.0), points_S);
  return model.publish();
}

// The grid a laser plane at 0.6 m maps from the lane's start: the walls, and the ramp where its surface is 0.6 m
// high (x = 6) as a wall across the lane.
std::shared_ptr<const mapping::GridSnapshot> laser_grid() {
  mapping::HimmGrid grid(mapping::HimmParams{});
  for (int repeat = 0; repeat < 5; ++repeat) {
    for (double y = -1.35; y <= 1.35; y += 0.05) grid.insert_ray({0.45, 0.0}, {6.0, y}, true);
    for (double x = 0.0; x <= 11.0; x += 0.1) {
      grid.insert_ray({x, 0.0}, {x, 1.45}, true);
      grid.insert_ray({x, 0.0}, {x, -1.45}, true);
    }
  }
  return grid.snapshot();
}

class TerrainLayer : public ::testing::Test {};

GlobalPathParams bearcat_planner() {
  GlobalPathParams params;
  params.footprint_radius_m = 0.4;
  params.window_margin_m = 3.0;
  return params;
}

TEST_F(TerrainLayer, GlobalPathGoesUpTheRampTheLaserReadsAsAWall) {
  const auto grid = laser_grid();
  const auto octree = octree_of(ramp_world(false));
  const HeightBandLayer band(*octree, kBearcatHeight_m);
  const Eigen::Vector2d start(0.0, 0.0), goal(9.0, 0.0);
  // The grid alone: a wall across the lane, so the only way is out of the lane through the unseen ground around it.
  const GlobalPathResult round = plan_global_path(*grid, nullptr, start, goal, bearcat_planner());
  if (round.status == GlobalPathStatus::kFound) {
    double farthest_aside = 0.0;
    for (const Eigen::Vector2d& waypoint : round.waypoints_W)
      farthest_aside = std::max(farthest_aside, std::abs(waypoint.y()));
    EXPECT_GT(farthest_aside, 1.4);
  }
  const GlobalPathResult up = plan_global_path(*grid, &band, start, goal, bearcat_planner());
  ASSERT_EQ(up.status, GlobalPathStatus::kFound) << to_string(up.status);
  for (const Eigen::Vector2d& waypoint : up.waypoints_W) EXPECT_LT(std::abs(waypoint.y()), 0.6);
  double length_m = 0.0;
  for (std::size_t i = 0; i + 1 < up.waypoints_W.size(); ++i) {
    length_m += (up.waypoints_W[i + 1] - up.waypoints_W[i]).norm();
  }
  EXPECT_LT(length_m, 9.5);
  EXPECT_TRUE(band.segment_clear(start, goal, 0.4));
  EXPECT_TRUE(band.segment_clear({8.0, 0.0}, {8.5, 0.5}, 0.4)) << "standing on the platform";
  const auto octree_without_rule = octree_of(ramp_world(false), false);
  const HeightBandLayer band_without_rule(*octree_without_rule, kBearcatHeight_m);
  EXPECT_NE(plan_global_path(*grid, &band_without_rule, start, goal, bearcat_planner()).status,
            GlobalPathStatus::kFound)
      << "without the terrain rule the slope is in the height band";
  EXPECT_FALSE(band_without_rule.segment_clear(start, goal, 0.4));
}

TEST_F(TerrainLayer, BoxStandingOnTheRampStillBlocks) {
  const auto octree = octree_of(ramp_world(true));
  const HeightBandLayer band(*octree, kBearcatHeight_m);
  EXPECT_FALSE(band.segment_clear({0.0, 0.0}, {9.0, 0.0}, 0.4));
  EXPECT_FALSE(band.segment_clear({4.0, 0.0}, {6.0, 0.0}, 0.0)) << "the box itself";
  EXPECT_TRUE(band.segment_clear({0.0, 0.8}, {4.0, 0.8}, 0.2)) << "the ramp beside it";
}

TEST_F(TerrainLayer, GuardLetsTheRobotClimbTheRampButNotIntoABoxOnIt) {
  const auto grid = laser_grid();
  const auto ramp = octree_of(ramp_world(false));
  const geometry::Pose2 on_the_ramp{5.3, 0.0, 0.0};  // the front at 5.8, the laser's wall at 6
  const GuardParams params;
  const GuardDecision climb = guard_command({grid.get(), ramp.get(), nullptr}, kBearcat, on_the_ramp, 0.5, 0.0, params);
  EXPECT_EQ(climb.action, GuardAction::kPass) << climb.zone << " " << climb.model;
  EXPECT_EQ(model_in_contact({grid.get(), ramp.get(), nullptr}, kBearcat, {6.5, 0.0, 0.0}, params), "")
      << "standing where the laser plane is inside the ramp";

  const auto box = octree_of(ramp_world(true));
  const GuardDecision into_box =
      guard_command({grid.get(), box.get(), nullptr}, kBearcat, {4.2, 0.0, 0.0}, 0.5, 0.0, params);
  EXPECT_NE(into_box.action, GuardAction::kPass);
  EXPECT_EQ(into_box.model, "octomap");

  const auto ramp_without_rule = octree_of(ramp_world(false), false);
  const GuardDecision wall =
      guard_command({grid.get(), ramp_without_rule.get(), nullptr}, kBearcat, on_the_ramp, 0.5, 0.0, params);
  EXPECT_NE(wall.action, GuardAction::kPass) << "without the terrain rule the laser's wall and the slope stop it";
}

TEST_F(TerrainLayer, LaserReturnsOnTheFloorStayObstacles) {
  // A thin pole the depth camera's rays passed by: only the laser saw it, on a floor the octree holds as drivable.
  mapping::HimmGrid grid(mapping::HimmParams{});
  for (int repeat = 0; repeat < 5; ++repeat) grid.insert_ray({0.45, 0.0}, {2.55, 0.05}, true);
  const auto octree = octree_of(ramp_world(false));
  const auto snapshot = grid.snapshot();
  const GuardDecision decision =
      guard_command({snapshot.get(), octree.get(), nullptr}, kBearcat, {1.7, 0.0, 0.0}, 0.5, 0.0, GuardParams{});
  EXPECT_NE(decision.action, GuardAction::kPass);
  EXPECT_EQ(decision.model, "grid");
}

}  // namespace
}  // namespace occgeo::service::control
