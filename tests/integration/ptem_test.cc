// Seed 004 §5–6 against the real server and simulator: the ugv preset (Hokuyo URG-04LX, 240°, 4 m) in lockstep on
// the shipped PTEM worlds, driven by --drive scripts (server commands ignored), then the server's PTEM is queried
// over the protocol. Prints what it measures (coverage of the obstacle's disc by the restricted region, σ histories
// as in Fig 6.2) and asserts what holds.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "../support/process.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

struct Obstacle {
  std::string name;
  std::string world_file;
  double x, y, radius_m;
};

const Obstacle kThin{"thin", "clients/sim/worlds/ptem_thin.yaml", 1.75, 0.0, 0.055};
const Obstacle kCone{"cone", "clients/sim/worlds/ptem_cone.yaml", 1.75, 0.0, 0.15};
constexpr double kApproachRadius_m = 0.15;  // ptem_approaching.yaml: the cone, from (3.3, 0) towards (0, 0)
constexpr double kApproachSpeed_mps = 0.1;

// World names ending in "_cum" build the cumulative PTEM (seed §4.2.2), every other one the single-scan PTEM
// (§4.2.3, the server's default); listed explicitly through the per-world overrides of the config.
std::string server_config(const std::vector<std::string>& cumulative_worlds) {
  std::ostringstream yaml;
  yaml << "ptem:\n  construction: single_scan\n  worlds:\n";
  // The seed's cumulative construction lets a cluster grow without bound (§4.2.2): that growth is what is measured.
  for (const std::string& world : cumulative_worlds) {
    yaml << "    " << world << ": {construction: cumulative, max_cluster_radius_m: 0}\n";
  }
  return yaml.str();
}

class PtemScenario : public ::testing::Test {
 protected:
  void start_server(const std::vector<std::string>& cumulative_worlds) {
    const auto config = dir_.path() / "occgeod.yaml";
    std::ofstream(config) << server_config(cumulative_worlds);
    server_ = std::make_unique<ServerProcess>(dir_.path() / "data", std::vector<std::string>{"--config", config});
    query_ = std::make_unique<client::Connection>(open_query_session(server_->address()));
  }

  void SetUp() override { std::filesystem::create_directories(dir_.path() / "data"); }

  // Runs the simulator in lockstep to completion; the robot follows `drive` and ignores the server's commands.
  void run_sim(const std::string& world_file, const std::string& world_name, const std::string& start,
               double duration_s, const std::string& drive, int seed = 1) {
    std::ostringstream duration;
    duration << duration_s;
    const std::vector<std::string> argv = {binary("clients/sim/occgeo-sim").string(),
                                           "--world",
                                           source(world_file).string(),
                                           "--robot",
                                           "ugv",
                                           "--id",
                                           "ugv-" + world_name,
                                           "--world-name",
                                           world_name,
                                           "--server",
                                           server_->address(),
                                           "--start",
                                           start,
                                           "--lockstep",
                                           "--duration",
                                           duration.str(),
                                           "--drive",
                                           drive,
                                           "--seed",
                                           std::to_string(seed),
                                           "--json"};
    const ProcessResult result = run_process(argv, std::chrono::seconds(120));
    ASSERT_EQ(result.exit_code, 0) << result.err << result.out;
    EXPECT_NE(result.out.find("\"collisions\": 0"), std::string::npos) << result.out;
  }

  // A PtemQuery over the wire; its reply (or Error) is matched here by the envelope's request_id.
  v1::PtemReply ptem(const std::string& world, const std::vector<Eigen::Vector2d>& points, bool include_clusters) {
    const std::uint64_t id = ++request_id_;
    v1::ClientMessage request;
    request.set_request_id(id);
    auto* query = request.mutable_ptem();
    query->set_world(world);
    query->set_include_clusters(include_clusters);
    for (const Eigen::Vector2d& p : points) {
      auto* point = query->add_points();
      point->set_x(p.x());
      point->set_y(p.y());
    }
    query_->send(request);
    for (int i = 0; i < 100; ++i) {
      const auto reply = query_->receive(std::chrono::seconds(10));
      if (!reply) break;
      if (reply->has_error() && reply->request_id() == id) {
        ADD_FAILURE() << client::describe(reply->error());
        return {};
      }
      if (reply->has_ptem() && reply->request_id() == id) return reply->ptem();
    }
    ADD_FAILURE() << "no PtemReply to request " << id;
    return {};
  }

