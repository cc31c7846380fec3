// OctoMap model costs: insertion of a real URG-04LX scan (682 beams, 240°) through OctoMapModel (lazy inner-node
// update) against OctoMap's plain insertPointCloud, snapshot publish (a deep copy of the tree) and FCL collision of a
// box footprint. Before the benchmarks, main() times both insertion paths in one run, prints their ratio, and checks
// that they build the same map (every leaf's probability), saying so when they do not.

#include <benchmark/benchmark.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numbers>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "occgeo/mapping/octomap_model.h"

namespace occgeo::mapping {
namespace {

using geometry::Pose3;

const std::filesystem::path kDatasets = std::filesystem::path(OCCGEO_SOURCE_DIR) / ".." / "shared" / "datasets";

constexpr int kBeams = 682;
constexpr float kIncrement = static_cast<float>(2.0 * std::numbers::pi / 1024.0);
constexpr float kAngleMin = -kIncrement * (kBeams - 1) / 2;
constexpr float kRangeMax = 100.0F;  // every URG reading (<= 5.6 m) counts as a hit
constexpr int kWantedLine = 1000;

// Where the scan came from, for the printout.
std::string g_scan_source;

// Ranges of the URG-04LX scan on line kWantedLine of exp1.dat; the file has only 756 lines, so its last scan is used
// when line 1000 does not exist; a synthetic 10 x 10 m room seen from its centre when the file is absent.
std::vector<float> load_scan() {
  std::ifstream in(kDatasets / "urg04lx-mines" / "exp1.dat");
  std::string line, last;
  int n = 0;
  while (n < kWantedLine && std::getline(in, line)) {
    last = line;
    ++n;
  }
  std::vector<float> ranges;
  if (!last.empty()) {
    std::istringstream fields(last);
    std::vector<double> values;
    for (double v = 0; fields >> v;) values.push_back(v);
    if (values.size() >= 24 + kBeams) {
      for (int i = 0; i < kBeams; ++i) ranges.push_back(static_cast<float>(values[24 + i] / 1000.0));
      g_scan_source = "exp1.dat line " + std::to_string(n) + (n < kWantedLine ? " (the last; line 1000 absent)" : "");
      return ranges;
    }
  }
  g_scan_source = "synthetic 10 x 10 m room (exp1.dat absent)";
  for (int i = 0; i < kBeams; ++i) {
    const double a = double{kAngleMin} + i * double{kIncrement};
    const double c = std::abs(std::cos(a)), s = std::abs(std::sin(a));
    ranges.push_back(static_cast<float>(std::min(c > 1e-9 ? 5.0 / c : 1e9, s > 1e-9 ? 5.0 / s : 1e9)));
  }
  return ranges;
}

const std::vector<float>& scan() {
  static const std::vector<float> ranges = load_scan();
  return ranges;
}

// The laser 0.3 m up and pitched 3° down: rays through 3D voxels, as on a real robot.
const Pose3 kX_WS = Pose3::from_xyz_rpy(0.0, 0.0, 0.3, 0.0, 0.05, 0.0);

OctoMapParams bench_params() {
  OctoMapParams params;
  params.voxel_filter_enabled = false;
  params.outlier_filter_enabled = false;
  params.min_publish_interval_s = 0.0;
  // Plain OctoMap's update rule, so that the model's map can be compared leaf by leaf with insertPointCloud's (the
  // see-through rule is a deliberate difference: octomap_insert_test checks it apart).
  params.laser_see_through_clears = false;
  return params;
}

octomap::point3d to_octo(const Eigen::Vector3d& p) {
  return {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())};
}

// The scan's end points in the world, computed exactly as OctoMapModel::insert_scan does.
octomap::Pointcloud scan_cloud(const Pose3& X_WS) {
  octomap::Pointcloud cloud;
  for (int i = 0; i < kBeams; ++i) {
    const double r = scan()[i];
    if (r == 0.0) continue;
    const double a = double{kAngleMin} + i * double{kIncrement};
    cloud.push_back(to_octo(X_WS.transform * Eigen::Vector3d{r * std::cos(a), r * std::sin(a), 0.0}));
  }
  return cloud;
}

std::unique_ptr<octomap::OcTree> plain_tree() {
  const OctoMapParams params = bench_params();
  auto tree = std::make_unique<octomap::OcTree>(params.resolution_m);
  tree->setProbHit(params.prob_hit);
  tree->setProbMiss(params.prob_miss);
  tree->setClampingThresMin(params.clamping_min);
  tree->setClampingThresMax(params.clamping_max);
  tree->setOccupancyThres(params.occupancy_threshold);
  return tree;
}

// Pose of scan k of a sequence: the laser drifting 2 cm and turning 1° per scan, so successive scans touch new voxels.
Pose3 sequence_pose(int k) {
  return Pose3{kX_WS.transform * Pose3::from_xyz_rpy(0.02 * k, 0.0, 0.0, 0.0, 0.0, 0.0175 * k).transform};
}

void BM_InsertScanPlainInsertPointCloud(benchmark::State& state) {
  const std::unique_ptr<octomap::OcTree> tree = plain_tree();
  const double max_range = bench_params().max_range_m;
  std::vector<octomap::Pointcloud> clouds;
  for (int k = 0; k < 64; ++k) clouds.push_back(scan_cloud(sequence_pose(k)));
  int k = 0;
  for (auto _ : state) {
    tree->insertPointCloud(clouds[k % 64], to_octo(sequence_pose(k % 64).translation()), max_range);
    ++k;
  }
  state.SetLabel(g_scan_source);
}
BENCHMARK(BM_InsertScanPlainInsertPointCloud)->Unit(benchmark::kMicrosecond);

void BM_InsertScanOctoMapModel(benchmark::State& state) {
  OctoMapModel model{bench_params()};
  int k = 0;
  for (auto _ : state) {
    model.insert_scan(sequence_pose(k % 64), kAngleMin, kIncrement, scan(), kRangeMax);
    ++k;
  }
  state.SetLabel(g_scan_source);
}
BENCHMARK(BM_InsertScanOctoMapModel)->Unit(benchmark::kMicrosecond);

// A scan followed by a publish, as when the server publishes after every scan (min_publish_interval_s = 0): the
// inner-node refresh, pruning and the deep copy of a room-sized map.
void BM_InsertScanAndPublishEveryScan(benchmark::State& state) {
  OctoMapModel model{bench_params()};
  for (int k = 0; k < 64; ++k) model.insert_scan(sequence_pose(k), kAngleMin, kIncrement, scan(), kRangeMax);
  int k = 0;
  for (auto _ : state) {
    model.insert_scan(sequence_pose(k % 64), kAngleMin, kIncrement, scan(), kRangeMax);
    model.publish();
    ++k;
  }
  state.counters["nodes"] = static_cast<double>(model.snapshot()->node_count());
}
BENCHMARK(BM_InsertScanAndPublishEveryScan)->Unit(benchmark::kMicrosecond);

// Publish cost after one URG scan (timed: the publish alone), on a small map (64 scans) and on a large one
// (geb079.bt, 532k nodes): a publish refreshes and copies the 8-voxel blocks the scan changed, so the cost follows the
// change, not the map. Both take the same 500 scans from poses that move on (a pose seen again changes less, its
// voxels clamped already).
void BM_PublishSnapshot(benchmark::State& state) {
  OctoMapModel model{bench_params()};
  const bool big = state.range(0) == 1;
  if (big) {
    const std::filesystem::path path = kDatasets / "octomap-samples" / "geb079.bt";
    if (!std::filesystem::exists(path)) {
      state.SkipWithError("geb079.bt absent");
      return;
    }
    model.load_bt(path);
  } else {
    for (int k = 0; k < 64; ++k) model.insert_scan(sequence_pose(k), kAngleMin, kIncrement, scan(), kRangeMax);
  }
  model.publish();
  int k = 64;
  for (auto _ : state) {
    state.PauseTiming();
    model.insert_scan(sequence_pose(k++), kAngleMin, kIncrement, scan(), kRangeMax);
    state.ResumeTiming();
    benchmark::DoNotOptimize(model.publish());
  }
  state.counters["nodes"] = static_cast<double>(model.snapshot()->node_count());
  state.SetLabel(big ? "geb079.bt (Freiburg building 079), after one scan" : "64 URG scans, after one scan");
}
BENCHMARK(BM_PublishSnapshot)->Arg(0)->Arg(1)->Iterations(500)->Unit(benchmark::kMicrosecond);

// Collision of a 0.6 x 0.4 x 0.5 m box footprint against a snapshot, at poses sweeping the map: with the snapshot's
// occupied-column broadphase (collide) or FCL's octree walk for every pose (collide_fcl_only).
void collide_box(benchmark::State& state, bool fcl_only) {
  OctoMapModel model{bench_params()};
  const bool big = state.range(0) == 1;
  Eigen::Vector3d lo{-3.0, -3.0, 0.0}, hi{3.0, 3.0, 0.0};
  if (big) {
    const std::filesystem::path path = kDatasets / "octomap-samples" / "geb079.bt";
    if (!std::filesystem::exists(path)) {
      state.SkipWithError("geb079.bt absent");
      return;
    }
    model.load_bt(path);
    lo = {-10.0, -10.0, 0.0};
    hi = {10.0, 10.0, 0.0};
  } else {
    for (int k = 0; k < 64; ++k) model.insert_scan(sequence_pose(k), kAngleMin, kIncrement, scan(), kRangeMax);
  }
  const auto snapshot = model.publish();
  const geometry::BoxFootprint box{0.6, 0.4, 0.5, 0.0};
  std::vector<Pose3> poses;
  for (int i = 0; i < 256; ++i) {
    const double t = i / 255.0;
    poses.push_back(Pose3::from_xyz_rpy(lo.x() + t * (hi.x() - lo.x()),
                                        lo.y() + std::fmod(7.3 * t, 1.0) * (hi.y() - lo.y()), 0.0, 0.0, 0.0, 6.0 * t));
  }
  std::size_t i = 0, hits = 0;
  for (auto _ : state) {
    const Pose3& X_WB = poses[i++ % poses.size()];
    hits += (fcl_only ? snapshot->collide_fcl_only(box, X_WB) : snapshot->collide(box, X_WB)).hit ? 1 : 0;
  }
  state.counters["hit_fraction"] = static_cast<double>(hits) / static_cast<double>(std::max<std::size_t>(i, 1));
  state.SetLabel(big ? "geb079.bt" : "64 URG scans");
}
void BM_CollideBox(benchmark::State& state) { collide_box(state, false); }
BENCHMARK(BM_CollideBox)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);
void BM_CollideBoxFclOnly(benchmark::State& state) { collide_box(state, true); }
BENCHMARK(BM_CollideBoxFclOnly)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// Leaves of a pruned tree as (depth-free key in half voxels, probability), for the same-map check.
using Leaf = std::tuple<long, long, long, long, double>;
Leaf leaf(double size, double x, double y, double z, double p, double res) {
  const double h = res / 2;
  return {std::lround(size / h), std::lround(x / h), std::lround(y / h), std::lround(z / h), p};
}

