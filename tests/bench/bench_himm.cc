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

#include "bench_room.h"
#include "occgeo/mapping/himm_grid.h"

namespace occgeo::mapping {
namespace {

using bench::kAngleIncrement;
using bench::kAngleMin;
using bench::kBeams;
using bench::kRangeMax;
using bench::Scan;

std::vector<Scan> make_scans() { return bench::make_scans(64, 64); }

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
