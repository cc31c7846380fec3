// OctoMapModel on the real data in ../shared/datasets (beside the repository): the lazy fast path against OctoMap's
// plain insertPointCloud, .bt files, PCL room scans and a Kinect frame. Skipped when the datasets are absent.

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <numbers>
#include <sstream>
#include <string>
#include <tuple>
#include <unordered_set>
#include <vector>

#include "occgeo/mapping/octomap_model.h"
#include "unfiltered_octomap.h"

namespace occgeo::mapping {
namespace {

using geometry::Pose3;

const std::filesystem::path kDatasets = std::filesystem::path(OCCGEO_SOURCE_DIR) / ".." / "shared" / "datasets";

#define REQUIRE_DATASET(path) \
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "dataset absent: " << (path)

// URG-04LX geometry (datasets/urg04lx-mines/SOURCE.txt): 682 beams over ~240°, 360/1024° apart.
constexpr int kUrgBeams = 682;
constexpr float kUrgIncrement = static_cast<float>(2.0 * std::numbers::pi / 1024.0);
constexpr float kUrgAngleMin = -kUrgIncrement * (kUrgBeams - 1) / 2;

// Ranges (metres, 0 = no return) of the scans on lines first..last (1-based) of exp1.dat.
std::vector<std::vector<float>> read_urg_scans(int first, int last) {
  std::ifstream in(kDatasets / "urg04lx-mines" / "exp1.dat");
  std::vector<std::vector<float>> scans;
  std::string line;
  for (int n = 1; n <= last && std::getline(in, line); ++n) {
    if (n < first) continue;
    std::istringstream fields(line);
    std::vector<double> values;
    for (double v = 0; fields >> v;) values.push_back(v);
    std::vector<float>& ranges = scans.emplace_back();
    for (int i = 0; i < kUrgBeams; ++i) ranges.push_back(static_cast<float>(values.at(24 + i)) / 1000.0F);
  }
  return scans;
}

// A leaf as (size, x, y, z, probability), sizes and centres in half voxels (so integers: coordinates computed in float
// and in double compare equal), comparable and sortable.
using LeafTuple = std::tuple<long, long, long, long, double>;

LeafTuple leaf_tuple(double size, double x, double y, double z, double probability) {
  constexpr double kHalfVoxel = 0.025;  // all trees compared here have 5 cm voxels
  return {std::lround(size / kHalfVoxel), std::lround(x / kHalfVoxel), std::lround(y / kHalfVoxel),
          std::lround(z / kHalfVoxel), probability};
}

std::vector<LeafTuple> leaves_of(const OctoMapSnapshot& snapshot) {
  std::vector<LeafTuple> leaves;
  snapshot.for_each_leaf([&](const OctoVoxel& v) {
    leaves.push_back(leaf_tuple(v.size_m, v.center_W.x(), v.center_W.y(), v.center_W.z(), v.probability));
  });
  std::sort(leaves.begin(), leaves.end());
  return leaves;
}

std::vector<LeafTuple> leaves_of(const octomap::OcTree& tree) {
  std::vector<LeafTuple> leaves;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    leaves.push_back(leaf_tuple(it.getSize(), it.getX(), it.getY(), it.getZ(), it->getOccupancy()));
  }
  std::sort(leaves.begin(), leaves.end());
  return leaves;
}

// Number of leaves of a that b lacks or holds with another probability.
std::size_t count_differences(const std::vector<LeafTuple>& a, const std::vector<LeafTuple>& b) {
  std::vector<LeafTuple> only_a;
  std::set_difference(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(only_a));
  return only_a.size();
}

using test_support::unfiltered;

octomap::OcTree plain_tree(const OctoMapParams& params) {
  octomap::OcTree tree(params.resolution_m);
  tree.setProbHit(params.prob_hit);
  tree.setProbMiss(params.prob_miss);
  tree.setClampingThresMin(params.clamping_min);
  tree.setClampingThresMax(params.clamping_max);
  tree.setOccupancyThres(params.occupancy_threshold);
  return tree;
}

octomap::point3d to_octo(const Eigen::Vector3d& p) {
  return {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())};
}

