// OctoMapModel on synthetic geometry: sensor poses in 3D, max-range readings, snapshots, queries, FCL collision and
// parameter validation.

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "occgeo/mapping/octomap_model.h"
#include "unfiltered_octomap.h"

namespace occgeo::mapping {
namespace {

using geometry::Pose3;
constexpr double kPi = std::numbers::pi;

using test_support::unfiltered;

// Pose of the sensor that sees the wall below.
const Pose3 X_WS_wall = Pose3::from_xyz_rpy(0.0, 0.0, 0.5, 0.0, 0.0, 0.0);

// Centres of the voxels of a wall filling x in [2.0, 2.05), y in [-1, 1), z in [0, 1) at 5 cm, one point per voxel (so
// the wall is exactly those voxels), in the frame of a sensor at X_WS_wall.
std::vector<Eigen::Vector3f> wall_points_S() {
  std::vector<Eigen::Vector3f> points;
  for (int iy = -20; iy < 20; ++iy) {
    for (int iz = 0; iz < 20; ++iz) points.emplace_back(2.025F, 0.05F * iy + 0.025F, 0.05F * iz + 0.025F - 0.5F);
  }
  return points;
}

TEST(OctoMapModelTest, PitchedElevatedLaserHitsTheFloorWhereGeometrySays) {
  // Robot at (2, 1) facing +y; laser 0.2 m ahead of the axle, 0.5 m above the floor (whose surface lies mid-voxel at
  // z = 0.025), pitched down 30°. Beam at angle a in the laser plane meets the floor after 0.5 / (sin 30° cos a) m.
  const Pose3 X_WB = Pose3::from_xyz_rpy(2.0, 1.0, 0.025, 0.0, 0.0, kPi / 2);
  const Pose3 X_BS = Pose3::from_xyz_rpy(0.2, 0.0, 0.5, 0.0, kPi / 6, 0.0);
  const Pose3 X_WS = X_WB.compose(X_BS);
  const float angle_min = -std::numbers::pi_v<float> / 4;
  const float angle_increment = std::numbers::pi_v<float> / 180;
  std::vector<float> ranges;
  std::vector<Eigen::Vector3d> floor_points_W;
  for (int i = 0; i <= 90; ++i) {
    const double a = double{angle_min} + i * double{angle_increment};
    const double r = 0.5 / (std::sin(kPi / 6) * std::cos(a));
    ranges.push_back(static_cast<float>(r));
    floor_points_W.push_back(X_WS.transform * Eigen::Vector3d{r * std::cos(a), r * std::sin(a), 0.0});
  }
  // The straight-ahead beam: 1 m long, landing 0.866 m ahead of the laser along the robot's heading (+y).
  EXPECT_NEAR(floor_points_W[45].x(), 2.0, 1e-6);
  EXPECT_NEAR(floor_points_W[45].y(), 1.0 + 0.2 + 0.5 / std::tan(kPi / 6), 1e-6);
  EXPECT_NEAR(floor_points_W[45].z(), 0.025, 1e-6);

  OctoMapModel model{unfiltered()};
  model.insert_scan(X_WS, angle_min, angle_increment, ranges, 4.0F);
  const auto snapshot = model.publish();
  for (const Eigen::Vector3d& p_W : floor_points_W) EXPECT_TRUE(snapshot->occupied(p_W)) << p_W.transpose();
  // Every occupied voxel is a floor voxel, and the laser's own position was cleared, not marked.
  const auto occupied = snapshot->occupied_in_box({-10, -10, -10}, {10, 10, 10});
  EXPECT_LE(occupied.size(), floor_points_W.size());
  EXPECT_GE(occupied.size(), 20U);  // beams 1.7 cm apart on the floor share voxels
  for (const OctoVoxel& v : occupied) EXPECT_NEAR(v.center_W.z(), 0.025, 1e-6);
  EXPECT_FALSE(snapshot->occupied(X_WS.translation() + Eigen::Vector3d{0.0, 0.3, -0.15}));
  // The level-mount mistake would have put the hits at laser height.
  EXPECT_TRUE(snapshot->occupied_in_box({-10, -10, 0.3}, {10, 10, 10}).empty());
}

TEST(OctoMapModelTest, SingleRayFollowsTheSensorAxis) {
  // A sonar on a mast, looking down 90°: its 1 m reading hits straight below.
  OctoMapModel model{unfiltered()};
  const Pose3 X_WS = Pose3::from_xyz_rpy(0.025, 0.025, 1.525, 0.0, kPi / 2, 0.0);
  model.insert_ray(X_WS, 1.0, 3.0);
  const auto snapshot = model.publish();
  EXPECT_TRUE(snapshot->occupied({0.025, 0.025, 0.525}));
  EXPECT_LT(*snapshot->occupancy({0.025, 0.025, 1.0}), 0.5);
  EXPECT_FALSE(snapshot->occupancy({0.025, 0.025, 0.4}).has_value());
}

TEST(OctoMapModelTest, MaxRangeReadingsClearWithoutMarking) {
  OctoMapParams params = unfiltered();
  params.max_range_m = 3.0;
  OctoMapModel model{params};
  // On a voxel centre, so that the beams run along voxel centres, away from voxel faces.
  const Pose3 X_WS = Pose3::from_xyz_rpy(0.025, 0.025, 0.525, 0.0, 0.0, 0.0);
  // Beam 0 (+x) reads the scan's max range, beam 1 (+y) +inf, beam 2 (-x) 3.5 m: beyond params.max_range_m, so it
  // clears 3 m only. None of them marks anything.
  const std::vector<float> ranges{4.0F, std::numeric_limits<float>::infinity(), 3.5F};
  model.insert_scan(X_WS, 0.0F, std::numbers::pi_v<float> / 2, ranges, 4.0F);
  const auto snapshot = model.publish();
  EXPECT_TRUE(snapshot->occupied_in_box({-10, -10, -10}, {10, 10, 10}).empty());
  const auto free = [&](double x, double y) {
    const std::optional<double> p = snapshot->occupancy({x, y, 0.525});
    return p.has_value() && *p < 0.5;
  };
  EXPECT_TRUE(free(2.9, 0.025));                                        // cleared up to min(range_max 4, max_range_m 3)
  EXPECT_FALSE(snapshot->occupancy({3.2, 0.025, 0.525}).has_value());   // beyond max_range_m: untouched
  EXPECT_TRUE(free(0.025, 2.9));                                        // +inf clears too
  EXPECT_TRUE(free(-2.9, 0.025));                                       // the 3.5 m reading cleared to 3 m...
  EXPECT_FALSE(snapshot->occupancy({-3.4, 0.025, 0.525}).has_value());  // ...and marked nothing where it ended

  // A max-range reading clears a voxel an earlier scan marked, a little at a time.
  model.insert_scan(X_WS, 0.0F, 0.0F, std::vector<float>{2.0F}, 4.0F);
  const Eigen::Vector3d p_hit{2.025, 0.025, 0.525};
  ASSERT_TRUE(model.occupancy(p_hit).has_value());
  EXPECT_GT(*model.occupancy(p_hit), 0.5);
  for (int i = 0; i < 5; ++i) model.insert_scan(X_WS, 0.0F, 0.0F, std::vector<float>{4.0F}, 4.0F);
  EXPECT_LT(model.occupancy(p_hit).value_or(1.0), 0.5);
}

TEST(OctoMapModelTest, ZeroReadingsAreNoReturnAndBadReadingsAreRejected) {
  OctoMapModel model{unfiltered()};
  const Pose3 X_WS;
  model.insert_scan(X_WS, 0.0F, 0.1F, std::vector<float>{0.0F, 0.0F}, 4.0F);
  EXPECT_EQ(model.leaf_count(), 0U);
  try {
    model.insert_scan(X_WS, 0.0F, 0.1F, std::vector<float>{1.0F, -1.0F}, 4.0F);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ranges[1]"), std::string::npos) << e.what();
  }
  EXPECT_EQ(model.leaf_count(), 0U);  // nothing applied
  Pose3 bad;
  bad.transform.translation().x() = std::nan("");
  EXPECT_THROW(model.insert_ray(bad, 1.0, 2.0), std::invalid_argument);
  EXPECT_THROW(model.insert_ray(X_WS, std::nan(""), 2.0), std::invalid_argument);
  EXPECT_THROW(model.insert_ray(X_WS, 1.0, 0.0), std::invalid_argument);
}

TEST(OctoMapModelTest, SnapshotsAreImmutableWhileIngestGoesOn) {
  OctoMapModel model{unfiltered()};
  const auto empty = model.snapshot();
  ASSERT_NE(empty, nullptr);
  EXPECT_EQ(empty->leaf_count(), 0U);

  model.insert_cloud(X_WS_wall, wall_points_S());
  EXPECT_EQ(model.snapshot(), empty);  // not published yet
  const auto first = model.publish();
  EXPECT_EQ(model.snapshot(), first);
  EXPECT_EQ(first->version(), 1U);
  EXPECT_TRUE(first->occupied({2.02, 0.0, 0.5}));

  // Clearing the wall through a window changes the model and later snapshots, not the one readers already hold.
  for (int i = 0; i < 10; ++i) model.insert_ray(Pose3::from_xyz_rpy(0.0, 0.025, 0.525, 0.0, 0.0, 0.0), 5.0, 5.0);
  const Eigen::Vector3d p_window{2.025, 0.025, 0.525};
  EXPECT_LT(*model.occupancy(p_window), 0.5);
  EXPECT_TRUE(first->occupied(p_window));
  EXPECT_FALSE(empty->occupancy(p_window).has_value());
  const auto second = model.publish();
  EXPECT_FALSE(second->occupied(p_window));

  // maybe_publish: nothing new → no publish; new data but too soon → none; after the interval → one.
  const auto t0 = OctoMapModel::Clock::now();
  EXPECT_FALSE(model.maybe_publish(t0 + std::chrono::hours(1)));
  model.insert_ray(Pose3{}, 1.0, 5.0);
  EXPECT_FALSE(model.maybe_publish(t0 - std::chrono::hours(1)));
  EXPECT_TRUE(model.maybe_publish(t0 + std::chrono::hours(1)));
  EXPECT_EQ(model.snapshot()->version(), model.version());
}

TEST(OctoMapModelTest, QueriesOnAWall) {
  OctoMapModel model{unfiltered()};
  model.insert_cloud(X_WS_wall, wall_points_S());
  const auto snapshot = model.publish();

  // Ray cast along +x at mid height stops at the wall's voxel centre.
  const auto hit = snapshot->cast_ray({0.0, 0.025, 0.525}, {1.0, 0.0, 0.0}, 5.0);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->voxel_center_W.x(), 2.025, 1e-6);
  EXPECT_NEAR(hit->distance_m, 2.025, 1e-6);
  // Over the wall (it ends at z = 1) and too short: nothing.
  EXPECT_FALSE(snapshot->cast_ray({0.0, 0.025, 1.2}, {1.0, 0.0, 0.0}, 5.0).has_value());
  EXPECT_FALSE(snapshot->cast_ray({0.0, 0.025, 0.525}, {1.0, 0.0, 0.0}, 1.5).has_value());
  EXPECT_THROW((void)snapshot->cast_ray({0, 0, 0}, {0, 0, 0}, 1.0), std::invalid_argument);