  // Fraction of the disc (cx, cy, r) that the world's PTEM restricts, on a 2.5 mm lattice.
  double restricted_fraction(const std::string& world, double cx, double cy, double r) {
    constexpr double kStep = 0.0025;
    std::vector<Eigen::Vector2d> points;
    const int n = static_cast<int>(std::ceil(r / kStep));
    for (int i = -n; i <= n; ++i) {
      for (int j = -n; j <= n; ++j) {
        const Eigen::Vector2d d(i * kStep, j * kStep);
        if (d.norm() <= r) points.emplace_back(cx + d.x(), cy + d.y());
      }
    }
    const v1::PtemReply reply = ptem(world, points, false);
    int restricted = 0;
    for (const auto& sample : reply.samples()) restricted += sample.restricted() ? 1 : 0;
    return points.empty() ? 0.0 : static_cast<double>(restricted) / static_cast<double>(points.size());
  }

  // Area (m²) of the restricted region within the box, on a 1 cm lattice.
  double restricted_area(const std::string& world, double x0, double x1, double y0, double y1) {
    constexpr double kStep = 0.01;
    std::vector<Eigen::Vector2d> points;
    for (double x = x0 + kStep / 2; x < x1; x += kStep) {
      for (double y = y0 + kStep / 2; y < y1; y += kStep) points.emplace_back(x, y);
    }
    const v1::PtemReply reply = ptem(world, points, false);
    int restricted = 0;
    for (const auto& sample : reply.samples()) restricted += sample.restricted() ? 1 : 0;
    return restricted * kStep * kStep;
  }

  TempDir dir_;
  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<client::Connection> query_;
  std::uint64_t request_id_ = 0;
};

std::string describe_clusters(const v1::PtemReply& reply) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(4);
  for (const auto& c : reply.clusters()) {
    out << " [centre (" << c.center().x() << ", " << c.center().y() << ") R " << c.radius_m() << " σ " << c.sigma_m()
        << " age " << c.age_scans() << " scans/" << c.age_s() << " s]";
  }
  return out.str();
}

