// PTEM (seed 004 §4) cost: update per Hokuyo URG-04LX scan (682 beams over 240°, 4 m) in both constructions, and
// threat queries on a snapshot. The scene is a hall of pillars (r = 0.15 m, 0.8 m apart, so gaps of 0.5 m > C_r and
// each pillar is its own cluster) that returns nearly every beam: the many-obstacle end of what the seed's clustering
// is meant for (walls would merge into a few oversized clusters instead).

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <numbers>
#include <random>
#include <vector>

#include "occgeo/mapping/ptem.h"

namespace occgeo::mapping {
namespace {

constexpr int kBeams = 682;
constexpr double kFieldOfView = 240.0 * std::numbers::pi / 180.0;
constexpr double kMaxRange = 4.0;
constexpr double kPillarRadius = 0.15;
constexpr double kPillarSpacing = 0.8;

struct Scan {
  double stamp_s;
  Eigen::Vector2d p_WS;
  double yaw_WS;
  std::vector<Eigen::Vector2d> points_W;
};

// Range along p + t u to the nearest pillar of the infinite lattice (centres at (i + 0.5, j + 0.5) * spacing), or +inf
// beyond max range; checks the lattice cells the ray passes near by stepping along it.
double cast_ray(const Eigen::Vector2d& p, const Eigen::Vector2d& u) {
  double best = std::numeric_limits<double>::infinity();
  for (double t = 0.0; t <= kMaxRange + kPillarSpacing; t += kPillarSpacing / 4.0) {
    const Eigen::Vector2d q = p + t * u;
    const double ci = std::floor(q.x() / kPillarSpacing), cj = std::floor(q.y() / kPillarSpacing);
    for (int di = -1; di <= 1; ++di) {
      for (int dj = -1; dj <= 1; ++dj) {
        const Eigen::Vector2d c((ci + di + 0.5) * kPillarSpacing, (cj + dj + 0.5) * kPillarSpacing);
        const Eigen::Vector2d w = p - c;
        const double b = u.dot(w);
        const double disc = b * b - (w.squaredNorm() - kPillarRadius * kPillarRadius);
        if (disc < 0.0) continue;
        const double hit = -b - std::sqrt(disc);
        if (hit > 0.0) best = std::min(best, hit);
      }
    }
    if (best < t) break;
  }
  return best <= kMaxRange ? best : std::numeric_limits<double>::infinity();
}

// 64 scans, 10 Hz, from a robot driving diagonally through the hall at 0.3 m/s, turning slowly.
std::vector<Scan> make_scans() {
  std::vector<Scan> scans;
  for (int k = 0; k < 64; ++k) {
    Scan scan;
    scan.stamp_s = 0.1 * k;
    scan.p_WS = Eigen::Vector2d(0.03 * k + 0.4, 0.01 * k + 0.4);
    scan.yaw_WS = 0.02 * k;
    for (int beam = 0; beam < kBeams; ++beam) {
      const double angle = scan.yaw_WS - kFieldOfView / 2.0 + kFieldOfView * beam / (kBeams - 1);
      const Eigen::Vector2d u(std::cos(angle), std::sin(angle));
      const double range = cast_ray(scan.p_WS, u);
      if (std::isfinite(range)) scan.points_W.push_back(scan.p_WS + range * u);
    }
    scans.push_back(std::move(scan));
  }
  return scans;
}

const std::vector<Scan>& scans() {
  static const std::vector<Scan> kScans = make_scans();
  return kScans;
}

PtemScan to_ptem_scan(const Scan& scan, double stamp_s) {
  PtemScan out;
  out.stamp_s = stamp_s;
  out.p_WS = scan.p_WS;
  out.yaw_WS = scan.yaw_WS;
  out.field_of_view_rad = kFieldOfView;
  out.max_range_m = kMaxRange;
  out.points_W = scan.points_W;
  return out;
}

double mean_points_per_scan() {
  double points = 0.0;
  for (const Scan& scan : scans()) points += static_cast<double>(scan.points_W.size());
  return points / static_cast<double>(scans().size());
}

// A model that has taken every scan once (the cumulative one then holds every pillar seen on the way).
PtemModel warmed_up_model(PtemConstruction construction, std::uint64_t& scans_taken) {
  PtemParams params;
  params.construction = construction;
  PtemModel model(params);
  for (const Scan& scan : scans()) model.insert_scan(to_ptem_scan(scan, 0.1 * static_cast<double>(scans_taken++)));
  return model;
}

// Ingest one scan and publish a snapshot, as a server does.
void BM_UpdatePerScan(benchmark::State& state, PtemConstruction construction) {
  std::uint64_t scans_taken = 0;
  PtemModel model = warmed_up_model(construction, scans_taken);
  std::shared_ptr<const PtemSnapshot> published;
  double clusters = 0.0;
  for (auto _ : state) {
    const Scan& scan = scans()[scans_taken % scans().size()];
    model.insert_scan(to_ptem_scan(scan, 0.1 * static_cast<double>(scans_taken++)));
    published = model.snapshot();
    clusters += static_cast<double>(model.cluster_count());
  }
  benchmark::DoNotOptimize(published);
  state.counters["points/scan"] = mean_points_per_scan();
  state.counters["clusters"] = clusters / static_cast<double>(state.iterations());
  state.counters["scans/s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK_CAPTURE(BM_UpdatePerScan, cumulative, PtemConstruction::kCumulative)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_UpdatePerScan, single_scan, PtemConstruction::kSingleScan)->Unit(benchmark::kMicrosecond);

// Threat value (and value + gradient) at random points around the robot's path.
void BM_ThreatQuery(benchmark::State& state, PtemConstruction construction, bool with_gradient) {
  std::uint64_t scans_taken = 0;
  const std::shared_ptr<const PtemSnapshot> snapshot = warmed_up_model(construction, scans_taken).snapshot();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(0.0, 3.0);
  std::vector<Eigen::Vector2d> queries(1024);
  for (Eigen::Vector2d& q : queries) q = Eigen::Vector2d(coordinate(rng), coordinate(rng));
  std::size_t next = 0;
  for (auto _ : state) {
    const Eigen::Vector2d& q = queries[next++ % queries.size()];
    if (with_gradient) {
      benchmark::DoNotOptimize(snapshot->threat_and_gradient(q));
    } else {
      benchmark::DoNotOptimize(snapshot->threat(q));
    }
  }
  state.counters["clusters"] = static_cast<double>(snapshot->clusters().size());
}
BENCHMARK_CAPTURE(BM_ThreatQuery, single_scan, PtemConstruction::kSingleScan, false);
BENCHMARK_CAPTURE(BM_ThreatQuery, single_scan_gradient, PtemConstruction::kSingleScan, true);
BENCHMARK_CAPTURE(BM_ThreatQuery, cumulative, PtemConstruction::kCumulative, false);
BENCHMARK_CAPTURE(BM_ThreatQuery, cumulative_gradient, PtemConstruction::kCumulative, true);

}  // namespace
}  // namespace occgeo::mapping

BENCHMARK_MAIN();
