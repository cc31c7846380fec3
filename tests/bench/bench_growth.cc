// How one laser scan's cost grows with the map: the server's whole per-scan ingest path (PTEM, HIMM grid, OctoMap,
// distance field, and the publication of every model's snapshot after each scan, as a lockstep robot gets it) for
// square outdoor worlds of 20, 100 and 300 m a side, seen by an 80 m, 360-beam lidar 0.3 m above the ground.
//
// Each world is a plain with walls around it and one box (0.3 to 2 m a side) per 16 m², placed from a fixed seed; the
// larger worlds hold the 20 m world, walls and boxes, in their corner at the origin.
// Before timing, the robot scans from a lattice of poses 8 m apart over the whole world, so the map holds everything
// the lidar can see; the timed scans then come from random poses inside the world (the map barely grows while they
// run). A cost proportional to the map on the per-scan path shows as a per-scan time growing with the side.
//
// Counters: ms per scan, the process's resident memory after the fill (MB; sizes run in increasing order, so it
// includes what earlier sizes left to the allocator), the scans of the fill and their mean CPU time (the fill publishes
// the octree only once, at its end).
// Before the Google Benchmark runs, a summary prints the largest world's cost per scan as a ratio of the smallest's,
// measured in the same run. The worlds are built with the server's defaults (config.h); every timed scan publishes
// every model, as a lockstep robot's scans do.

#include <benchmark/benchmark.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "core.h"
#include "ingest/model_ingest.h"
#include "occgeo/service/config.h"

