// Two servers in one process keep their own settings: nothing the server reads while it runs is process-wide. Here
// the terrain rule (config section `terrain:`), which decides how high above the floor the octree's voxels start to
// count as obstacles for a footprint.
#include <gtest/gtest.h>

#include <vector>

#include "core.h"
#include "model_geometry.h"
#include "occgeo/service/config.h"
#include "occgeo/v1/session.pb.h"

namespace occgeo::service {
namespace {

// A 0.5 x 0.5 m slab of points 0.15 m above the floor, 1 m ahead of the origin: a kerb-like obstacle.
std::vector<Eigen::Vector3f> slab_points() {
  std::vector<Eigen::Vector3f> points;
  for (float x = 0.75F; x <= 1.25F; x += 0.02F) {
    for (float y = -0.25F; y <= 0.25F; y += 0.02F) points.emplace_back(x, y, 0.15F);
  }
  return points;
}

ServerConfig config_with_ground_band(double ground_band_m) {
  ServerConfig config;
  config.terrain.ground_band_m = ground_band_m;
  config.terrain.enabled = false;  // every voxel in the band is an obstacle: only the band's floor differs
  config.octomap.outlier_filter_enabled = false;
  return config;
}

// The world's octree after the slab was seen from 2 m above the origin, as its readers get it.
std::shared_ptr<const mapping::OctoMapSnapshot> octree_with_slab(ServerCore& core) {
  auto world = core.add_world("yard", mapping::HimmGrid(core.config().himm));
  world->with_octree_on_strand([](mapping::OctoMapModel& octomap) {
    std::vector<Eigen::Vector3f> points_S;
    for (const Eigen::Vector3f& p : slab_points()) points_S.emplace_back(p - Eigen::Vector3f(0.0F, 0.0F, 2.0F));
    octomap.insert_cloud(geometry::Pose3::from_xyz_rpy(0.0, 0.0, 2.0, 0.0, 0.0, 0.0), points_S);
  });
  return world->publish_octomap_on_strand();
}

TEST(ServerInstances, TwoServersInOneProcessKeepTheirOwnTerrainSettings) {
  ServerCore low_band(config_with_ground_band(0.05));
  const auto low_octree = octree_with_slab(low_band);
  // Built second: with a process-wide setting it would have replaced the first server's.
  ServerCore high_band(config_with_ground_band(0.30));
  const auto high_octree = octree_with_slab(high_band);

  const geometry::Footprint box = geometry::BoxFootprint{0.6, 0.6, 1.0, 0.0};
  const geometry::Pose2 over_the_slab{1.0, 0.0, 0.0};
  EXPECT_NEAR(octomap_ground_band_m(*low_octree), 0.06, 1e-9);
  EXPECT_NEAR(octomap_ground_band_m(*high_octree), 0.31, 1e-9);
  EXPECT_TRUE(collide_octomap(*low_octree, box, over_the_slab).hit)
      << "a 0.15 m slab is an obstacle to the server whose floor band ends at 0.05 m";
  EXPECT_FALSE(collide_octomap(*high_octree, box, over_the_slab).hit)
      << "the same slab is floor to the server whose band ends at 0.30 m";
  // And a fresh publication of the first server's world still follows its own rule.
  const auto low_again = octree_with_slab(low_band);
  EXPECT_TRUE(collide_octomap(*low_again, box, over_the_slab).hit);
}

// Each robot's Bearcat behaviour turns wheel speeds into motion with its own wheel (or track) separation, not the one
// robot's in the configuration: a small differential robot and a tracked one on the same server differ.
TEST(ServerInstances, EveryRobotsBearcatUsesItsOwnWheelSeparation) {
  ServerCore core{ServerConfig{}};
  auto small = std::make_shared<RobotModel>();
  small->id = "small";
  small->drive = geometry::DifferentialDriveParams{0.3, 0.05, 0.5};
  auto tracked = std::make_shared<RobotModel>();
  tracked->id = "tracked";
  geometry::SkidSteerParams tracks = geometry::ugv_skid_steer_params();
  tracks.track_separation_m = 0.55;
  tracked->drive = tracks;
  std::string error;
  const auto small_robot = core.register_robot(small, "default", error);
  const auto tracked_robot = core.register_robot(tracked, "default", error);
  ASSERT_TRUE(small_robot && tracked_robot) << error;
  EXPECT_DOUBLE_EQ(small_robot->behaviour_on_strand().params().wheel_separation_m, 0.3);
  EXPECT_DOUBLE_EQ(tracked_robot->behaviour_on_strand().params().wheel_separation_m, 0.55);
  EXPECT_DOUBLE_EQ(bearcat_params_for(*small, core.config().bearcat).wheel_separation_m, 0.3);
  EXPECT_DOUBLE_EQ(core.config().bearcat.wheel_separation_m, 0.7) << "the configuration itself is left alone";
}

// Each server counts into its own registry: a robot of the same name on two servers has two sets of counters, and
// one server's /metrics shows only what happened on it.
TEST(ServerInstances, TwoServersInOneProcessCountTheirOwnMetrics) {
  ServerCore first{ServerConfig{}};
  ServerCore second{ServerConfig{}};
  auto model = std::make_shared<RobotModel>();
  model->id = "alpha";
  std::string error;
  const auto on_first = first.register_robot(model, "default", error);
  const auto on_second = second.register_robot(model, "default", error);
  ASSERT_TRUE(on_first && on_second) << error;
  for (int i = 0; i < 3; ++i) on_first->counters().scans_rejected.inc();
  on_second->counters().guard_interventions.inc();
  const std::string status_kind = "status";
  first.query_counts().at(v1::ClientMessage::kStatus, status_kind).inc();

  const std::string first_text = first.metrics().render();
  const std::string second_text = second.metrics().render();
  EXPECT_NE(first_text.find("occgeo_scans_rejected_total{robot=\"alpha\"} 3\n"), std::string::npos) << first_text;
  EXPECT_NE(second_text.find("occgeo_scans_rejected_total{robot=\"alpha\"} 0\n"), std::string::npos) << second_text;
  EXPECT_NE(first_text.find("occgeo_guard_interventions_total{robot=\"alpha\"} 0\n"), std::string::npos);
  EXPECT_NE(second_text.find("occgeo_guard_interventions_total{robot=\"alpha\"} 1\n"), std::string::npos);
  EXPECT_NE(first_text.find("occgeo_queries_total{kind=\"status\"} 1\n"), std::string::npos);
  EXPECT_EQ(second_text.find("occgeo_queries_total"), std::string::npos) << "no query reached the second server";
}

}  // namespace
}  // namespace occgeo::service