  // A height band z in [0.2, 0.3] over y in [-0.5, 0.5]: wall voxels only, all inside the band's voxels.
  const auto band = snapshot->occupied_in_box({-5.0, -0.5, 0.2}, {5.0, 0.5, 0.3});
  EXPECT_GE(band.size(), 2U * 20U);
  for (const OctoVoxel& v : band) {
    EXPECT_NEAR(v.center_W.x(), 2.025, 1e-6);
    EXPECT_GE(v.center_W.z(), 0.2 - 0.05);
    EXPECT_LE(v.center_W.z(), 0.3 + 0.05);
    EXPECT_GT(v.probability, 0.5);
  }
  // Unknown is distinguished from free: behind the wall nothing was observed, in front it was cleared.
  EXPECT_FALSE(snapshot->occupancy({3.0, 0.025, 0.525}).has_value());
  EXPECT_LT(snapshot->occupancy({1.0, 0.025, 0.525}).value_or(1.0), 0.5);
  EXPECT_FALSE(snapshot->occupancy({1e9, 0.0, 0.0}).has_value());  // beyond OctoMap's key range
}

TEST(OctoMapModelTest, FclCollisionOfFootprintsAgainstAWall) {
  OctoMapModel model{unfiltered()};
  model.insert_cloud(X_WS_wall, wall_points_S());
  const auto snapshot = model.publish();
  // A 0.6 m long box, 0.5 m tall: its front is at x + 0.3. The wall's voxels start at x = 2.0.
  const geometry::BoxFootprint box{0.6, 0.4, 0.5, 0.0};
  EXPECT_FALSE(snapshot->collide(box, Pose3::from_xyz_rpy(1.0, 0.0, 0.0, 0.0, 0.0, 0.0)).hit);
  EXPECT_FALSE(snapshot->collide(box, Pose3::from_xyz_rpy(1.69, 0.0, 0.0, 0.0, 0.0, 0.0)).hit);
  const OctoCollision c = snapshot->collide(box, Pose3::from_xyz_rpy(1.8, 0.0, 0.0, 0.0, 0.0, 0.0));
  EXPECT_TRUE(c.hit);
  EXPECT_GE(c.contact_W.x(), 2.0 - 1e-6);
  EXPECT_LE(c.contact_W.x(), 2.1 + 1e-6);
  EXPECT_LE(std::abs(c.contact_W.y()), 0.2 + 1e-6);
  // Turned 90°, the box is only 0.4 m deep along x: front at x + 0.2.
  EXPECT_FALSE(snapshot->collide(box, Pose3::from_xyz_rpy(1.75, 0.0, 0.0, 0.0, 0.0, kPi / 2)).hit);
  // Raised above the wall's top (z = 1): free in 3D although its ground projection overlaps.
  EXPECT_FALSE(snapshot->collide(box, Pose3::from_xyz_rpy(2.0, 0.0, 1.05, 0.0, 0.0, 0.0)).hit);
  EXPECT_TRUE(snapshot->collide(box, Pose3::from_xyz_rpy(2.0, 0.0, 0.9, 0.0, 0.0, 0.0)).hit);
  // Beyond the wall's end (y >= 1) it is unknown space, which counts as free.
  EXPECT_FALSE(snapshot->collide(box, Pose3::from_xyz_rpy(2.0, 1.3, 0.0, 0.0, 0.0, 0.0)).hit);
  // A cylinder of radius 0.3.
  const geometry::CylinderFootprint cylinder{0.3, 1.0};
  EXPECT_FALSE(snapshot->collide(cylinder, Pose3::from_xyz_rpy(1.65, 0.0, 0.0, 0.0, 0.0, 0.0)).hit);
  EXPECT_TRUE(snapshot->collide(cylinder, Pose3::from_xyz_rpy(1.75, 0.0, 0.0, 0.0, 0.0, 0.0)).hit);
  EXPECT_THROW((void)snapshot->collide(geometry::BoxFootprint{0.0, 1.0, 1.0, 0.0}, Pose3{}), std::invalid_argument);
}

TEST(OctoMapModelTest, FiltersReduceTheCloudAsConfigured) {
  // 1000 points on a 1 cm lattice filling a 10 cm cube, plus one outlier 8 m away.
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 10; ++j) {
      for (int k = 0; k < 10; ++k)
        points.emplace_back(1.0F + 0.005F + 0.01F * i, 0.005F + 0.01F * j, 0.005F + 0.01F * k);
    }
  }
  points.emplace_back(5.0F, 5.0F, 5.0F);
  const Pose3 X_WS;
  OctoMapParams params = unfiltered();
  EXPECT_EQ(OctoMapModel{params}.insert_cloud(X_WS, points), 1001U);
  params.voxel_filter_enabled = true;  // 5 cm leaves: the cube spans 2 x 2 x 2 of them
  EXPECT_EQ(OctoMapModel{params}.insert_cloud(X_WS, points), 8U + 1U);
  params.voxel_leaf_m = 0.2;  // one leaf holds the cube
  EXPECT_EQ(OctoMapModel{params}.insert_cloud(X_WS, points), 1U + 1U);
  params.voxel_filter_enabled = false;
  params.outlier_filter_enabled = true;
  params.outlier_mean_k = 8;
  EXPECT_EQ(OctoMapModel{params}.insert_cloud(X_WS, points), 1000U);  // the outlier goes, the cube stays
  // NaNs (an organized cloud's invalid pixels) are dropped before anything else.
  points.emplace_back(std::nanf(""), 0.0F, 0.0F);
  params.outlier_filter_enabled = false;
  EXPECT_EQ(OctoMapModel{params}.insert_cloud(X_WS, points), 1001U);
}

