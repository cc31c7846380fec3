// Distance field (mapping/distance_field.h) against the alternatives, on the HIMM grid of SICK LMS200 scans (181
// beams, 1 degree apart, 8 m max range) in a 20 x 20 m room with boxes, as in bench_himm.cc:
//  - clearance per query of a 1.0 x 0.8 m box footprint: the field vs geometry::compute_clearance (exact ring search)
//    vs FCL 0.7 box-box distance over the cells near the footprint (GST_INDEP), with ratios printed at the end;
//  - incremental update per scan: the own 2D brushfire vs dynamicEDT3D (one z layer) fed the same changed cells;
//  - incremental update per step of a person walking through the room, both;
//  - full rebuild of the field over the same box, both.

#include <benchmark/benchmark.h>
#include <dynamicEDT3D/dynamicEDT3D.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/narrowphase/distance.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "bench_room.h"
#include "occgeo/geometry/collision.h"
#include "occgeo/mapping/distance_field.h"
#include "occgeo/mapping/himm_grid.h"

namespace occgeo::mapping {
namespace {

using bench::kAngleIncrement;
using bench::kAngleMin;
using bench::kBeams;
using bench::kRangeMax;
using bench::Scan;

std::vector<Scan> make_scans() { return bench::make_scans(256, 64); }

constexpr double kMaxDistance = 3.0;  // Field cap and query radius, metres.

DistanceFieldParams field_params() {
  DistanceFieldParams params;
  params.max_distance_m = kMaxDistance;
  return params;
}

// The grid's snapshot after each scan, with the box of cells that scan can touch.
struct Step {
  std::shared_ptr<const GridSnapshot> grid;
  CellBox touched;
};

const std::vector<Step>& steps() {
  static const std::vector<Step> kSteps = [] {
    HimmGrid grid(HimmParams{});
    const geometry::GridGeometry cells(HimmParams{}.cell_size_m);
    std::vector<Step> result;
    for (const Scan& scan : make_scans()) {
      grid.insert_scan(scan.X_WS, kAngleMin, kAngleIncrement, scan.ranges, kRangeMax);
      const double reach = static_cast<double>(kRangeMax) + 2.0 * HimmParams{}.cell_size_m;
      result.push_back({grid.snapshot(),
                        {cells.cell_of(scan.X_WS.position() - Eigen::Vector2d::Constant(reach)),
                         cells.cell_of(scan.X_WS.position() + Eigen::Vector2d::Constant(reach))}});
    }
    return result;
  }();
  return kSteps;
}

// Scans of the first lap only warm the grid up; timed updates use the later laps, where a scan mostly confirms what
// the grid already holds, as in steady operation.
constexpr std::size_t kWarmSteps = 64;

const DistanceFieldSnapshot& final_field() {
  static const std::shared_ptr<const DistanceFieldSnapshot> kField = [] {
    DistanceField field(field_params());
    static_cast<void>(field.update(steps().back().grid));
    return field.snapshot();
  }();
  return *kField;
}

std::vector<geometry::ClearanceRequest> requests() {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> coordinate(1.0, 19.0);
  std::uniform_real_distribution<double> angle(-std::numbers::pi, std::numbers::pi);
  std::vector<geometry::ClearanceRequest> result(512);
  for (auto& request : result) {
    request.footprint = geometry::BoxFootprint{};
    request.pose = {coordinate(rng), coordinate(rng), angle(rng)};
    request.max_distance_m = 2.0;
  }
  return result;
}

void BM_ClearanceField(benchmark::State& state) {
  const DistanceFieldSnapshot& field = final_field();
  const auto queries = requests();
  const std::uint64_t fallbacks = field.exact_fallback_count();
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(field.compute_clearance(queries[i++ % queries.size()]));
  }
  state.counters["exact_check_fraction"] =
      static_cast<double>(field.exact_fallback_count() - fallbacks) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_ClearanceField);

void BM_ClearanceExactSearch(benchmark::State& state) {
  const GridSnapshot& grid = *steps().back().grid;
  const auto queries = requests();
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(geometry::compute_clearance(queries[i++ % queries.size()], grid));
}
BENCHMARK(BM_ClearanceExactSearch);

// FCL distance from the footprint box to each occupied cell prism within the query radius (fcl has no 2D grid
// shape; an fcl::OcTree would be the other way, measured at 0.1-20 ms per distance in DESIGN.md).
void BM_ClearanceFcl(benchmark::State& state) {
  const GridSnapshot& grid = *steps().back().grid;
  const auto queries = requests();
  const geometry::GridGeometry cells(grid.cell_size());
  const fcl::Boxd cell(grid.cell_size(), grid.cell_size(), 2.0);
  fcl::DistanceRequestd request;
  request.gjk_solver_type = fcl::GST_INDEP;
  std::size_t i = 0;
  for (auto _ : state) {
    const geometry::ClearanceRequest& query = queries[i++ % queries.size()];
    const auto& box = std::get<geometry::BoxFootprint>(query.footprint);
    const fcl::Boxd footprint(box.length, box.width, box.height);
    fcl::Transform3d X_WF = fcl::Transform3d::Identity();
    X_WF.linear() = Eigen::AngleAxisd(query.pose.theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    X_WF.translation() << query.pose.x + box.center_x * std::cos(query.pose.theta),
        query.pose.y + box.center_x * std::sin(query.pose.theta), box.height / 2.0;
    const double reach = std::hypot(box.length / 2 + std::abs(box.center_x), box.width / 2) + query.max_distance_m;
    double best = query.max_distance_m;
    grid.for_each_occupied(cells.cell_of({query.pose.x - reach, query.pose.y - reach}),
                           cells.cell_of({query.pose.x + reach, query.pose.y + reach}),
                           [&](const geometry::CellIndex& c) {
                             fcl::Transform3d X_WC = fcl::Transform3d::Identity();
                             X_WC.translation() << cells.center_of(c), box.height / 2.0;
                             fcl::DistanceResultd result;
                             fcl::distance(&footprint, X_WF, &cell, X_WC, request, result);
                             best = std::min(best, std::max(result.min_distance, 0.0));
                             return true;
                           });
    benchmark::DoNotOptimize(best);
  }
}
BENCHMARK(BM_ClearanceFcl);

void BM_FieldUpdatePerScan(benchmark::State& state) {
  const auto& all = steps();
  std::unique_ptr<DistanceField> field;
  std::size_t i = all.size();
  std::size_t changed = 0;
  std::size_t updates = 0;
  for (auto _ : state) {
    if (i == all.size()) {
      state.PauseTiming();
      field = std::make_unique<DistanceField>(field_params());
      static_cast<void>(field->update(all[kWarmSteps - 1].grid));
      i = kWarmSteps;
      state.ResumeTiming();
    }
    changed += field->update(all[i].grid, all[i].touched).changed_cells;
    ++updates;
    ++i;
  }
  state.counters["changed_cells/scan"] = static_cast<double>(changed) / static_cast<double>(updates);
}
BENCHMARK(BM_FieldUpdatePerScan)->Unit(benchmark::kMicrosecond);

// A person (a disc of 0.25 m radius) walking across the room and back at one cell per step, the room's walls and boxes
// standing still: each step frees the cells behind the person and occupies the ones ahead, and the wavefronts of those
// few cells are the whole update, as they are in a world with people or other robots in it.
struct WalkStep {
  std::shared_ptr<const GridSnapshot> grid;
  std::vector<geometry::CellIndex> changed;
};

const std::vector<WalkStep>& walk_steps() {
  static const std::vector<WalkStep> kSteps = [] {
    const HimmParams params;
    HimmGrid grid(params);
    const geometry::GridGeometry cells(params.cell_size_m);
    const auto fill = [&](const bench::Box& box, bool outline) {
      const geometry::CellIndex lo = cells.cell_of({box.min_x, box.min_y});
      const geometry::CellIndex hi = cells.cell_of({box.max_x, box.max_y});
      for (std::int32_t y = lo.iy; y <= hi.iy; ++y) {
        for (std::int32_t x = lo.ix; x <= hi.ix; ++x) {
          if (outline && x != lo.ix && x != hi.ix && y != lo.iy && y != hi.iy) continue;
          grid.set_certainty({x, y}, static_cast<std::uint8_t>(params.max_certainty));
        }
      }
    };
    fill(bench::kRoom, true);
    for (const bench::Box& box : bench::kObstacles) fill(box, false);
    const auto person_cells = [&](double cx, double cy) {
      std::vector<geometry::CellIndex> result;
      constexpr double kRadius = 0.25;
      const geometry::CellIndex lo = cells.cell_of({cx - kRadius, cy - kRadius});
      const geometry::CellIndex hi = cells.cell_of({cx + kRadius, cy + kRadius});
      for (std::int32_t y = lo.iy; y <= hi.iy; ++y) {
        for (std::int32_t x = lo.ix; x <= hi.ix; ++x) {
          const Eigen::Vector2d centre = cells.center_of({x, y});
          if (std::hypot(centre.x() - cx, centre.y() - cy) <= kRadius) result.push_back({x, y});
        }
      }
      return result;
    };
    // Out from x = 1 m to 19 m along y = 10 m (between the boxes) and back, one cell per step; the sequence is a
    // loop, so the benchmark can replay it for as long as it needs.
    std::vector<double> xs;
    for (int i = 10; i <= 190; ++i) xs.push_back(i * params.cell_size_m);
    for (int i = 189; i >= 11; --i) xs.push_back(i * params.cell_size_m);
    std::vector<geometry::CellIndex> current = person_cells(xs.back(), 10.0);
    for (const auto& c : current) grid.set_certainty(c, static_cast<std::uint8_t>(params.max_certainty));
    std::vector<WalkStep> result;
    for (const double x : xs) {
      const std::vector<geometry::CellIndex> next = person_cells(x, 10.0);
      WalkStep step;
      const auto in = [](const std::vector<geometry::CellIndex>& set, const geometry::CellIndex& c) {
        return std::find(set.begin(), set.end(), c) != set.end();
      };
      for (const auto& c : current) {
        if (!in(next, c)) {
          grid.set_certainty(c, 0);
          step.changed.push_back(c);
        }
      }
      for (const auto& c : next) {
        if (!in(current, c)) {
          grid.set_certainty(c, static_cast<std::uint8_t>(params.max_certainty));
          step.changed.push_back(c);
        }
      }
      step.grid = grid.snapshot();
      result.push_back(std::move(step));
      current = next;
    }
    return result;
  }();
  return kSteps;
}

void BM_FieldUpdateMovingPerson(benchmark::State& state) {
  const auto& all = walk_steps();
  DistanceField field(field_params());
  static_cast<void>(field.update(all.back().grid));
  std::size_t i = 0;
  std::size_t processed = 0;
  std::size_t changed = 0;
  for (auto _ : state) {
    const WalkStep& step = all[i++ % all.size()];
    const DistanceFieldUpdate update = field.update(step.grid, step.changed);
    processed += update.processed_cells;
    changed += update.changed_cells;
  }
  const auto steps = static_cast<double>(state.iterations());
  state.counters["changed_cells/step"] = static_cast<double>(changed) / steps;
  state.counters["processed_cells/step"] = static_cast<double>(processed) / steps;
  state.counters["s/processed_cell"] =
      benchmark::Counter(static_cast<double>(processed), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_FieldUpdateMovingPerson)->Unit(benchmark::kMicrosecond);

// The same walk fed to dynamicEDT3D (one z layer over the room grown by the cap): occupyCell/clearCell, then update().
void BM_DynamicEdt3dUpdateMovingPerson(benchmark::State& state) {
  const auto& all = walk_steps();
  const GridSnapshot& last = *all.back().grid;
  const auto reach = static_cast<std::int32_t>(std::ceil(kMaxDistance / last.cell_size())) + 1;
  const CellBox tiles = *last.tile_bounds();
  const CellBox box{{tiles.min.ix - reach, tiles.min.iy - reach}, {tiles.max.ix + reach, tiles.max.iy + reach}};
  const int max_squared = static_cast<int>(std::pow(kMaxDistance / last.cell_size(), 2));
  DynamicEDT3D edt(max_squared);
  edt.initializeEmpty(box.max.ix - box.min.ix + 1, box.max.iy - box.min.iy + 1, 1, true);
  last.for_each_occupied(box.min, box.max, [&](const geometry::CellIndex& c) {
    edt.occupyCell(c.ix - box.min.ix, c.iy - box.min.iy, 0);
    return true;
  });
  edt.update();
  std::size_t i = 0;
  for (auto _ : state) {
    const WalkStep& step = all[i++ % all.size()];
    for (const auto& c : step.changed) {
      if (step.grid->occupied(c)) {
        edt.occupyCell(c.ix - box.min.ix, c.iy - box.min.iy, 0);
      } else {
        edt.clearCell(c.ix - box.min.ix, c.iy - box.min.iy, 0);
      }
    }
    edt.update();
  }
  benchmark::DoNotOptimize(edt.getDistance(0, 0, 0));
}
BENCHMARK(BM_DynamicEdt3dUpdateMovingPerson)->Unit(benchmark::kMicrosecond);

// The same scans fed to dynamicEDT3D (one z layer, same box and cap): occupyCell/clearCell for the cells whose
// occupancy flipped (found outside the timing), then update().
void BM_DynamicEdt3dUpdatePerScan(benchmark::State& state) {
  const auto& all = steps();
  const CellBox box = *final_field().bounds();
  const int width = box.max.ix - box.min.ix + 1;
  const int height = box.max.iy - box.min.iy + 1;
  const auto occupied_cells = [&](const GridSnapshot& grid) {
    const std::vector<std::uint8_t> values = grid.window(box.min, width, height);
    std::vector<bool> occupied(values.size());
    for (std::size_t k = 0; k < values.size(); ++k) {
      occupied[k] = values[k] != kUnobserved && values[k] >= grid.occupied_threshold();
    }
    return occupied;
  };
  struct Change {
    int x, y;
    bool occupied;
  };
  std::vector<std::vector<Change>> changes(all.size());
  std::vector<bool> before = occupied_cells(*all[kWarmSteps - 1].grid);
  for (std::size_t s = kWarmSteps; s < all.size(); ++s) {
    std::vector<bool> after = occupied_cells(*all[s].grid);
    for (std::size_t k = 0; k < after.size(); ++k) {
      if (after[k] != before[k]) {
        changes[s].push_back({static_cast<int>(k) % width, static_cast<int>(k) / width, static_cast<bool>(after[k])});
      }
    }
    before = std::move(after);
  }
  const int max_squared = static_cast<int>(std::pow(kMaxDistance / HimmParams{}.cell_size_m, 2));
  std::unique_ptr<DynamicEDT3D> edt;
  std::size_t i = all.size();
  for (auto _ : state) {
    if (i == all.size()) {
      state.PauseTiming();
      edt = std::make_unique<DynamicEDT3D>(max_squared);
      edt->initializeEmpty(width, height, 1, true);
      const std::vector<bool> start = occupied_cells(*all[kWarmSteps - 1].grid);
      for (std::size_t k = 0; k < start.size(); ++k) {
        if (start[k]) edt->occupyCell(static_cast<int>(k) % width, static_cast<int>(k) / width, 0);
      }
      edt->update();
      i = kWarmSteps;
      state.ResumeTiming();
    }
    for (const Change& change : changes[i]) {
      if (change.occupied) {
        edt->occupyCell(change.x, change.y, 0);
      } else {
        edt->clearCell(change.x, change.y, 0);
      }
    }
    edt->update();
    ++i;
  }
}
BENCHMARK(BM_DynamicEdt3dUpdatePerScan)->Unit(benchmark::kMicrosecond);

void BM_FieldFullBuild(benchmark::State& state) {
  const auto grid = steps().back().grid;
  for (auto _ : state) {
    DistanceField field(field_params());
    benchmark::DoNotOptimize(field.update(grid));
  }
  state.counters["cells"] = static_cast<double>((final_field().bounds()->max.ix - final_field().bounds()->min.ix + 1) *
                                                (final_field().bounds()->max.iy - final_field().bounds()->min.iy + 1));
}
BENCHMARK(BM_FieldFullBuild)->Unit(benchmark::kMillisecond);

void BM_DynamicEdt3dFullBuild(benchmark::State& state) {
  const CellBox box = *final_field().bounds();
  const int width = box.max.ix - box.min.ix + 1;
  const int height = box.max.iy - box.min.iy + 1;
  const GridSnapshot& grid = *steps().back().grid;
  const int max_squared = static_cast<int>(std::pow(kMaxDistance / HimmParams{}.cell_size_m, 2));
  for (auto _ : state) {
    DynamicEDT3D edt(max_squared);
    edt.initializeEmpty(width, height, 1, true);
    grid.for_each_occupied(box.min, box.max, [&](const geometry::CellIndex& c) {
      edt.occupyCell(c.ix - box.min.ix, c.iy - box.min.iy, 0);
      return true;
    });
    edt.update();
    benchmark::DoNotOptimize(edt.getDistance(0, 0, 0));
  }
}
BENCHMARK(BM_DynamicEdt3dFullBuild)->Unit(benchmark::kMillisecond);

// Prints the runs as usual, then the ratios of the three clearance methods and of the two update methods.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& run : runs)
      times_[run.benchmark_name()] = run.GetAdjustedRealTime() / benchmark::GetTimeUnitMultiplier(run.time_unit);
    ConsoleReporter::ReportRuns(runs);
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    ratio("BM_ClearanceExactSearch", "BM_ClearanceField");
    ratio("BM_ClearanceFcl", "BM_ClearanceField");
    ratio("BM_DynamicEdt3dUpdatePerScan", "BM_FieldUpdatePerScan");
    ratio("BM_DynamicEdt3dUpdateMovingPerson", "BM_FieldUpdateMovingPerson");
    ratio("BM_DynamicEdt3dFullBuild", "BM_FieldFullBuild");
  }

 private:
  void ratio(const std::string& slow, const std::string& fast) const {
    const auto s = times_.find(slow);
    const auto f = times_.find(fast);
    if (s == times_.end() || f == times_.end() || f->second <= 0.0) return;
    std::printf("ratio %s / %s = %.1f\n", slow.c_str(), fast.c_str(), s->second / f->second);
  }
  std::map<std::string, double> times_;  // Seconds per iteration.
};

}  // namespace
}  // namespace occgeo::mapping

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  occgeo::mapping::RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  return 0;
}
