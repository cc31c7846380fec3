// Collision checks and clearance queries per second for the Bearcat box footprint (1.0 x 0.8 x 1.0 m) and, for
// comparison, a cylinder of the same width, on a 20 x 20 m map of 0.1 m cells: walls around the edge and across the
// middle plus ~5% random occupied cells. Poses are pre-generated, uniform over the map's interior.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <vector>

#include "occgeo/geometry/collision.h"
#include "occgeo/mapping/himm_grid.h"

namespace occgeo::geometry {
namespace {

constexpr double kCellSize_m = 0.1;
constexpr int kCellsPerSide = 200;

// A dense occupancy bitmap over cells [0, kCellsPerSide)^2, like one tile of the HIMM grid's snapshot.
class DenseCellSource : public OccupiedCellSource {
 public:
  DenseCellSource() : occupied_(kCellsPerSide * kCellsPerSide, 0) {}

  void set(int ix, int iy) { occupied_[static_cast<std::size_t>(iy * kCellsPerSide + ix)] = 1; }

  double cell_size() const override { return kCellSize_m; }
  void for_each_occupied(CellIndex min, CellIndex max,
                         const std::function<bool(const CellIndex&)>& visit) const override {
    const std::int32_t x0 = std::max(min.ix, 0), x1 = std::min(max.ix, kCellsPerSide - 1);
    const std::int32_t y0 = std::max(min.iy, 0), y1 = std::min(max.iy, kCellsPerSide - 1);
    for (std::int32_t iy = y0; iy <= y1; ++iy) {
      const std::uint8_t* row = &occupied_[static_cast<std::size_t>(iy * kCellsPerSide)];
      for (std::int32_t ix = x0; ix <= x1; ++ix) {
        if (row[ix] != 0 && !visit({ix, iy})) return;
      }
    }
  }