TEST(OctoMapInsertTest, LazyScanInsertionEqualsPlainInsertPointCloudOnRealUrgScans) {
  REQUIRE_DATASET(kDatasets / "urg04lx-mines" / "exp1.dat");
  const std::vector<std::vector<float>> scans = read_urg_scans(300, 329);
  ASSERT_EQ(scans.size(), 30U);
  // Plain OctoMap's update: without the see-through cap, which insertPointCloud does not have.
  OctoMapParams params = unfiltered();
  params.laser_see_through_clears = false;
  OctoMapModel model{params};
  octomap::OcTree plain = plain_tree(params);
  for (std::size_t s = 0; s < scans.size(); ++s) {
    // A laser 0.3 m up, rolled and pitched a little, moving 5 cm and turning 2° per scan: rays in all 3 axes.
    const double k = static_cast<double>(s);
    const Pose3 X_WS = Pose3::from_xyz_rpy(0.05 * k, 0.01 * k, 0.3, 0.02, -0.05, 0.035 * k);
    model.insert_scan(X_WS, kUrgAngleMin, kUrgIncrement, scans[s], 100.0F);
    octomap::Pointcloud cloud;
    for (int i = 0; i < kUrgBeams; ++i) {
      const double r = scans[s][i];
      if (r == 0.0) continue;
      const double a = double{kUrgAngleMin} + i * double{kUrgIncrement};
      cloud.push_back(to_octo(X_WS.transform * Eigen::Vector3d{r * std::cos(a), r * std::sin(a), 0.0}));
    }
    plain.insertPointCloud(cloud, to_octo(X_WS.translation()), params.max_range_m);
  }
  const auto snapshot = model.publish();
  plain.prune();
  const std::vector<LeafTuple> fast = leaves_of(*snapshot);
  const std::vector<LeafTuple> reference = leaves_of(plain);
  EXPECT_GT(reference.size(), 10000U);
  EXPECT_EQ(fast.size(), reference.size());
  EXPECT_EQ(count_differences(fast, reference), 0U);
  EXPECT_EQ(count_differences(reference, fast), 0U);
  EXPECT_EQ(snapshot->node_count(), plain.size());
}

TEST(OctoMapInsertTest, LazyCloudInsertionEqualsPlainOnRoomScanButDiscretizeDoesNot) {
  REQUIRE_DATASET(kDatasets / "pcl-scans" / "room_scan1.pcd");
  const std::vector<Eigen::Vector3f> points_S = read_pcd_points(kDatasets / "pcl-scans" / "room_scan1.pcd");
  ASSERT_GT(points_S.size(), 100000U);
  const Pose3 X_WS = Pose3::from_xyz_rpy(0.3, -0.2, 1.1, 0.05, 0.1, 0.7);
  const OctoMapParams params = unfiltered();
  OctoMapModel model{params};
  model.insert_cloud(X_WS, points_S);

  octomap::Pointcloud cloud_W;
  const Eigen::Isometry3f X_WS_f = X_WS.transform.cast<float>();
  for (const Eigen::Vector3f& p_S : points_S) {
    if (!p_S.allFinite()) continue;
    const Eigen::Vector3f p_W = X_WS_f * p_S;
    cloud_W.push_back(p_W.x(), p_W.y(), p_W.z());
  }
  octomap::OcTree plain = plain_tree(params);
  plain.insertPointCloud(cloud_W, to_octo(X_WS.translation()), params.max_range_m);
  plain.prune();
  const std::vector<LeafTuple> reference = leaves_of(plain);
  const std::vector<LeafTuple> fast = leaves_of(*model.publish());
  EXPECT_EQ(fast.size(), reference.size());
  EXPECT_EQ(count_differences(fast, reference), 0U);
  EXPECT_EQ(count_differences(reference, fast), 0U);

  // OctoMap's discretize option (computeDiscreteUpdate) shoots the free rays at voxel centres: not the same map.
  OctoMapParams discrete_params = params;
  discrete_params.discretize_endpoints = true;
  OctoMapModel discrete{discrete_params};
  discrete.insert_cloud(X_WS, points_S);
  const std::vector<LeafTuple> discrete_leaves = leaves_of(*discrete.publish());
  const std::size_t differing = count_differences(discrete_leaves, reference);
  std::cout << "[ info     ] discretize_endpoints: " << differing << " of " << discrete_leaves.size()
            << " leaves differ from the plain path\n";
  RecordProperty("discretize_differing_leaves", static_cast<int>(differing));
  EXPECT_GT(differing, 0U);
}

