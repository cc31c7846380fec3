// The snapshot's occupied-column broadphase: collide (broadphase, then FCL) must answer exactly as collide_fcl_only
// (FCL's octree walk for every pose), on a room mapped from laser scans, on a pruned tree with big leaves and on an
// empty tree.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "occgeo/mapping/octomap_model.h"
#include "unfiltered_octomap.h"

namespace occgeo::mapping {
namespace {

using geometry::Pose3;
constexpr double kPi = std::numbers::pi;

using test_support::unfiltered;

// The room: walls at x = ±3 m and y = ±2 m, floor at z = 0, open to the sky.
constexpr double kRoomHalfX = 3.0;
constexpr double kRoomHalfY = 2.0;

// Range along direction_W from origin_W (inside the room) to the first wall or the floor.
double room_range(const Eigen::Vector3d& origin_W, const Eigen::Vector3d& direction_W) {
  double range = std::numeric_limits<double>::infinity();
  const auto consider = [&](double origin, double direction, double plane) {
    if (direction == 0.0) return;
    const double t = (plane - origin) / direction;
    if (t > 0.0) range = std::min(range, t);
  };
  consider(origin_W.x(), direction_W.x(), kRoomHalfX);
  consider(origin_W.x(), direction_W.x(), -kRoomHalfX);
  consider(origin_W.y(), direction_W.y(), kRoomHalfY);
  consider(origin_W.y(), direction_W.y(), -kRoomHalfY);
  consider(origin_W.z(), direction_W.z(), 0.0);
  return range;
}

// A room mapped by a level laser at several heights and a laser pitched down at the floor, from several places.
std::shared_ptr<const OctoMapSnapshot> scanned_room(OctoMapModel& model) {
  const float angle_min = -std::numbers::pi_v<float>;
  const float angle_increment = std::numbers::pi_v<float> / 360;
  constexpr float kRangeMax = 8.0F;
  const std::vector<Eigen::Vector2d> places{{0.0, 0.0}, {-1.8, 1.1}, {2.1, -0.9}, {1.0, 1.2}};
  for (const Eigen::Vector2d& place : places) {
    for (const Pose3& X_WS : {Pose3::from_xyz_rpy(place.x(), place.y(), 0.3, 0.0, 0.0, 0.2),
                              Pose3::from_xyz_rpy(place.x(), place.y(), 1.1, 0.0, 0.0, -0.4),
                              Pose3::from_xyz_rpy(place.x(), place.y(), 0.6, 0.0, 0.35, 0.9)}) {
      std::vector<float> ranges;
      for (int i = 0; i < 720; ++i) {
        const double a = double{angle_min} + i * double{angle_increment};
        const Eigen::Vector3d direction_W = X_WS.transform.linear() * Eigen::Vector3d{std::cos(a), std::sin(a), 0.0};
        ranges.push_back(static_cast<float>(std::min(room_range(X_WS.translation(), direction_W), 8.0)));
      }
      model.insert_scan(X_WS, angle_min, angle_increment, ranges, kRangeMax);
    }
  }
  return model.publish();
}

geometry::Footprint random_footprint(std::mt19937& rng) {
  std::uniform_real_distribution<double> size(0.05, 1.2), height(0.05, 1.5);
  switch (std::uniform_int_distribution<int>(0, 2)(rng)) {
    case 0:
      return geometry::BoxFootprint{size(rng), size(rng), height(rng),
                                    std::uniform_real_distribution<double>(-0.3, 0.3)(rng)};
    case 1:
      return geometry::CylinderFootprint{size(rng) / 2, height(rng)};
    default: {
      // A convex polygon: points on a circle at increasing angles.
      const int n = std::uniform_int_distribution<int>(3, 7)(rng);
      const double radius = size(rng) / 2;
      geometry::ConvexPolygonFootprint polygon;
      for (int k = 0; k < n; ++k) {
        const double angle = 2 * kPi * (k + 0.5 * std::uniform_real_distribution<double>(0.0, 1.0)(rng)) / n;
        polygon.vertices_B.emplace_back(0.1 + radius * std::cos(angle), radius * std::sin(angle));
      }
      polygon.height = height(rng);
      return polygon;
    }
  }
}

// Poses over the box [lo, hi] (yaw anywhere; every second pose also rolled and pitched), plus a few far away.
std::vector<Pose3> random_poses(std::mt19937& rng, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int count) {
  std::uniform_real_distribution<double> x(lo.x(), hi.x()), y(lo.y(), hi.y()), z(lo.z(), hi.z()), yaw(-kPi, kPi),
      tilt(-0.6, 0.6);
  std::vector<Pose3> poses;
  for (int i = 0; i < count; ++i) {
    const bool tilted = i % 2 == 1;
    poses.push_back(
        Pose3::from_xyz_rpy(x(rng), y(rng), z(rng), tilted ? tilt(rng) : 0.0, tilted ? tilt(rng) : 0.0, yaw(rng)));
  }
  poses.push_back(Pose3::from_xyz_rpy(500.0, 0.0, 0.0, 0.0, 0.0, 0.0));
  poses.push_back(Pose3::from_xyz_rpy(-1500.0, 1500.0, -3.0, 0.3, 0.0, 1.0));
  poses.push_back(Pose3::from_xyz_rpy(0.0, 0.0, 4000.0, 0.0, 0.0, 0.0));
  return poses;
}

struct Tally {
  int hits = 0;
  int misses = 0;
};

// Compares collide with collide_fcl_only for every pose and footprint; returns how many hit and missed.
Tally expect_same_answers(const OctoMapSnapshot& snapshot, std::mt19937& rng, const std::vector<Pose3>& poses) {
  Tally tally;
  for (const Pose3& X_WB : poses) {
    const geometry::Footprint footprint = random_footprint(rng);
    const OctoCollision with_broadphase = snapshot.collide(footprint, X_WB);
    const OctoCollision fcl_only = snapshot.collide_fcl_only(footprint, X_WB);
    EXPECT_EQ(with_broadphase.hit, fcl_only.hit)
        << "footprint #" << footprint.index() << " at " << X_WB.translation().transpose();
    if (with_broadphase.hit && fcl_only.hit) {
      EXPECT_EQ(with_broadphase.contact_W, fcl_only.contact_W);
    }
    (fcl_only.hit ? tally.hits : tally.misses) += 1;
  }
  return tally;
}

TEST(OctoMapBroadphaseTest, ScannedRoomAnswersAsFclAlone) {
  OctoMapModel model{unfiltered()};
  const auto snapshot = scanned_room(model);
  ASSERT_GT(snapshot->occupied_in_box({-10, -10, -10}, {10, 10, 10}).size(), 1000U);
  std::mt19937 rng(20261202);
  // Over the room and a metre beyond its walls, from below the floor to above the walls' top.
  const auto poses =
      random_poses(rng, {-kRoomHalfX - 1.0, -kRoomHalfY - 1.0, -0.6}, {kRoomHalfX + 1.0, kRoomHalfY + 1.0, 2.0}, 1500);
  const Tally tally = expect_same_answers(*snapshot, rng, poses);
  // Both answers are common, so the comparison exercises the broadphase's "free" and its hand-over to FCL.
  EXPECT_GT(tally.hits, 200);
  EXPECT_GT(tally.misses, 200);
}

TEST(OctoMapBroadphaseTest, PosesHuggingTheWallsAnswerAsFclAlone) {
  OctoMapModel model{unfiltered()};
  const auto snapshot = scanned_room(model);
  std::mt19937 rng(7);
  // Small footprints within a few centimetres of the wall x = 3 and of the floor, where a summary rounding a single
  // voxel the wrong way would answer "free" for a touching pose.
  std::vector<Pose3> poses;
  std::uniform_real_distribution<double> y(-1.5, 1.5), offset(-0.1, 0.1), yaw(-kPi, kPi);
  for (int i = 0; i < 600; ++i) {
    const geometry::Footprint probe = geometry::BoxFootprint{0.2, 0.2, 0.2, 0.0};
    const Pose3 X_WB = i % 2 == 0 ? Pose3::from_xyz_rpy(kRoomHalfX - 0.1 + offset(rng), y(rng), 0.5, 0.0, 0.0, yaw(rng))
                                  : Pose3::from_xyz_rpy(0.5 * y(rng), y(rng), 0.05 + offset(rng), 0.0, 0.0, yaw(rng));
    poses.push_back(X_WB);
    EXPECT_EQ(snapshot->collide(probe, X_WB).hit, snapshot->collide_fcl_only(probe, X_WB).hit)
        << X_WB.translation().transpose();
  }
  // Exactly touching: the floor's voxels span z in [0, 0.05), the wall's x in [3, 3.05); and a hair away either way.
  for (const double nudge : {-1e-7, 0.0, 1e-7}) {
    const geometry::BoxFootprint probe{0.2, 0.2, 0.2, 0.0};
    for (const Pose3& X_WB : {Pose3::from_xyz_rpy(0.4, 0.3, 0.05 + nudge, 0.0, 0.0, 0.0),
                              Pose3::from_xyz_rpy(kRoomHalfX - 0.1 + nudge, 0.3, 0.5, 0.0, 0.0, 0.0)}) {
      EXPECT_EQ(snapshot->collide(probe, X_WB).hit, snapshot->collide_fcl_only(probe, X_WB).hit)
          << X_WB.translation().transpose();
    }
  }
  const Tally tally = expect_same_answers(*snapshot, rng, poses);
  EXPECT_GT(tally.hits, 50);
  EXPECT_GT(tally.misses, 50);
}

TEST(OctoMapBroadphaseTest, BigPrunedLeavesAreCoveredWholly) {
  // A solid 1.6 m cube, one end point per voxel and all hit once: its 32^3 voxels are equal and prune into one leaf
  // spanning four 8-voxel cells per axis, aligned on the key grid (keys of x = 0 start at 2^15).
  OctoMapModel model{unfiltered()};
  std::vector<Eigen::Vector3f> block_S;
  const Pose3 X_WS = Pose3::from_xyz_rpy(-2.0, 0.8, 0.8, 0.0, 0.0, 0.0);
  for (int ix = 0; ix < 32; ++ix) {
    for (int iy = 0; iy < 32; ++iy) {
      for (int iz = 0; iz < 32; ++iz) {
        const Eigen::Vector3d p_W{0.05 * ix + 0.025, 0.05 * iy + 0.025, 0.05 * iz + 0.025};
        block_S.push_back((X_WS.transform.inverse() * p_W).cast<float>());
      }
    }
  }
  model.insert_cloud(X_WS, block_S);
  const auto snapshot = model.publish();
  double biggest_leaf_m = 0.0;
  snapshot->for_each_leaf([&](const OctoVoxel& v) {
    if (v.probability >= 0.5) biggest_leaf_m = std::max(biggest_leaf_m, v.size_m);
  });
  ASSERT_NEAR(biggest_leaf_m, 1.6, 1e-9);

  // A small probe deep inside the block, away from the leaf's corner, centre and base cell, hits.
  const geometry::BoxFootprint probe{0.1, 0.1, 0.1, 0.0};
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d{1.3, 0.3, 1.2}, Eigen::Vector3d{0.3, 1.35, 0.2}, Eigen::Vector3d{1.5, 1.5, 1.4}}) {
    const Pose3 X_WB = Pose3::from_xyz_rpy(p.x(), p.y(), p.z(), 0.0, 0.0, 0.0);
    EXPECT_TRUE(snapshot->collide(probe, X_WB).hit) << p.transpose();
    EXPECT_TRUE(snapshot->collide_fcl_only(probe, X_WB).hit) << p.transpose();
  }
  // Just above the block, free; reaching 1 cm into it, a hit.
  EXPECT_FALSE(snapshot->collide(probe, Pose3::from_xyz_rpy(0.8, 0.8, 1.61, 0.0, 0.0, 0.0)).hit);
  EXPECT_TRUE(snapshot->collide(probe, Pose3::from_xyz_rpy(0.8, 0.8, 1.59, 0.0, 0.0, 0.0)).hit);