// Times kScans scans through both paths in this run, prints the ratio, and compares the maps leaf by leaf.
void compare_paths() {
  constexpr int kScans = 200;
  const OctoMapParams params = bench_params();
  std::vector<octomap::Pointcloud> clouds;
  for (int k = 0; k < kScans; ++k) clouds.push_back(scan_cloud(sequence_pose(k)));

  // Best of 5 rounds each, alternating, to damp this shared machine's noise.
  double plain_best = 1e9, model_best = 1e9, refresh_best = 1e9;
  std::unique_ptr<octomap::OcTree> plain;
  std::unique_ptr<OctoMapModel> model;
  for (int round = 0; round < 5; ++round) {
    plain = plain_tree();
    auto t0 = std::chrono::steady_clock::now();
    for (int k = 0; k < kScans; ++k) {
      plain->insertPointCloud(clouds[k], to_octo(sequence_pose(k).translation()), params.max_range_m);
    }
    auto t1 = std::chrono::steady_clock::now();
    plain_best = std::min(plain_best, std::chrono::duration<double, std::milli>(t1 - t0).count());

    model = std::make_unique<OctoMapModel>(params);
    t0 = std::chrono::steady_clock::now();
    for (int k = 0; k < kScans; ++k) model->insert_scan(sequence_pose(k), kAngleMin, kIncrement, scan(), kRangeMax);
    t1 = std::chrono::steady_clock::now();
    model_best = std::min(model_best, std::chrono::duration<double, std::milli>(t1 - t0).count());
    // The once-per-batch inner-node update and prune run in publish, together with the snapshot's deep copy.
    t0 = std::chrono::steady_clock::now();
    model->publish();
    t1 = std::chrono::steady_clock::now();
    refresh_best = std::min(refresh_best, std::chrono::duration<double, std::milli>(t1 - t0).count());
  }
  plain->prune();

  std::vector<Leaf> a, b;
  const double res = params.resolution_m;
  model->snapshot()->for_each_leaf([&](const OctoVoxel& v) {
    a.push_back(leaf(v.size_m, v.center_W.x(), v.center_W.y(), v.center_W.z(), v.probability, res));
  });
  for (auto it = plain->begin_leafs(), end = plain->end_leafs(); it != end; ++it) {
    b.push_back(leaf(it.getSize(), it.getX(), it.getY(), it.getZ(), it->getOccupancy(), res));
  }
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  const bool same = a == b;

  std::printf("OctoMap insertion, %d URG-04LX scans (%d beams, %s), 5 cm, best of 5:\n", kScans, kBeams,
              g_scan_source.c_str());
  std::printf("  plain insertPointCloud      %8.1f us/scan\n", 1000.0 * plain_best / kScans);
  std::printf("  OctoMapModel::insert_scan   %8.1f us/scan  (ratio %.2fx)\n", 1000.0 * model_best / kScans,
              plain_best / model_best);
  std::printf("  + one publish (inner refresh, prune, copy) %.1f us for the batch -> %.1f us/scan (ratio %.2fx)\n",
              1000.0 * refresh_best, 1000.0 * (model_best + refresh_best) / kScans,
              plain_best / (model_best + refresh_best));
  std::printf("  same map: %s (%zu leaves vs %zu)\n", same ? "yes, every leaf's probability equal" : "NO — maps differ",
              a.size(), b.size());
}

}  // namespace
}  // namespace occgeo::mapping

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  occgeo::mapping::compare_paths();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