// Seed §5.1 (Fig 5.1, 5.3): the thin obstacle and the cone, stationary, under both constructions, seen
//   - with the robot standing still at the origin for 5 s, five noise seeds each, and
//   - with the robot driving past at 0.2 m/s from (0, −0.6) heading +x: after 5 s (approaching, x = 1.0), 8 s
//     (beside it, x = 1.6) and 15 s (past it, x = 3.0, the obstacle behind the URG's 240° field of view).
TEST_F(PtemScenario, StationaryObstacleIsOneClusterCoveringTheObstacle) {
  struct Run {
    const Obstacle* obstacle;
    std::string motion, start, drive;
    double duration_s;
    int seed;
  };
  std::vector<Run> runs;
  for (const Obstacle* obstacle : {&kThin, &kCone}) {
    for (int seed = 1; seed <= 5; ++seed) runs.push_back({obstacle, "still", "0,0,0", "0,0,5", 5.0, seed});
    for (const double t : {5.0, 8.0, 15.0}) runs.push_back({obstacle, "past", "0,-0.6,0", "0.2,0,15", t, 1});
  }
  const auto world_name = [](const Run& run, const std::string& construction) {
    std::ostringstream name;
    name << run.obstacle->name << "_" << run.motion << "_" << (run.motion == "still" ? "seed" : "t")
         << (run.motion == "still" ? run.seed : static_cast<int>(run.duration_s)) << "_" << construction;
    return name.str();
  };
  std::vector<std::string> cumulative;
  for (const Run& run : runs) cumulative.push_back(world_name(run, "cum"));
  start_server(cumulative);

  std::cout << "\nstationary obstacles: fraction of the obstacle's disc the PTEM restricts\n";
  std::map<std::string, std::vector<double>> still_fractions;  // "thin cumulative" -> per seed
  for (const Run& run : runs) {
    for (const std::string construction : {"cum", "ss"}) {
      const std::string world = world_name(run, construction);
      SCOPED_TRACE(world);
      run_sim(run.obstacle->world_file, world, run.start, run.duration_s, run.drive, run.seed);
      const v1::PtemReply reply = ptem(world, {}, true);
      const double fraction = restricted_fraction(world, run.obstacle->x, run.obstacle->y, run.obstacle->radius_m);
      std::cout << std::fixed << std::setprecision(3) << "  " << std::setw(24) << std::left << world << std::right
                << " " << std::setw(11) << reply.construction() << "  scans " << std::setw(3) << reply.scans()
                << "  clusters " << reply.cluster_count() << "  restricted fraction " << fraction
                << describe_clusters(reply) << "\n";
      EXPECT_EQ(reply.construction(), construction == "cum" ? "cumulative" : "single_scan");
      const bool behind = run.motion == "past" && run.duration_s > 10.0;
      if (behind && construction == "ss") {
        // Seed §4.2.5, Fig 4.4: the obstacle left the field of view sideways, last seen by the edge beams; the
        // single-scan construction retains that last cluster (partly outside the sector and not re-observed).
        EXPECT_EQ(reply.cluster_count(), 1U) << describe_clusters(reply);
        std::cout << "    single_scan retained the obstacle after it left the 240° field of view: restricted fraction "
                  << fraction << "\n";
        if (reply.clusters_size() < 1) continue;
        const auto& c = reply.clusters(0);
        EXPECT_LT(std::hypot(c.center().x() - run.obstacle->x, c.center().y() - run.obstacle->y),
                  run.obstacle->radius_m + 0.06);
        EXPECT_GT(c.age_scans(), 0U);
        EXPECT_GE(fraction, 0.5);
        continue;
      }
      EXPECT_EQ(reply.cluster_count(), 1U) << describe_clusters(reply);
      if (reply.clusters_size() < 1) continue;
      const auto& c = reply.clusters(0);
      // The cluster sits on the obstacle: its centre within the obstacle's disc widened by the laser's 3σ noise.
      EXPECT_LT(std::hypot(c.center().x() - run.obstacle->x, c.center().y() - run.obstacle->y),
                run.obstacle->radius_m + 0.06);
      // The restricted region covers the obstacle: the cluster starts on its near side with the preset radius (0.25 m),
      // which reaches across both; only the cone's far rim, never seen, may poke out by a few millimetres.
      EXPECT_GE(fraction, run.obstacle->radius_m < 0.1 ? 0.999 : 0.95);
      if (run.motion == "still") {
        still_fractions[run.obstacle->name + " " + reply.construction()].push_back(fraction);
      }
    }
  }
  std::cout << "standing still, over 5 seeds:\n";
  for (const auto& [key, fractions] : still_fractions) {
    double sum = 0.0, low = 1.0;
    for (const double f : fractions) {
      sum += f;
      low = std::min(low, f);
    }
    const double mean = sum / static_cast<double>(fractions.size());
    std::cout << std::fixed << std::setprecision(3) << "  " << std::setw(22) << std::left << key << std::right
              << " mean restricted fraction " << mean << "  min " << low << "\n";
    // From one viewpoint the returns lie on less than the near half of the circle; the preset radius carries the
    // cluster over the rest.
    EXPECT_GE(mean, 0.98) << key;
  }
}