TEST(OctoMapModelTest, ValidationNamesTheField) {
  const auto expect_field = [](OctoMapParams params, const std::string& field) {
    try {
      params.validate();
      ADD_FAILURE() << field << ": no exception";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("OctoMapParams." + field + " "), std::string::npos) << e.what();
    }
    EXPECT_THROW(OctoMapModel{params}, std::invalid_argument);
  };
  OctoMapParams p;
  EXPECT_NO_THROW(p.validate());
  p = {};
  p.resolution_m = 0.0;
  expect_field(p, "resolution_m");
  p = {};
  p.resolution_m = std::nan("");
  expect_field(p, "resolution_m");
  p = {};
  p.prob_hit = 0.5;
  expect_field(p, "prob_hit");
  p = {};
  p.prob_miss = 0.6;
  expect_field(p, "prob_miss");
  p = {};
  p.clamping_min = 0.45;
  expect_field(p, "clamping_min");
  p = {};
  p.clamping_max = 1.0;
  expect_field(p, "clamping_max");
  p = {};
  p.occupancy_threshold = 0.99;
  expect_field(p, "occupancy_threshold");
  p = {};
  p.max_range_m = -1.0;
  expect_field(p, "max_range_m");
  p = {};
  p.voxel_leaf_m = -0.1;
  expect_field(p, "voxel_leaf_m");
  p = {};
  p.outlier_mean_k = 0;
  expect_field(p, "outlier_mean_k");
  p = {};
  p.outlier_stddev_mul = 0.0;
  expect_field(p, "outlier_stddev_mul");
  p = {};
  p.min_publish_interval_s = -1.0;
  expect_field(p, "min_publish_interval_s");
}

}  // namespace
}  // namespace occgeo::mapping
