// The server's query kernels in process, on one core: collision checks and clearance lookups per second as the
// handlers run them (HIMM grid snapshot + distance field, the Bearcat's 1.0 x 0.8 m box), and batched collision poses
// per second, both the kernel alone and with the reply message built. The map is an indoor-like 40 x 40 m world of
// 0.1 m cells: outer walls, a few inner walls with doors and 150 boxes of furniture. Poses are uniform over it.
// Google Benchmark's per_s counters are per CPU second too.
//
// Before the Google Benchmark runs, a summary prints each figure next to its goal (collision >= 1M checks/s/core,
// batched collision >= 5M poses/s) and the p50/p99 latency of one clearance lookup over every model (grid, an octree
// of the same world as 0.05 m voxel columns up to 1 m, PTEM; goal p99 <= 5 us), measured in the same run.
// `--no-summary` runs the Google Benchmarks alone (e.g. under perf).

#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <random>
#include <string>
#include <vector>

#include "handlers/query_kernels.h"
#include "occgeo/mapping/distance_field.h"
#include "occgeo/mapping/himm_grid.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/mapping/ptem.h"
#include "octree_band_field.h"

namespace occgeo::service {
namespace {

constexpr double kCell_m = 0.1;
constexpr int kSide = 400;

std::shared_ptr<const mapping::OctoMapSnapshot>& filled_octomap();

const WorldSnapshot& bench_world() {
  static const WorldSnapshot world = [] {
    std::vector<bool> occupied(static_cast<std::size_t>(kSide) * kSide, false);
    const auto set = [&](int x, int y) {
      if (x >= 0 && y >= 0 && x < kSide && y < kSide) occupied[static_cast<std::size_t>(y) * kSide + x] = true;
    };
    for (int i = 0; i < kSide; ++i) {
      set(i, 0), set(i, kSide - 1), set(0, i), set(kSide - 1, i);
      if (i % 100 > 12) set(i, 130), set(i, 270), set(200, i);  // inner walls with 1.3 m doors
    }
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> at(5, kSide - 10), size(2, 9);
    for (int b = 0; b < 150; ++b) {
      const int x0 = at(rng), y0 = at(rng), w = size(rng), h = size(rng);
      for (int y = y0; y < y0 + h; ++y) {
        for (int x = x0; x < x0 + w; ++x) set(x, y);
      }
    }
    mapfile::OccupancyImage image;
    image.width = kSide;
    image.height = kSide;
    image.resolution = kCell_m;
    image.pixels.resize(occupied.size());
    for (int y = 0; y < kSide; ++y) {
      for (int x = 0; x < kSide; ++x) {
        image.pixels[static_cast<std::size_t>(kSide - 1 - y) * kSide + x] =
            occupied[static_cast<std::size_t>(y) * kSide + x] ? 0 : 254;
      }
    }
    auto grid = mapping::HimmGrid::from_image(image, mapping::HimmParams{}).snapshot();
    mapping::DistanceField field(mapping::DistanceFieldParams{});
    field.update(grid);
    static mapping::OctoMapModel octomap{mapping::OctoMapParams{}};
    static mapping::PtemModel ptem{mapping::PtemParams{}};
    // The same walls and furniture in the octree: every occupied grid cell a column of 0.05 m voxels up to 1 m.
    mapping::OctoMapModel filled{mapping::OctoMapParams{}};
    constexpr double kVoxel_m = 0.05;
    for (int y = 0; y < kSide; ++y) {
      for (int x = 0; x < kSide; ++x) {
        if (!occupied[static_cast<std::size_t>(y) * kSide + x]) continue;
        for (int sub = 0; sub < 4; ++sub) {
          const double vx = x * kCell_m + (sub % 2 + 0.5) * kVoxel_m, vy = y * kCell_m + (sub / 2 + 0.5) * kVoxel_m;
          for (int layer = 1; layer < 20; ++layer) {
            // A return 1 mm long ends in the voxel it starts in: it marks that voxel and clears nothing else.
            geometry::Pose3 X_WS;
            X_WS.transform.translation() = Eigen::Vector3d(vx - 0.0005, vy, (layer + 0.5) * kVoxel_m);
            filled.insert_ray(X_WS, 0.001, 5.0);
          }
        }
      }
    }
    filled_octomap() = filled.publish();
    return WorldSnapshot{grid, ptem.snapshot(), nullptr, field.snapshot(), octomap.publish(), nullptr, nullptr};
  }();
  return world;
}

std::shared_ptr<const mapping::OctoMapSnapshot>& filled_octomap() {
  static std::shared_ptr<const mapping::OctoMapSnapshot> snapshot;
  return snapshot;
}

// bench_world() with the octree holding the world's walls and furniture too, for queries over every model, without
// the octree's band fields: octree clearance walks the voxel columns.
const WorldSnapshot& bench_world_all_models_walk() {
  static const WorldSnapshot world = [] {
    WorldSnapshot out = bench_world();
    out.octomap = filled_octomap();
    return out;
  }();
  return world;
}

// The same with the band field a server keeps for the Bearcat's height (1 m), as queries then find it.
const WorldSnapshot& bench_world_all_models() {
  static const WorldSnapshot world = [] {
    WorldSnapshot out = bench_world_all_models_walk();
    OctreeBandField band(1.0, mapping::DistanceFieldParams{});
    band.update(*out.octomap);
    out.octree_bands = std::make_shared<const std::vector<OctreeBandSnapshot>>(1, band.snapshot());
    return out;
  }();
  return world;
}

const geometry::Footprint kBearcat = geometry::BoxFootprint{1.0, 0.8, 1.0, 0.0};
const std::vector<v1::Model> kGrid = {v1::MODEL_GRID};
const std::vector<v1::Model> kAllModels = {v1::MODEL_GRID, v1::MODEL_OCTOMAP, v1::MODEL_PTEM};

const std::vector<geometry::Pose2>& bench_poses() {
  static const std::vector<geometry::Pose2> poses = [] {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> xy(0.5, kSide * kCell_m - 0.5), theta(-M_PI, M_PI);
    std::vector<geometry::Pose2> out(65536);
    for (auto& p : out) p = {xy(rng), xy(rng), theta(rng)};
    return out;
  }();
  return poses;
}

void report(benchmark::State& state, double per_iteration) {
  state.counters["per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * per_iteration, benchmark::Counter::kIsRate);
  // items_per_second too, which scripts/benchmarks.sh reads as entries (poses) per second.
  state.SetItemsProcessed(static_cast<std::int64_t>(static_cast<double>(state.iterations()) * per_iteration));
}

void BM_CollisionSingle(benchmark::State& state) {
  const WorldSnapshot& world = bench_world();
  const auto& poses = bench_poses();
  const double radius = geometry::bounding_radius(kBearcat);
  std::size_t next = 0;
  double hits = 0;
  for (auto _ : state) {
    v1::CollisionReply reply;
    answer_collision(world, kBearcat, radius, poses[next], kGrid, reply);
    hits += reply.hit() ? 1.0 : 0.0;
    benchmark::DoNotOptimize(reply);
    next = (next + 1) & (poses.size() - 1);
  }
  report(state, 1.0);
  state.counters["hit_fraction"] = benchmark::Counter(hits, benchmark::Counter::kAvgIterations);
}

void BM_ClearanceSingle(benchmark::State& state) {
  const WorldSnapshot& world = bench_world();
  const auto& poses = bench_poses();
  std::size_t next = 0;
  for (auto _ : state) {
    v1::ClearanceReply reply;
    answer_clearance(world, kBearcat, poses[next], 1.0, kGrid, reply);
    benchmark::DoNotOptimize(reply);
    next = (next + 1) & (poses.size() - 1);
  }
  report(state, 1.0);
}

constexpr int kBatch = 10000;

void BM_CollisionBatchKernel(benchmark::State& state) {
  const WorldSnapshot& world = bench_world();
  const auto& poses = bench_poses();
  const double radius = geometry::bounding_radius(kBearcat);
  for (auto _ : state) {
    int hits = 0;
    for (int i = 0; i < kBatch; ++i) {
      hits +=
          grid_collision(*world.grid, world.distance.get(), kBearcat, radius, poses[static_cast<std::size_t>(i)]).hit;
    }
    benchmark::DoNotOptimize(hits);
  }
  report(state, kBatch);
}

void BM_CollisionBatchReply(benchmark::State& state) {
  const WorldSnapshot& world = bench_world();
  const auto& poses = bench_poses();
  const double radius = geometry::bounding_radius(kBearcat);
  for (auto _ : state) {
    google::protobuf::Arena arena;
    auto* reply = google::protobuf::Arena::CreateMessage<v1::CollisionBatchReply>(&arena);
    reply->mutable_results()->Reserve(kBatch);
    for (int i = 0; i < kBatch; ++i) {
      answer_collision(world, kBearcat, radius, poses[static_cast<std::size_t>(i)], kGrid, *reply->add_results());
    }
    benchmark::DoNotOptimize(reply);
  }
  report(state, kBatch);
}

// One clearance lookup over the grid, the octree (the same walls and furniture as 0.05 m voxels up to 1 m) and the
// PTEM, as ClearanceQuery answers it with all models, on world.
void clearance_all_models(benchmark::State& state, const WorldSnapshot& world) {
  const auto& poses = bench_poses();
  std::size_t next = 0;
  for (auto _ : state) {
    v1::ClearanceReply reply;
    answer_clearance(world, kBearcat, poses[next], 1.0, kAllModels, reply);
    benchmark::DoNotOptimize(reply);
    next = (next + 1) & (poses.size() - 1);
  }
  report(state, 1.0);
}
// With the octree's band field, as a server answers once queries asked for the Bearcat's height.
void BM_ClearanceAllModels(benchmark::State& state) { clearance_all_models(state, bench_world_all_models()); }
// With the octree walked (no band field): the cost the field saves.
void BM_ClearanceAllModelsOctreeWalk(benchmark::State& state) {
  clearance_all_models(state, bench_world_all_models_walk());
}

BENCHMARK(BM_CollisionSingle);
BENCHMARK(BM_ClearanceSingle);
BENCHMARK(BM_ClearanceAllModels);
BENCHMARK(BM_ClearanceAllModelsOctreeWalk);
BENCHMARK(BM_CollisionBatchKernel)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CollisionBatchReply)->Unit(benchmark::kMillisecond);

// CPU time of this thread, seconds: per-core figures that other processes sharing the cores do not distort.
double thread_cpu_s() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + static_cast<double>(now.tv_nsec) * 1e-9;
}

// Runs work over the poses for about `seconds` of CPU time and returns entries per CPU second.
template <typename Work>
double rate(double seconds, Work&& work) {
  const auto& poses = bench_poses();
  const double start = thread_cpu_s();
  std::size_t done = 0;
  double elapsed = 0.0;
  while (elapsed < seconds) {
    for (std::size_t i = 0; i < 4096; ++i) work(poses[(done + i) & (poses.size() - 1)]);
    done += 4096;
    elapsed = thread_cpu_s() - start;
  }
  return static_cast<double>(done) / elapsed;
}

void print_summary(double seconds) {
  const WorldSnapshot& world = bench_world();
  const double radius = geometry::bounding_radius(kBearcat);
  int sink = 0;
  const double single = rate(seconds, [&](const geometry::Pose2& pose) {
    v1::CollisionReply reply;
    answer_collision(world, kBearcat, radius, pose, kGrid, reply);
    sink += reply.hit();
  });
  const double clearance = rate(seconds, [&](const geometry::Pose2& pose) {
    v1::ClearanceReply reply;
    answer_clearance(world, kBearcat, pose, 1.0, kGrid, reply);
    sink += reply.found();
  });
  const double batch = rate(seconds, [&](const geometry::Pose2& pose) {
    sink += grid_collision(*world.grid, world.distance.get(), kBearcat, radius, pose).hit;
  });
  const double exact = rate(seconds, [&](const geometry::Pose2& pose) {
    sink += geometry::check_collision({kBearcat, pose}, *world.grid).hit;
  });
  // Latency of single all-model clearance lookups (wall clock per call; other processes on the cores show as tail),
  // the octree answered from its band field and, in the same run, by walking its columns; then each model of the
  // first on its own, to show which one the tail comes from.
  const auto& poses = bench_poses();
  const std::size_t samples = seconds < 0.5 ? 2000 : 20000;
  struct Series {
    const char* name;
    const WorldSnapshot* world;
    std::vector<v1::Model> models;
    std::vector<double> latencies_us;
  };
  std::array<Series, 5> series = {{{"all models", &bench_world_all_models(), kAllModels, {}},
                                   {"all models, octree walked", &bench_world_all_models_walk(), kAllModels, {}},
                                   {"grid only", &bench_world_all_models(), {v1::MODEL_GRID}, {}},
                                   {"octree only (band field)", &bench_world_all_models(), {v1::MODEL_OCTOMAP}, {}},
                                   {"ptem only", &bench_world_all_models(), {v1::MODEL_PTEM}, {}}}};
  // Each series on its own, one lookup after the other as a query thread answers them: interleaved, every lookup of
  // one series would find the caches filled by the other series' lookups (the octree walk streams megabytes).
  for (Series& run : series) {
    for (std::size_t i = 0; i < samples; ++i) {
      v1::ClearanceReply reply;
      const auto start = std::chrono::steady_clock::now();
      answer_clearance(*run.world, kBearcat, poses[i & (poses.size() - 1)], 1.0, run.models, reply);
      const auto stop = std::chrono::steady_clock::now();
      sink += reply.found();
      run.latencies_us.push_back(std::chrono::duration<double, std::micro>(stop - start).count());
    }
  }
  for (Series& run : series) std::sort(run.latencies_us.begin(), run.latencies_us.end());
  const auto percentile = [&](std::size_t w, double q) {
    const auto& run = series[w].latencies_us;
    return run[std::min(run.size() - 1, static_cast<std::size_t>(q * static_cast<double>(run.size())))];
  };
  benchmark::DoNotOptimize(sink);
  std::printf(
      "clearance of the Bearcat box with all models (grid, octree of the same world, PTEM), %zu lookups: "
      "p50 %.2f us  p99 %.2f us  goal p99 <= 5 us\n",
      samples, percentile(0, 0.50), percentile(0, 0.99));
  std::printf("  the same with the octree walked instead of its band field: p50 %.2f us  p99 %.2f us (%.1fx the p99)\n",
              percentile(1, 0.50), percentile(1, 0.99), percentile(1, 0.99) / percentile(0, 0.99));
  for (std::size_t w = 2; w < series.size(); ++w) {
    std::printf("  %s: p50 %.2f us  p99 %.2f us\n", series[w].name, percentile(w, 0.50), percentile(w, 0.99));
  }
  const WorldSnapshot& fields = bench_world_all_models();
  std::printf("  lookups that needed the exact search near the footprint: grid field %llu, octree band field %llu\n",
              static_cast<unsigned long long>(fields.distance->exact_fallback_count()),
              static_cast<unsigned long long>(fields.octree_bands->front().field->exact_fallback_count()));
  std::printf(
      "in-process query kernels, per CPU second of one core, Bearcat box on a 40 x 40 m indoor map of 0.1 m cells\n");
  std::printf("  collision checks/s (CollisionQuery kernel): %12.0f  goal 1000000  ratio %.2f\n", single, single / 1e6);
  std::printf("  clearance lookups/s (ClearanceQuery kernel): %11.0f\n", clearance);
  std::printf("  batched collision poses/s (grid kernel):     %11.0f  goal 5000000  ratio %.2f\n", batch, batch / 5e6);
  std::printf("  exact check_collision on the snapshot, for comparison: %.0f/s (kernel speed-up %.1fx)\n", exact,
              batch / exact);
}

}  // namespace
}  // namespace occgeo::service

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  bool smoke = false;
  bool summary = true;  // --no-summary: the Google Benchmarks alone, e.g. under a profiler
  for (int i = 1; i < argc; ++i) {
    smoke = smoke || std::string(argv[i]).find("min_time=0.0") != std::string::npos;
    summary = summary && std::string(argv[i]) != "--no-summary";
  }
  if (summary) occgeo::service::print_summary(smoke ? 0.05 : 1.0);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