namespace occgeo::service {
namespace {

constexpr double kTruthCell_m = 0.05;
constexpr int kBeams = 360;
constexpr double kRangeMax_m = 80.0;
constexpr double kLatticeSpacing_m = 8.0;
// The summary times each of these poses once, in the same order in every build: a pose seen again changes less (its
// voxels are clamped already), so the Google Benchmark loop, which cycles through them as long as it runs, gets
// cheaper with its iteration count and is not comparable between runs; the summary is.
constexpr int kTimedPoses = 256;
// The smallest world, also the room in the corner of the larger ones: the summary times the same scans in that room
// in every world, which separates what the map's size costs from what the longer beams of a larger world cost.
constexpr double kRoomSide_m = 20.0;

double thread_cpu_s() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double resident_mb() {
  std::ifstream statm("/proc/self/statm");
  long pages_total = 0, pages_resident = 0;
  statm >> pages_total >> pages_resident;
  return static_cast<double>(pages_resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

// The ground truth: a boolean raster of kTruthCell_m cells over [0, side]², walls on the border, random boxes inside.
class TruthWorld {
 public:
  explicit TruthWorld(double side_m)
      : side_m_(side_m),
        cells_(static_cast<int>(std::ceil(side_m / kTruthCell_m))),
        occupied_(static_cast<std::size_t>(cells_) * static_cast<std::size_t>(cells_), false) {
    const auto fill = [&](double x0, double y0, double x1, double y1) {
      for (int y = cell(y0); y <= cell(y1); ++y) {
        for (int x = cell(x0); x <= cell(x1); ++x) set(x, y);
      }
    };
    fill(0, 0, side_m, 0.2), fill(0, side_m - 0.2, side_m, side_m);
    fill(0, 0, 0.2, side_m), fill(side_m - 0.2, 0, side_m, side_m);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> at(1.0, side_m - 3.0), size(0.3, 2.0);
    const int boxes = static_cast<int>(side_m * side_m / 16.0);
    for (int b = 0; b < boxes; ++b) {
      const double x = at(rng), y = at(rng);
      fill(x, y, x + size(rng), y + size(rng));
    }
    if (side_m > kRoomSide_m) {
      const TruthWorld room(kRoomSide_m);
      for (int y = 0; y < room.cells_; ++y) {
        for (int x = 0; x < room.cells_; ++x) occupied_[index(x, y)] = room.occupied_[room.index(x, y)];
      }
    }
  }

  [[nodiscard]] double side_m() const { return side_m_; }
  [[nodiscard]] bool occupied(double x, double y) const {
    const int cx = cell(x), cy = cell(y);
    if (cx < 0 || cy < 0 || cx >= cells_ || cy >= cells_) return true;
    return occupied_[index(cx, cy)];
  }

  // A 360-beam scan from (x, y, theta): the first occupied cell along each beam, marched in half-cell steps; beams
  // that meet nothing within kRangeMax_m read kRangeMax_m (no return).
  [[nodiscard]] v1::LaserScan scan(const geometry::Pose2& pose, std::uint64_t seq) const {
    v1::LaserScan out;
    out.set_sensor("lidar");
    out.set_seq(seq);
    out.set_stamp_s(0.1 * static_cast<double>(seq));
    for (int i = 0; i < kBeams; ++i) {
      const double angle = pose.theta + angle_min() + angle_increment() * i;
      const double dx = std::cos(angle), dy = std::sin(angle);
      double range = kRangeMax_m;
      for (double r = 0.2; r < kRangeMax_m; r += kTruthCell_m / 2) {
        if (occupied(pose.x + r * dx, pose.y + r * dy)) {
          range = r;
          break;
        }
      }
      out.add_ranges(static_cast<float>(range));
    }
    return out;
  }

  static double angle_min() { return -std::numbers::pi; }
  static double angle_increment() { return 2.0 * std::numbers::pi / kBeams; }

 private:
  [[nodiscard]] static int cell(double v) { return static_cast<int>(std::floor(v / kTruthCell_m)); }
  [[nodiscard]] std::size_t index(int x, int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(cells_) + static_cast<std::size_t>(x);
  }
  void set(int x, int y) {
    if (x >= 0 && y >= 0 && x < cells_ && y < cells_) occupied_[index(x, y)] = true;
  }

  double side_m_;
  int cells_;
  std::vector<bool> occupied_;
};

LaserModel lidar() {
  LaserModel laser;
  laser.name = "lidar";
  laser.X_BS = geometry::Pose3::from_xyz_rpy(0.0, 0.0, 0.3, 0.0, 0.0, 0.0);
  laser.angle_min_rad = TruthWorld::angle_min();
  laser.angle_increment_rad = TruthWorld::angle_increment();
  laser.beam_count = kBeams;
  laser.range_min_m = 0.05;
  laser.range_max_m = kRangeMax_m;
  return laser;
}

// A free pose (nothing within 0.5 m) near (x, y), or nullopt.
std::optional<geometry::Pose2> free_pose_near(const TruthWorld& truth, double x, double y, double theta) {
  for (double d = 0.0; d < 3.0; d += 0.25) {
    for (const auto& [ox, oy] : {std::pair{d, 0.0}, {-d, 0.0}, {0.0, d}, {0.0, -d}}) {
      bool clear = true;
      for (double a = 0; a < 2 * std::numbers::pi && clear; a += 0.5) {
        clear = !truth.occupied(x + ox + 0.5 * std::cos(a), y + oy + 0.5 * std::sin(a));
      }
      if (clear) return geometry::Pose2{x + ox, y + oy, theta};
    }
  }
  return std::nullopt;
}

// kTimedPoses free poses drawn from a fixed seed over `where` (a world, or the room in its corner), each with its scan
// of `truth`.
std::vector<std::pair<geometry::Pose2, v1::LaserScan>> timed_scans(const TruthWorld& where, const TruthWorld& truth) {
  std::vector<std::pair<geometry::Pose2, v1::LaserScan>> scans;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> xy(2.0, where.side_m() - 2.0), theta(-std::numbers::pi, std::numbers::pi);
  while (static_cast<int>(scans.size()) < kTimedPoses) {
    if (const auto pose = free_pose_near(where, xy(rng), xy(rng), theta(rng))) {
      scans.emplace_back(*pose, truth.scan(*pose, 0));
    }
  }
  return scans;
}

// One world of a given side, filled, with the scans the timed loop cycles through.
struct GrownWorld {
  std::unique_ptr<ServerCore> core;
  std::shared_ptr<World> world;
  std::vector<std::pair<geometry::Pose2, v1::LaserScan>> timed_scans;
  // Scans from the smallest world's timed poses, in the room every world holds at its corner (the same scans in every
  // world: the room's walls stop every beam).
  std::vector<std::pair<geometry::Pose2, v1::LaserScan>> room_scans;
  std::uint64_t next_seq = 1;
  int fill_scans = 0;
  double rss_mb = 0.0;
  double fill_cpu_s = 0.0;
};

// One scan through every model, then the grid, distance field and PTEM published; the octree too when asked (every
// timed scan; the fill publishes it at its end only, so that filling the large worlds does not take an hour).
void ingest_one(World& world, const LaserModel& laser, const geometry::Pose2& pose, const v1::LaserScan& scan,
                bool publish_octree) {
  IngestTarget target{world.grid_on_strand(), world.octomap_params(), std::nullopt, {}};
  target.touch({pose.x, pose.y}, laser.range_max_m);
  insert_laser_scan(world, target, "bench", pose, laser, scan);
  world.apply_octree_work_on_strand(std::move(target.octree_work));
  world.publish_on_strand(target.touched);
  if (publish_octree) world.publish_octomap_on_strand();
}

GrownWorld& grown_world(double side_m) {
  static std::map<int, GrownWorld> worlds;
  auto& grown = worlds[static_cast<int>(side_m)];
  if (grown.core) return grown;
  ServerConfig config;
  // The octree is published explicitly (ingest_one), never by the world's own timer: this thread calls the world's
  // strand functions directly, and nothing else may run on that strand meanwhile.
  config.octomap_publish_every_messages = std::numeric_limits<std::uint32_t>::max();
  grown.core = std::make_unique<ServerCore>(config);
  grown.world = grown.core->add_world("growth", mapping::HimmGrid(config.himm));
  const TruthWorld truth(side_m);
  const LaserModel laser = lidar();
  const double fill_start_s = thread_cpu_s();
  const int rows = static_cast<int>(std::ceil((side_m - 3.0) / kLatticeSpacing_m));
  int row = 0;
  for (double y = 2.0; y < side_m - 1.0; y += kLatticeSpacing_m, ++row) {
    std::fprintf(stderr, "\rgrowth: filling the %.0f x %.0f m world: %3d %%", side_m, side_m, 100 * row / rows);
    for (double x = 2.0; x < side_m - 1.0; x += kLatticeSpacing_m) {
      const auto pose = free_pose_near(truth, x, y, 0.0);
      if (!pose) continue;
      ingest_one(*grown.world, laser, *pose, truth.scan(*pose, grown.next_seq++), false);
      ++grown.fill_scans;
    }
  }
  grown.world->publish_octomap_on_strand();
  grown.fill_cpu_s = thread_cpu_s() - fill_start_s;
  std::fprintf(stderr, "\rgrowth: filling the %.0f x %.0f m world: done, %d scans\n", side_m, side_m, grown.fill_scans);
  grown.rss_mb = resident_mb();
  grown.timed_scans = timed_scans(truth, truth);
  // The smallest world's poses, in the room: the same scans in every world.
  grown.room_scans = side_m > kRoomSide_m ? timed_scans(TruthWorld(kRoomSide_m), truth) : grown.timed_scans;
  return grown;
}

// The mean CPU seconds per scan over the scans (used by the summary).
double cpu_per_scan_s(GrownWorld& grown, std::vector<std::pair<geometry::Pose2, v1::LaserScan>>& scans) {
  const LaserModel laser = lidar();
  const double start = thread_cpu_s();
  for (auto& [pose, scan] : scans) {
    scan.set_seq(grown.next_seq);
    scan.set_stamp_s(0.1 * static_cast<double>(grown.next_seq++));
    ingest_one(*grown.world, laser, pose, scan, true);
  }
  return (thread_cpu_s() - start) / static_cast<double>(scans.size());
}

// The mean length of the scans' beams (no return: the lidar's maximum range), metres: a scan's cost grows with it.
double mean_beam_m(const std::vector<std::pair<geometry::Pose2, v1::LaserScan>>& scans) {
  double sum = 0.0;
  std::size_t beams = 0;
  for (const auto& [pose, scan] : scans) {
    for (const float range : scan.ranges()) sum += static_cast<double>(range);
    beams += static_cast<std::size_t>(scan.ranges_size());
  }
  return beams == 0 ? 0.0 : sum / static_cast<double>(beams);
}

void BM_ScanAllModelsPublished(benchmark::State& state) {
  const double side_m = static_cast<double>(state.range(0));
  GrownWorld& grown = grown_world(side_m);
  const LaserModel laser = lidar();
  std::size_t i = 0;
  for (auto _ : state) {
    auto& [pose, scan] = grown.timed_scans[i++ % grown.timed_scans.size()];
    scan.set_seq(grown.next_seq);
    scan.set_stamp_s(0.1 * static_cast<double>(grown.next_seq++));
    ingest_one(*grown.world, laser, pose, scan, true);
  }
  state.counters["rss_MB"] = grown.rss_mb;
  state.counters["fill_scans"] = grown.fill_scans;
  state.counters["fill_ms_per_scan"] = 1e3 * grown.fill_cpu_s / std::max(1, grown.fill_scans);
  state.SetLabel(std::to_string(static_cast<int>(side_m)) + " m world, 80 m lidar");
}
BENCHMARK(BM_ScanAllModelsPublished)->Arg(20)->Arg(100)->Arg(300)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace occgeo::service

// The summary: each size's CPU per scan, resident memory, and the largest's cost as a ratio of the smallest's (goal:
// within 1.5x), measured here before the Google Benchmark runs. OCCGEO_GROWTH_SIDES=20 limits it (the CI smoke run).
int main(int argc, char** argv) {
  using namespace occgeo::service;
  std::vector<int> sides = {20, 100, 300};
  if (const char* only = std::getenv("OCCGEO_GROWTH_SIDES")) sides = {std::atoi(only)};
  double first = 0.0, last = 0.0, room_first = 0.0, room_last = 0.0;
  for (const int side : sides) {
    GrownWorld& grown = grown_world(side);
    // The room's scans first: the random poses, most of them outside the room, do not see into it.
    const double room_per_scan = cpu_per_scan_s(grown, grown.room_scans);
    const double per_scan = side > kRoomSide_m ? cpu_per_scan_s(grown, grown.timed_scans) : room_per_scan;
    std::printf(
        "growth: %3d x %3d m: %.2f ms CPU per scan (all models, published every scan; beams %.1f m on average), "
        "%.0f MB resident, fill %d scans at %.2f ms each\n",
        side, side, 1e3 * per_scan, mean_beam_m(grown.timed_scans), grown.rss_mb, grown.fill_scans,
        1e3 * grown.fill_cpu_s / std::max(1, grown.fill_scans));
    if (side > kRoomSide_m) {
      std::printf("growth: %3d x %3d m: %.2f ms CPU per scan of the %.0f m room's scans (beams %.1f m on average)\n",
                  side, side, 1e3 * room_per_scan, kRoomSide_m, mean_beam_m(grown.room_scans));
    }
    if (first == 0.0) first = per_scan, room_first = room_per_scan;
    last = per_scan, room_last = room_per_scan;
  }
  if (sides.size() > 1) {
    std::printf("growth: largest / smallest cost per scan = %.2fx (goal <= 1.5x)\n", last / first);
    std::printf("growth: the same scans (the room's) in the largest / in the smallest map = %.2fx\n",
                room_last / room_first);
  }
  std::fflush(stdout);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