// The same rays through OctoMapModel::insert_cloud and through plain insertPointCloud, batch by batch, publishing
// (inner refresh and prune) every few batches so that later batches meet pruned nodes, some already clamped; the
// leaves must stay identical throughout.
// Inserts the clouds into the model and into a plain OcTree, publishing every publish_every batches: each snapshot
// holds the plain tree's leaves and node count. Every snapshot is kept to the end and checked again then: a snapshot
// shares the blocks no later batch changed with the snapshots after it, and must not see those batches.
void expect_same_map_over_batches(const OctoMapParams& params, const std::vector<std::vector<Eigen::Vector3f>>& clouds,
                                  const std::vector<Pose3>& poses, int publish_every) {
  OctoMapModel model{params};
  octomap::OcTree plain = plain_tree(params);
  std::vector<std::pair<std::shared_ptr<const OctoMapSnapshot>, std::vector<LeafTuple>>> kept;
  for (std::size_t b = 0; b < clouds.size(); ++b) {
    const Pose3& X_WS = poses[b % poses.size()];
    model.insert_cloud(X_WS, clouds[b]);
    octomap::Pointcloud cloud_W;
    const Eigen::Isometry3f X_WS_f = X_WS.transform.cast<float>();
    for (const Eigen::Vector3f& p_S : clouds[b]) {
      const Eigen::Vector3f p_W = X_WS_f * p_S;
      cloud_W.push_back(p_W.x(), p_W.y(), p_W.z());
    }
    plain.insertPointCloud(cloud_W, to_octo(X_WS.translation()), params.max_range_m);
    if (static_cast<int>(b % static_cast<std::size_t>(publish_every)) == publish_every - 1 || b + 1 == clouds.size()) {
      const auto snapshot = model.publish();
      plain.prune();
      const std::vector<LeafTuple> fast = leaves_of(*snapshot);
      std::vector<LeafTuple> reference = leaves_of(plain);
      ASSERT_EQ(fast.size(), reference.size()) << "after batch " << b;
      ASSERT_EQ(count_differences(fast, reference), 0U) << "after batch " << b;
      ASSERT_EQ(snapshot->node_count(), plain.size()) << "after batch " << b;
      ASSERT_EQ(snapshot->leaf_count(), reference.size()) << "after batch " << b;
      kept.emplace_back(snapshot, std::move(reference));
    }
  }
  for (std::size_t i = 0; i < kept.size(); ++i) {
    // Dropped oldest first, so that the blocks they shared outlive them in the later snapshots.
    const auto& [snapshot, reference] = kept[i];
    ASSERT_EQ(count_differences(leaves_of(*snapshot), reference), 0U) << "snapshot " << i << " at the end";
    kept[i].first.reset();
  }
}

// Per batch, the number of hit keys that are also free keys of another ray, of free keys crossed by more than one ray
// and of rays cut at max_range: the cases the deduplication must get right, counted to show the data has them.
struct BatchCases {
  std::size_t hit_also_free = 0;
  std::size_t shared_free = 0;
  std::size_t max_range_rays = 0;
};

BatchCases count_cases(const OctoMapParams& params, const std::vector<std::vector<Eigen::Vector3f>>& clouds,
                       const std::vector<Pose3>& poses) {
  BatchCases cases;
  const octomap::OcTree tree = plain_tree(params);
  octomap::KeyRay ray;
  for (std::size_t b = 0; b < clouds.size(); ++b) {
    const Pose3& X_WS = poses[b % poses.size()];
    const octomap::point3d origin = to_octo(X_WS.translation());
    octomap::KeySet free, hits, seen;
    for (const Eigen::Vector3f& p_S : clouds[b]) {
      const Eigen::Vector3f p_W = X_WS.transform.cast<float>() * p_S;
      octomap::point3d end{p_W.x(), p_W.y(), p_W.z()};
      const bool hit = (end - origin).norm() <= params.max_range_m;
      if (!hit) {
        end = origin + (end - origin).normalized() * static_cast<float>(params.max_range_m);
        ++cases.max_range_rays;
      }
      if (tree.computeRayKeys(origin, end, ray)) {
        for (const octomap::OcTreeKey& key : ray) {
          if (!free.insert(key).second && seen.insert(key).second) ++cases.shared_free;
        }
      }
      octomap::OcTreeKey key;
      if (hit && tree.coordToKeyChecked(end, key)) hits.insert(key);
    }
    for (const octomap::OcTreeKey& key : hits) cases.hit_also_free += free.count(key);
  }
  return cases;
}