 private:
  std::vector<std::uint8_t> occupied_;
};

const DenseCellSource& bench_map() {
  static const DenseCellSource map = [] {
    DenseCellSource m;
    std::mt19937 rng(42);
    std::bernoulli_distribution occupied(0.05);
    for (int iy = 0; iy < kCellsPerSide; ++iy) {
      for (int ix = 0; ix < kCellsPerSide; ++ix) {
        const bool border = ix == 0 || iy == 0 || ix == kCellsPerSide - 1 || iy == kCellsPerSide - 1;
        const bool inner_wall = (ix == 100 && iy < 140) || (iy == 60 && ix > 40);
        if (border || inner_wall || occupied(rng)) m.set(ix, iy);
      }
    }
    return m;
  }();
  return map;
}

// The same map as the server holds it: a HIMM grid snapshot (tiles, copy-on-write), restored from an image of
// the dense map, so the two sources can be compared side by side in one run.
const occgeo::mapping::GridSnapshot& bench_snapshot() {
  static const std::shared_ptr<const occgeo::mapping::GridSnapshot> snapshot = [] {
    occgeo::mapfile::OccupancyImage image;
    image.width = kCellsPerSide;
    image.height = kCellsPerSide;
    image.resolution = kCellSize_m;
    image.pixels.assign(static_cast<std::size_t>(kCellsPerSide) * kCellsPerSide, 254);
    const DenseCellSource& dense = bench_map();
    dense.for_each_occupied({0, 0}, {kCellsPerSide - 1, kCellsPerSide - 1}, [&](const CellIndex& c) {
      image
          .pixels[static_cast<std::size_t>(kCellsPerSide - 1 - c.iy) * kCellsPerSide + static_cast<std::size_t>(c.ix)] =
          0;
      return true;
    });
    return occgeo::mapping::HimmGrid::from_image(image, occgeo::mapping::HimmParams{}).snapshot();
  }();
  return *snapshot;
}

const Footprint kBearcat = BoxFootprint{1.0, 0.8, 1.0, 0.0};
const Footprint kCylinder = CylinderFootprint{0.4, 1.0};
// The Bearcat's box as a polygon (the cost of the general path against the box's), and an octagon of 0.45 m radius.
const Footprint kBearcatPolygon =
    occgeo::geometry::ConvexPolygonFootprint{{{-0.5, -0.4}, {0.5, -0.4}, {0.5, 0.4}, {-0.5, 0.4}}, 1.0};
const Footprint kOctagon = [] {
  occgeo::geometry::ConvexPolygonFootprint octagon{{}, 1.0};
  for (int k = 0; k < 8; ++k) {
    octagon.vertices_B.emplace_back(0.45 * std::cos(k * M_PI / 4), 0.45 * std::sin(k * M_PI / 4));
  }
  return Footprint{octagon};
}();

// Which poses a benchmark cycles through: uniform over the map (at 5% density almost all collide, and a check stops
// at the first cell in contact), or only collision-free ones (every candidate cell is examined: the worst case).
enum class Poses { kUniform, kCollisionFree };

std::vector<Pose2> make_poses(const Footprint& footprint, Poses kind) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> position(1.0, kCellsPerSide * kCellSize_m - 1.0);
  std::uniform_real_distribution<double> heading(-M_PI, M_PI);
  std::vector<Pose2> poses;
  while (poses.size() < 2048) {
    const Pose2 pose{position(rng), position(rng), heading(rng)};
    if (kind == Poses::kUniform || !check_collision({footprint, pose}, bench_map()).hit) poses.push_back(pose);
  }
  return poses;
}

void report_rates(benchmark::State& state) {
  const auto queries = static_cast<double>(state.iterations());
  state.counters["queries/s"] = benchmark::Counter(queries, benchmark::Counter::kIsRate);
  state.counters["s/query"] = benchmark::Counter(queries, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_CheckCollision(benchmark::State& state, const Footprint& footprint, Poses kind, bool on_snapshot = false) {
  const OccupiedCellSource& map = on_snapshot ? static_cast<const OccupiedCellSource&>(bench_snapshot()) : bench_map();
  const std::vector<Pose2> poses = make_poses(footprint, kind);
  std::size_t next = 0;
  double hits = 0.0, cells_tested = 0.0;
  for (auto _ : state) {
    const CollisionResult result = check_collision({footprint, poses[next]}, map);
    benchmark::DoNotOptimize(result);
    hits += result.hit;
    cells_tested += result.cells_tested;
    next = (next + 1) % poses.size();
  }
  report_rates(state);
  state.counters["hit_fraction"] = benchmark::Counter(hits, benchmark::Counter::kAvgIterations);
  state.counters["cells_tested"] = benchmark::Counter(cells_tested, benchmark::Counter::kAvgIterations);
}

void BM_ComputeClearance(benchmark::State& state, const Footprint& footprint, Poses kind, bool on_snapshot = false) {
  const OccupiedCellSource& map = on_snapshot ? static_cast<const OccupiedCellSource&>(bench_snapshot()) : bench_map();
  const std::vector<Pose2> poses = make_poses(footprint, kind);
  std::size_t next = 0;
  double clearance_sum = 0.0;
  for (auto _ : state) {
    const ClearanceResult result = compute_clearance({footprint, poses[next], 5.0}, map);
    benchmark::DoNotOptimize(result);
    clearance_sum += result.clearance_m;
    next = (next + 1) % poses.size();
  }
  report_rates(state);
  state.counters["mean_clearance_m"] = benchmark::Counter(clearance_sum, benchmark::Counter::kAvgIterations);
}

// The cell source alone: visiting the occupied cells of the Bearcat's world AABB at collision-free poses with a
// trivial visitor, the floor under BM_CheckCollision/bearcat_free.
void BM_SourceScanOfFootprintAabb(benchmark::State& state) {
  const DenseCellSource& map = bench_map();
  const std::vector<Pose2> poses = make_poses(kBearcat, Poses::kCollisionFree);
  std::size_t next = 0;
  int visited = 0;
  const std::function<bool(const CellIndex&)> count = [&visited](const CellIndex&) {
    ++visited;
    return true;
  };
  for (auto _ : state) {
    const Pose2& pose = poses[next];
    const double c = std::abs(std::cos(pose.theta)), s = std::abs(std::sin(pose.theta));
    const double ex = 0.5 * c + 0.4 * s, ey = 0.5 * s + 0.4 * c;
    map.for_each_occupied({static_cast<std::int32_t>(std::floor((pose.x - ex) / kCellSize_m)),
                           static_cast<std::int32_t>(std::floor((pose.y - ey) / kCellSize_m))},
                          {static_cast<std::int32_t>(std::floor((pose.x + ex) / kCellSize_m)),
                           static_cast<std::int32_t>(std::floor((pose.y + ey) / kCellSize_m))},
                          count);
    benchmark::DoNotOptimize(visited);
    next = (next + 1) % poses.size();
  }
  report_rates(state);
}

BENCHMARK_CAPTURE(BM_CheckCollision, bearcat_uniform, kBearcat, Poses::kUniform);
BENCHMARK_CAPTURE(BM_CheckCollision, bearcat_free, kBearcat, Poses::kCollisionFree);
BENCHMARK_CAPTURE(BM_CheckCollision, cylinder_free, kCylinder, Poses::kCollisionFree);
BENCHMARK_CAPTURE(BM_CheckCollision, bearcat_polygon_free, kBearcatPolygon, Poses::kCollisionFree);
BENCHMARK_CAPTURE(BM_CheckCollision, octagon_free, kOctagon, Poses::kCollisionFree);
BENCHMARK_CAPTURE(BM_ComputeClearance, bearcat_uniform, kBearcat, Poses::kUniform);
BENCHMARK_CAPTURE(BM_ComputeClearance, bearcat_free, kBearcat, Poses::kCollisionFree);
BENCHMARK_CAPTURE(BM_ComputeClearance, cylinder_free, kCylinder, Poses::kCollisionFree);
BENCHMARK_CAPTURE(BM_ComputeClearance, bearcat_polygon_free, kBearcatPolygon, Poses::kCollisionFree);
BENCHMARK_CAPTURE(BM_ComputeClearance, octagon_free, kOctagon, Poses::kCollisionFree);
BENCHMARK(BM_SourceScanOfFootprintAabb);
BENCHMARK_CAPTURE(BM_CheckCollision, bearcat_free_on_grid_snapshot, kBearcat, Poses::kCollisionFree, true);
BENCHMARK_CAPTURE(BM_ComputeClearance, bearcat_free_on_grid_snapshot, kBearcat, Poses::kCollisionFree, true);

}  // namespace
}  // namespace occgeo::geometry

BENCHMARK_MAIN();
