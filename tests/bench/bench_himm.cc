// HIMM ingest cost of SICK LMS200 scans (181 beams over 180 degrees, 1 degree apart, 8 m max range) in a 20 x 20 m
// room with boxes, with and without the snapshot the server takes after every scan.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <memory>
#include <numbers>
#include <vector>

#include "occgeo/mapping/himm_grid.h"

namespace occgeo::mapping {
namespace {

constexpr int kBeams = 181;
constexpr float kAngleMin = -std::numbers::pi_v<float> / 2;
constexpr float kAngleIncrement = std::numbers::pi_v<float> / 180;
constexpr float kRangeMax = 8.0F;

// An axis-aligned box, metres.
struct Box {
  double min_x, min_y, max_x, max_y;
};

// The room's inside and the boxes standing in it.
constexpr Box kRoom{0.0, 0.0, 20.0, 20.0};
constexpr Box kObstacles[] = {{3.0, 3.0, 4.0, 5.0},   {8.0, 12.0, 10.0, 13.0},  {14.0, 4.0, 15.5, 5.5},
                              {5.0, 15.0, 5.6, 17.0}, {16.0, 14.0, 17.0, 18.0}, {11.0, 7.0, 11.4, 7.4}};

// Distances along origin + t * direction at which the ray enters and leaves box (t_enter > t_leave: it misses).
std::pair<double, double> slab_interval(const Box& box, const Eigen::Vector2d& origin,
                                        const Eigen::Vector2d& direction) {
  double t_enter = -std::numeric_limits<double>::infinity();
  double t_leave = std::numeric_limits<double>::infinity();
  const double lows[] = {box.min_x, box.min_y};
  const double highs[] = {box.max_x, box.max_y};
  for (int axis = 0; axis < 2; ++axis) {
    if (direction[axis] == 0.0) {
      if (origin[axis] < lows[axis] || origin[axis] > highs[axis]) return {1.0, 0.0};
      continue;
    }
    const double t0 = (lows[axis] - origin[axis]) / direction[axis];
    const double t1 = (highs[axis] - origin[axis]) / direction[axis];
    t_enter = std::max(t_enter, std::min(t0, t1));
    t_leave = std::min(t_leave, std::max(t0, t1));
  }
  return {t_enter, t_leave};
}

// Range (metres) a perfect sensor at origin measures along direction (unit vector): the nearest box or room wall.
double cast_ray(const Eigen::Vector2d& origin, const Eigen::Vector2d& direction) {
  double range = slab_interval(kRoom, origin, direction).second;
  for (const Box& box : kObstacles) {
    const auto [t_enter, t_leave] = slab_interval(box, origin, direction);
    if (t_enter <= t_leave && t_enter > 0.0) range = std::min(range, t_enter);
  }
  return range;
}

struct Scan {
  geometry::Pose2 X_WS;
  std::vector<float> ranges;
};

// Scans along a loop through the room; the laser sits 0.2 m ahead of the robot centre.
std::vector<Scan> make_scans() {
  const geometry::Pose2 X_BS{0.2, 0.0, 0.0};
  std::vector<Scan> scans;
  constexpr int kPoses = 64;
  for (int i = 0; i < kPoses; ++i) {
    const double phase = 2.0 * std::numbers::pi * i / kPoses;
    const geometry::Pose2 X_WB{10.0 + 6.5 * std::cos(phase), 10.0 + 4.5 * std::sin(phase),
                               phase + std::numbers::pi / 2};
    Scan scan{X_WB.compose(X_BS), std::vector<float>(kBeams)};
    for (int beam = 0; beam < kBeams; ++beam) {
      const double angle =
          scan.X_WS.theta + static_cast<double>(kAngleMin) + beam * static_cast<double>(kAngleIncrement);
      const double range = cast_ray(scan.X_WS.position(), {std::cos(angle), std::sin(angle)});
      scan.ranges[static_cast<std::size_t>(beam)] =
          range >= static_cast<double>(kRangeMax) ? kRangeMax : static_cast<float>(range);
    }
    scans.push_back(std::move(scan));
  }
  return scans;
}

const std::vector<Scan>& scans() {
  static const std::vector<Scan> kScans = make_scans();
  return kScans;
}

// Mean number of cells a scan's beams traverse (the work per scan), at the default 0.1 m cells.
double mean_cells_per_scan() {
  const geometry::GridGeometry grid(HimmParams{}.cell_size_m);
  double cells = 0.0;
  for (const Scan& scan : scans()) {
    const geometry::CellIndex start = grid.cell_of(scan.X_WS.position());
    for (int beam = 0; beam < kBeams; ++beam) {
      const double angle =
          scan.X_WS.theta + static_cast<double>(kAngleMin) + beam * static_cast<double>(kAngleIncrement);
      const double range = static_cast<double>(scan.ranges[static_cast<std::size_t>(beam)]);
      const geometry::CellIndex end =
          grid.cell_of(scan.X_WS.position() + range * Eigen::Vector2d(std::cos(angle), std::sin(angle)));
      cells += std::abs(end.ix - start.ix) + std::abs(end.iy - start.iy) + 1;
    }
  }
  return cells / static_cast<double>(scans().size());
}

// A grid that has already seen every scan once, so tiles exist and certainties are in their steady state.
HimmGrid warmed_up_grid() {
  HimmGrid grid{HimmParams{}};
  for (const Scan& scan : scans()) grid.insert_scan(scan.X_WS, kAngleMin, kAngleIncrement, scan.ranges, kRangeMax);
  return grid;
}

void set_counters(benchmark::State& state) {
  const double scans = static_cast<double>(state.iterations());
  state.counters["scans/s"] = benchmark::Counter(scans, benchmark::Counter::kIsRate);
  state.counters["cells/scan"] = mean_cells_per_scan();
  state.counters["time/cell"] =
      benchmark::Counter(scans * mean_cells_per_scan(), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_InsertScan(benchmark::State& state) {
  HimmGrid grid = warmed_up_grid();
  std::size_t next = 0;
  for (auto _ : state) {
    const Scan& scan = scans()[next++ % scans().size()];
    grid.insert_scan(scan.X_WS, kAngleMin, kAngleIncrement, scan.ranges, kRangeMax);
  }
  set_counters(state);
  state.counters["tiles"] = static_cast<double>(grid.tile_count());
}
BENCHMARK(BM_InsertScan);

// What the server does: ingest, then publish a new snapshot, releasing the previous one.
void BM_InsertScanThenSnapshot(benchmark::State& state) {
  HimmGrid grid = warmed_up_grid();
  std::shared_ptr<const GridSnapshot> published = grid.snapshot();
  const std::uint64_t copied_before = grid.copied_tile_count();
  std::size_t next = 0;
  for (auto _ : state) {
    const Scan& scan = scans()[next++ % scans().size()];
    grid.insert_scan(scan.X_WS, kAngleMin, kAngleIncrement, scan.ranges, kRangeMax);
    published = grid.snapshot();
  }
  benchmark::DoNotOptimize(published);
  set_counters(state);
  state.counters["copied tiles/scan"] =
      static_cast<double>(grid.copied_tile_count() - copied_before) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_InsertScanThenSnapshot);

void BM_Snapshot(benchmark::State& state) {
  const HimmGrid grid = warmed_up_grid();
  for (auto _ : state) benchmark::DoNotOptimize(grid.snapshot());
  state.counters["tiles"] = static_cast<double>(grid.tile_count());
}
BENCHMARK(BM_Snapshot);

}  // namespace
}  // namespace occgeo::mapping

BENCHMARK_MAIN();