// Dense planar batches (OctoMapModel deduplicates them with a bitmap over their bounding box): URG scans as clouds,
// from three poses in turn so that voxels clamp, with a 2.5 m max_range cutting the longer beams.
TEST(OctoMapInsertTest, LazyInsertionEqualsPlainOverManyBatchesWithPruningClampingAndMaxRange) {
  REQUIRE_DATASET(kDatasets / "urg04lx-mines" / "exp1.dat");
  const std::vector<std::vector<float>> scans = read_urg_scans(100, 159);
  OctoMapParams params = unfiltered();
  params.max_range_m = 2.5;
  std::vector<std::vector<Eigen::Vector3f>> clouds;
  for (const std::vector<float>& ranges : scans) {
    std::vector<Eigen::Vector3f>& cloud = clouds.emplace_back();
    for (int i = 0; i < kUrgBeams; ++i) {
      if (ranges[i] == 0.0F) continue;
      const double a = double{kUrgAngleMin} + i * double{kUrgIncrement};
      cloud.emplace_back(static_cast<float>(double{ranges[i]} * std::cos(a)),
                         static_cast<float>(double{ranges[i]} * std::sin(a)), 0.0F);
    }
  }
  const std::vector<Pose3> poses{Pose3::from_xyz_rpy(0.0, 0.0, 0.3, 0.0, 0.05, 0.0),
                                 Pose3::from_xyz_rpy(0.4, -0.3, 0.3, 0.02, -0.03, 0.5),
                                 Pose3::from_xyz_rpy(-0.2, 0.5, 0.2, 0.0, 0.0, -0.8)};
  const BatchCases cases = count_cases(params, clouds, poses);
  std::cout << "[ info     ] " << cases.hit_also_free << " hit keys also free in their batch, " << cases.shared_free
            << " free keys shared by several rays, " << cases.max_range_rays << " max-range rays\n";
  EXPECT_GT(cases.hit_also_free, 0U);
  EXPECT_GT(cases.shared_free, 0U);
  EXPECT_GT(cases.max_range_rays, 0U);
  expect_same_map_over_batches(params, clouds, poses, 7);
  expect_same_map_over_batches(params, clouds, poses, 1);
}