// Seed §6.1.1 (Fig 6.1, 6.2): the cone approaching the standing robot at 0.1 m/s from (3.3, 0). The simulator is run
// once per duration 1, 2, …, 10 s, each in a world of its own (deterministic: same seed, same start, so each run is a
// prefix of the next), and the PTEM queried after each: the cumulative construction's restricted region grows with
// time, the single-scan one stays the size of the obstacle.
TEST_F(PtemScenario, ApproachingObstacleGrowsTheCumulativeMapOnly) {
  constexpr int kSeconds = 10;
  std::vector<std::string> cumulative;
  for (int t = 1; t <= kSeconds; ++t) cumulative.push_back("approach_" + std::to_string(t) + "_cum");
  start_server(cumulative);
  const double disc_area = M_PI * kApproachRadius_m * kApproachRadius_m;

  struct Row {
    double sigma = 0, radius = 0, cx = 0, cy = 0, area = 0;
    unsigned clusters = 0;
  };
  std::vector<Row> cum(kSeconds + 1), ss(kSeconds + 1);
  for (int t = 1; t <= kSeconds; ++t) {
    for (const std::string construction : {"cum", "ss"}) {
      const std::string world = "approach_" + std::to_string(t) + "_" + construction;
      run_sim("clients/sim/worlds/ptem_approaching.yaml", world, "0,0,0", t, "0,0,1");
      const v1::PtemReply reply = ptem(world, {}, true);
      Row row;
      row.clusters = reply.cluster_count();
      for (const auto& c : reply.clusters()) {
        if (c.sigma_m() > row.sigma) {
          row.sigma = c.sigma_m();
          row.radius = c.radius_m();
          row.cx = c.center().x();
          row.cy = c.center().y();
        }
      }
      row.area = restricted_area(world, 0.0, 4.0, -1.0, 1.0);
      (construction == "cum" ? cum : ss)[static_cast<std::size_t>(t)] = row;
    }
  }

  std::cout << "\napproaching cone (r = 0.15 m, 0.1 m/s from x = 3.3): PTEM after t s of sim time (cf. seed Fig 6.2)\n"
            << "   t  obstacle_x | cumulative: clusters  mean_x   mean_y   R       sigma   area/disc"
            << " | single_scan: clusters  mean_x   mean_y   R       sigma   area/disc\n";
  for (int t = 1; t <= kSeconds; ++t) {
    const Row& c = cum[static_cast<std::size_t>(t)];
    const Row& s = ss[static_cast<std::size_t>(t)];
    std::cout << std::fixed << std::setprecision(3) << std::setw(4) << t << "  " << std::setw(10)
              << 3.3 - kApproachSpeed_mps * t << " | " << std::setw(20) << c.clusters << "  " << c.cx << "  "
              << std::setw(7) << c.cy << "  " << c.radius << "  " << c.sigma << "  " << std::setw(9)
              << c.area / disc_area << " | " << std::setw(21) << s.clusters << "  " << s.cx << "  " << std::setw(7)
              << s.cy << "  " << s.radius << "  " << s.sigma << "  " << std::setw(9) << s.area / disc_area << "\n";
  }

  for (int t = 1; t <= kSeconds; ++t) {
    SCOPED_TRACE("t = " + std::to_string(t) + " s");
    const Row& c = cum[static_cast<std::size_t>(t)];
    const Row& s = ss[static_cast<std::size_t>(t)];
    EXPECT_EQ(c.clusters, 1U);
    EXPECT_EQ(s.clusters, 1U);
    // Single scan: the obstacle as it is now, the cluster no larger than twice the obstacle.
    EXPECT_LE(s.radius, 2.0 * kApproachRadius_m);
    EXPECT_LE(s.area, 4.0 * disc_area);
    EXPECT_NEAR(s.cx, 3.3 - kApproachSpeed_mps * t - kApproachRadius_m / 2, 0.15);
    if (t > 1) {
      // Cumulative: every cluster only grows, so σ and the restricted area never shrink (1 cm² lattice tolerance).
      const Row& before = cum[static_cast<std::size_t>(t - 1)];
      EXPECT_GE(c.sigma, before.sigma - 1e-12);
      EXPECT_GE(c.area, before.area - 2e-4);
    }
  }
  // Over 10 s the cone moved 1 m: the cumulative circle spans the whole track, far beyond the obstacle.
  EXPECT_GT(cum[kSeconds].area, 4.0 * cum[1].area);
  EXPECT_GT(cum[kSeconds].radius, 0.5);
  EXPECT_GT(cum[kSeconds].sigma, 2.0 * ss[kSeconds].sigma);
}

}  // namespace
}  // namespace occgeo::testing