  std::mt19937 rng(1600);
  const auto poses = random_poses(rng, {-1.0, -1.0, -1.0}, {2.6, 2.6, 2.6}, 1000);
  const Tally tally = expect_same_answers(*snapshot, rng, poses);
  EXPECT_GT(tally.hits, 100);
  EXPECT_GT(tally.misses, 100);
}

TEST(OctoMapBroadphaseTest, EmptyAndFreeOnlyTreesNeverCollide) {
  OctoMapModel model{unfiltered()};
  std::mt19937 rng(3);
  const auto poses = random_poses(rng, {-3.0, -3.0, -1.0}, {3.0, 3.0, 1.0}, 100);
  const Tally empty = expect_same_answers(*model.snapshot(), rng, poses);
  EXPECT_EQ(empty.hits, 0);
  // Max-range readings clear space and mark nothing: a tree of free leaves only.
  const std::vector<float> ranges(360, 10.0F);
  model.insert_scan(Pose3::from_xyz_rpy(0.0, 0.0, 0.3, 0.0, 0.0, 0.0), -std::numbers::pi_v<float>,
                    std::numbers::pi_v<float> / 180, ranges, 4.0F);
  const auto snapshot = model.publish();
  ASSERT_GT(snapshot->leaf_count(), 0U);
  const Tally free_only = expect_same_answers(*snapshot, rng, poses);
  EXPECT_EQ(free_only.hits, 0);
}

TEST(OctoMapBroadphaseTest, BadFootprintsAreStillRejected) {
  OctoMapModel model{unfiltered()};
  const auto snapshot = model.publish();
  // The broadphase must not answer "free" before the footprint is validated, even on an empty tree.
  EXPECT_THROW((void)snapshot->collide(geometry::BoxFootprint{0.0, 1.0, 1.0, 0.0}, Pose3{}), std::invalid_argument);
  EXPECT_THROW((void)snapshot->collide(geometry::CylinderFootprint{0.5, -1.0}, Pose3{}), std::invalid_argument);
  geometry::ConvexPolygonFootprint line;
  line.vertices_B = {{0.0, 0.0}, {1.0, 0.0}};
  EXPECT_THROW((void)snapshot->collide(line, Pose3{}), std::invalid_argument);
}

}  // namespace
}  // namespace occgeo::mapping