// Sparse 3D batches (OctoMapModel sorts their Morton-coded keys): a few hundred rays in random directions, some
// beyond max_range, some end points on a shared grid so that hits coincide with other rays' free voxels.
TEST(OctoMapInsertTest, LazyInsertionEqualsPlainOnSparse3dBatches) {
  OctoMapParams params = unfiltered();
  params.max_range_m = 8.0;
  std::uint32_t state = 12345U;
  const auto uniform = [&state] {
    state = state * 1664525U + 1013904223U;
    return static_cast<float>(state >> 8) / static_cast<float>(1U << 24);
  };
  std::vector<std::vector<Eigen::Vector3f>> clouds;
  for (int b = 0; b < 12; ++b) {
    std::vector<Eigen::Vector3f>& cloud = clouds.emplace_back();
    for (int i = 0; i < 200; ++i) {
      Eigen::Vector3f d{uniform() - 0.5F, uniform() - 0.5F, uniform() - 0.5F};
      if (d.norm() < 1e-3F) continue;
      const float r = 0.5F + 10.0F * uniform();
      Eigen::Vector3f p = d.normalized() * r;
      if (i % 3 == 0) p = (p / 0.25F).array().round().matrix() * 0.25F;  // on a 25 cm grid: shared voxels
      cloud.push_back(p);
    }
  }
  const std::vector<Pose3> poses{Pose3::from_xyz_rpy(0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
                                 Pose3::from_xyz_rpy(1.0, 0.5, -0.3, 0.1, 0.2, 0.3)};
  const BatchCases cases = count_cases(params, clouds, poses);
  EXPECT_GT(cases.hit_also_free, 0U);
  EXPECT_GT(cases.shared_free, 0U);
  EXPECT_GT(cases.max_range_rays, 0U);
  expect_same_map_over_batches(params, clouds, poses, 4);
}

TEST(OctoMapInsertTest, BtRoundTripPreservesEveryLeaf) {
  REQUIRE_DATASET(kDatasets / "urg04lx-mines" / "exp1.dat");
  OctoMapModel model{unfiltered()};
  const std::vector<std::vector<float>> scans = read_urg_scans(500, 509);
  for (std::size_t s = 0; s < scans.size(); ++s) {
    model.insert_scan(Pose3::from_xyz_rpy(0.02 * static_cast<double>(s), 0.0, 0.3, 0.0, 0.1, 0.0), kUrgAngleMin,
                      kUrgIncrement, scans[s], 100.0F);
  }
  const std::filesystem::path path = std::filesystem::path(testing::TempDir()) / "octomap_round_trip.bt";
  model.save_bt(path);
  OctoMapModel loaded{unfiltered()};
  loaded.load_bt(path);
  std::filesystem::remove(path);

  // .bt stores each leaf's maximum-likelihood state (occupied or free), not its probability.
  const auto original = model.publish();
  const auto copy = loaded.publish();
  const double threshold = model.params().occupancy_threshold;
  std::vector<std::tuple<double, double, double, double, bool>> a, b;
  original->for_each_leaf([&](const OctoVoxel& v) {
    a.emplace_back(v.size_m, v.center_W.x(), v.center_W.y(), v.center_W.z(), v.probability >= threshold);
  });
  copy->for_each_leaf([&](const OctoVoxel& v) {
    b.emplace_back(v.size_m, v.center_W.x(), v.center_W.y(), v.center_W.z(), v.probability >= threshold);
  });
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  EXPECT_GT(a.size(), 1000U);
  EXPECT_EQ(a, b);
  EXPECT_EQ(loaded.params().resolution_m, model.params().resolution_m);
  EXPECT_THROW(loaded.load_bt(path), std::runtime_error);  // gone now
}

TEST(OctoMapInsertTest, Geb079LoadsWithOctomapsReaderAndKeepsItsNodeCount) {
  const std::filesystem::path path = kDatasets / "octomap-samples" / "geb079.bt";
  REQUIRE_DATASET(path);
  octomap::OcTree reference(0.1);
  ASSERT_TRUE(reference.readBinary(path.string()));
  EXPECT_EQ(reference.size(), 532566U);  // as SOURCE.txt states

  OctoMapModel model{OctoMapParams{}};
  model.load_bt(path);
  EXPECT_DOUBLE_EQ(model.params().resolution_m, 0.08);
  const auto snapshot = model.publish();
  EXPECT_EQ(snapshot->node_count(), 532566U);
  EXPECT_EQ(snapshot->leaf_count(), reference.getNumLeafNodes());
  // And our writer produces a file OctoMap's reader takes back with the same nodes.
  const std::filesystem::path copy = std::filesystem::path(testing::TempDir()) / "geb079_copy.bt";
  model.save_bt(copy);
  octomap::OcTree reread(0.1);
  ASSERT_TRUE(reread.readBinary(copy.string()));
  std::filesystem::remove(copy);
  EXPECT_EQ(reread.size(), 532566U);
}

TEST(OctoMapInsertTest, RoomScanOccupiedVoxelsLieNextToCloudPoints) {
  const std::filesystem::path path = kDatasets / "pcl-scans" / "room_scan1.pcd";
  REQUIRE_DATASET(path);
  OctoMapModel model{OctoMapParams{}};  // voxel grid and outlier removal on
  const std::size_t inserted = model.import_pcd(path, Pose3{});
  const std::vector<Eigen::Vector3f> raw = read_pcd_points(path);
  EXPECT_LT(inserted, raw.size());
  const auto snapshot = model.publish();
  const double res = snapshot->resolution();

  // Integer voxel coordinates of every raw point (the octree's grid: voxel i covers [i res, (i + 1) res)).
  const auto key = [res](double x, double y, double z) {
    return std::array<long, 3>{static_cast<long>(std::floor(x / res)), static_cast<long>(std::floor(y / res)),
                               static_cast<long>(std::floor(z / res))};
  };
  struct KeyHash {
    std::size_t operator()(const std::array<long, 3>& k) const {
      return static_cast<std::size_t>(k[0] * 73856093L ^ k[1] * 19349663L ^ k[2] * 83492791L);
    }
  };
  std::unordered_set<std::array<long, 3>, KeyHash> raw_keys;
  for (const Eigen::Vector3f& p : raw) {
    if (p.allFinite()) raw_keys.insert(key(p.x(), p.y(), p.z()));
  }

  const auto occupied = snapshot->occupied_in_box(Eigen::Vector3d::Constant(-100), Eigen::Vector3d::Constant(100));
  ASSERT_GT(occupied.size(), 1000U);
  std::unordered_set<std::array<long, 3>, KeyHash> occupied_keys;
  std::size_t far = 0;
  for (const OctoVoxel& v : occupied) {
    // A pruned leaf (eight equal children, recursively) stands for n^3 voxels of the resolution.
    const long n = std::lround(v.size_m / res);
    for (long i = 0; i < n * n * n; ++i) {
      const Eigen::Vector3d offset = res * (Eigen::Vector3d(static_cast<double>(i % n), static_cast<double>(i / n % n),
                                                            static_cast<double>(i / (n * n))) -
                                            Eigen::Vector3d::Constant((static_cast<double>(n) - 1.0) / 2.0));
      const Eigen::Vector3d c = v.center_W + offset;
      const auto k = key(c.x(), c.y(), c.z());
      occupied_keys.insert(k);
      bool near = false;
      for (long dx = -1; dx <= 1 && !near; ++dx) {
        for (long dy = -1; dy <= 1 && !near; ++dy) {
          for (long dz = -1; dz <= 1 && !near; ++dz) near = raw_keys.count({k[0] + dx, k[1] + dy, k[2] + dz}) != 0;
        }
      }
      if (!near) ++far;
    }
  }
  EXPECT_EQ(far, 0U) << "occupied voxels with no cloud point in them or their 26 neighbours";

  std::size_t in_occupied = 0, finite = 0;
  for (const Eigen::Vector3f& p : raw) {
    if (!p.allFinite()) continue;
    ++finite;
    if (occupied_keys.count(key(p.x(), p.y(), p.z())) != 0) ++in_occupied;
  }
  const double fraction = static_cast<double>(in_occupied) / static_cast<double>(finite);
  std::cout << "[ info     ] room_scan1: " << finite << " points, " << inserted << " after filters, " << occupied.size()
            << " occupied voxels; " << 100.0 * fraction << "% of the points lie in an occupied voxel\n";
  RecordProperty("room_scan1_points_in_occupied_percent", static_cast<int>(std::lround(100.0 * fraction)));
  EXPECT_GT(fraction, 0.8);
}

TEST(OctoMapInsertTest, OrganizedKinectFrameWithNaNsInserts) {
  const std::filesystem::path path = kDatasets / "pcl-scans" / "frame_20121214T142255.814212.pcd";
  REQUIRE_DATASET(path);
  const std::vector<Eigen::Vector3f> raw = read_pcd_points(path);
  ASSERT_EQ(raw.size(), 640U * 480U);
  const auto finite = static_cast<std::size_t>(
      std::count_if(raw.begin(), raw.end(), [](const Eigen::Vector3f& p) { return p.allFinite(); }));
  EXPECT_LT(finite, raw.size());  // the frame does have invalid pixels
  ASSERT_GT(finite, 0U);

  for (const bool filters : {false, true}) {
    OctoMapParams params;
    params.voxel_filter_enabled = filters;
    params.outlier_filter_enabled = filters;
    OctoMapModel model{params};
    const std::size_t inserted = model.import_pcd(path, Pose3{});
    if (filters) {
      EXPECT_LT(inserted, finite);
    } else {
      EXPECT_EQ(inserted, finite);
    }
    const auto snapshot = model.publish();
    std::size_t leaves = 0;
    bool all_finite = true;
    snapshot->for_each_leaf([&](const OctoVoxel& v) {
      ++leaves;
      all_finite = all_finite && v.center_W.allFinite() && std::isfinite(v.probability);
    });
    EXPECT_TRUE(all_finite);
    EXPECT_GT(leaves, 1000U);
    // The sensor looks along +z: everything it marked lies in front of it.
    const auto occupied = snapshot->occupied_in_box(Eigen::Vector3d::Constant(-100), Eigen::Vector3d::Constant(100));
    EXPECT_GT(occupied.size(), 100U);
    for (const OctoVoxel& v : occupied) ASSERT_GT(v.center_W.z(), 0.0);
  }
}

}  // namespace
}  // namespace occgeo::mapping
