// Collision and clearance with the default models answer against matter. A simulated UGV maps a world with its
// URG-04LX from several viewpoints, fed in-process to a real ServerCore; then every free pose at least one footprint
// radius from all occupied grid cells, octree voxels and PTEM cluster extents must be neither a hit nor at clearance 0.
// Worlds: the simulator's room world and seeded random worlds of boxes and thin walls.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "fake_session.h"
#include "occgeo/geometry/footprint.h"
#include "occgeo/sim/laser.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/sim_world.h"
#include "test_robots.h"

namespace occgeo::service {
namespace {

const sim::RobotPreset& ugv() { return *sim::find_robot_preset("ugv"); }

// A random world of 0.1 m pixels, 9 m x 7 m inside a 0.2 m wall, with boxes 0.3-1.2 m a side and thin walls 0.1 m
// thick and 1-3 m long, none within 1 m of the centre (where the robot starts).
sim::World random_world(std::uint32_t seed) {
  constexpr int kWidth = 94, kHeight = 74;
  std::vector<std::string> rows(kHeight, std::string(kWidth, '.'));
  const auto mark = [&](int col0, int row0, int cols, int rows_n) {
    for (int r = std::max(0, row0); r < std::min(kHeight, row0 + rows_n); ++r) {
      for (int c = std::max(0, col0); c < std::min(kWidth, col0 + cols); ++c) {
        rows[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)] = '#';
      }
    }
  };
  mark(0, 0, kWidth, 2);
  mark(0, kHeight - 2, kWidth, 2);
  mark(0, 0, 2, kHeight);
  mark(kWidth - 2, 0, 2, kHeight);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> col_of(4, kWidth - 16), row_of(4, kHeight - 16), box_side(3, 12),
      wall_length(10, 30), kind(0, 2);
  for (int placed = 0, tries = 0; placed < 10 && tries < 200; ++tries) {
    int cols = box_side(rng), rows_n = box_side(rng);
    if (kind(rng) == 0) {
      // A thin wall, across or along.
      if (rng() % 2 == 0) {
        cols = wall_length(rng);
        rows_n = 1;
      } else {
        cols = 1;
        rows_n = wall_length(rng);
      }
    }
    const int col0 = col_of(rng), row0 = row_of(rng);
    // Keep the centre (pixels 37..57 x 27..47, i.e. within 1 m) free.
    if (col0 < 57 && col0 + cols > 37 && row0 < 47 && row0 + rows_n > 27) continue;
    mark(col0, row0, cols, rows_n);
    ++placed;
  }
  std::vector<std::string_view> views(rows.begin(), rows.end());
  return sim::World::from_rows(views, 0.1, {-4.7, -3.7});
}

class PhysicalAnswers : public ::testing::Test {
 protected:
  PhysicalAnswers() : core_(config()) {}

  static ServerConfig config() {
    ServerConfig config;
    config.octomap.min_publish_interval_s = 0.0;  // every scan publishes the octree: the test reads it at once
    return config;
  }

  // Drives the simulated UGV's laser over the world from a lattice of free viewpoints, four headings each.
  void map(const sim::SimWorld& world, double x_min, double x_max, double y_min, double y_max) {
    driver_ = testing::driver_session(core_, "ugv-1", sim::make_robot_spec(ugv()));
    sim::LaserSimulator laser(*ugv().laser(), 5);
    std::uint64_t seq = 0;
    double stamp = 0.0;
    int viewpoints = 0;
    for (double x = x_min; x <= x_max + 1e-9; x += 1.5) {
      for (double y = y_min; y <= y_max + 1e-9; y += 1.5) {
        for (int turn = 0; turn < 4; ++turn) {
          const geometry::Pose2 X_WB{x, y, turn * M_PI / 2 + 0.3};
          // Viewpoints with the body (grown by 0.3 m) in an obstacle are skipped: a robot could not stand there.
          geometry::BoxFootprint grown = ugv().footprint;
          grown.length += 0.6;
          grown.width += 0.6;
          if (world.find_collision(grown, X_WB, stamp)) continue;
          if (turn == 0) ++viewpoints;
          stamp += 0.1;
          v1::Odometry odometry = testing::odometry(X_WB.x, X_WB.y, X_WB.theta, stamp);
          handle_odometry(driver_, odometry);
          const sim::SimulatedScan scan = laser.scan(world, X_WB, stamp);
          handle_laser_scan(
              driver_, sim::make_laser_scan_message(ugv().laser()->name, ++seq, stamp, scan.ranges_m).laser_scan());
          ASSERT_TRUE(driver_->next_of(v1::ServerMessage::kScanAck)) << "no ack of scan " << seq;
        }
      }
    }
    std::printf("mapped from %d viewpoints, %llu scans\n", viewpoints, static_cast<unsigned long long>(seq));
    ASSERT_GE(viewpoints, 6);
  }

  // Distance from p_W to the nearest matter the default models hold: occupied grid cells and octree voxels in the
  // footprint's height band (both as their bounding circles) and the PTEM clusters' extents.
  [[nodiscard]] double matter_distance(const WorldSnapshot& snapshot, const Eigen::Vector2d& p_W) const {
    double d = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector2d& c : cells_) d = std::min(d, (c - p_W).norm() - cell_half_diagonal_);
    for (const auto& [c, half_diagonal] : voxels_) d = std::min(d, (c - p_W).norm() - half_diagonal);
    for (const mapping::PtemCluster& cluster : snapshot.ptem->clusters()) {
      for (const Eigen::Vector2d& q : cluster.extent_W) d = std::min(d, (q - p_W).norm());
    }
    return d;
  }

  void collect_matter(const WorldSnapshot& snapshot) {
    cells_.clear();
    voxels_.clear();
    const double cell = snapshot.grid->cell_size();
    cell_half_diagonal_ = cell * M_SQRT1_2;
    snapshot.grid->for_each_occupied({-100000, -100000}, {100000, 100000}, [&](const geometry::CellIndex& c) {
      cells_.emplace_back((c.ix + 0.5) * cell, (c.iy + 0.5) * cell);
      return true;
    });
    snapshot.octomap->for_each_occupied({-1000, -1000, 0.0}, {1000, 1000, ugv().footprint.height},
                                        [&](const mapping::OctoVoxel& v) {
                                          voxels_.emplace_back(v.center_W.head<2>(), v.size_m * M_SQRT1_2);
                                          return true;
                                        });
  }

  // A collision or clearance query for the test's robot at X_WB against models (empty: the defaults).
  template <typename Query>
  void fill(Query& query, const geometry::Pose2& X_WB, const std::vector<v1::Model>& models) {
    query.set_robot_id("ugv-1");
    query.mutable_pose()->set_x(X_WB.x);
    query.mutable_pose()->set_y(X_WB.y);
    query.mutable_pose()->set_theta(X_WB.theta);
    for (const auto m : models) query.add_models(m);
  }

  v1::CollisionReply collide(const geometry::Pose2& X_WB, const std::vector<v1::Model>& models = {}) {
    v1::CollisionQuery query;
    fill(query, X_WB, models);
    handle_collision_query(querier_, ++request_id_, query);
    const auto reply = querier_->next();
    EXPECT_TRUE(reply && reply->has_collision()) << (reply ? reply->DebugString() : "no reply");
    return reply && reply->has_collision() ? reply->collision() : v1::CollisionReply{};
  }

  v1::ClearanceReply clearance(const geometry::Pose2& X_WB, const std::vector<v1::Model>& models = {}) {
    v1::ClearanceQuery query;
    fill(query, X_WB, models);
    handle_clearance_query(querier_, ++request_id_, query);
    const auto reply = querier_->next();
    EXPECT_TRUE(reply && reply->has_clearance()) << (reply ? reply->DebugString() : "no reply");
    return reply && reply->has_clearance() ? reply->clearance() : v1::ClearanceReply{};
  }

  void open_querier() {
    querier_ = std::make_shared<FakeSession>(core_);
    handle_hello(querier_, testing::hello_message(v1::ROLE_QUERY));
    ASSERT_TRUE(querier_->next_of(v1::ServerMessage::kWelcome));
  }

  // Random poses in the box until 200 of them lie at least the footprint's bounding radius from matter: none may be a
  // hit or at clearance 0, and each clearance is at least its pose's matter distance less that radius. Some of them
  // lie in the PTEM's keep-out near walls: it is reported beside the answer, never as a contact.
  void expect_free_poses_are_free(const std::string& name, std::uint32_t seed, double x_min, double x_max, double y_min,
                                  double y_max) {
    const WorldSnapshot snapshot = core_.world("default")->snapshots();
    ASSERT_GT(snapshot.grid->occupied_cell_count(), 0U);
    ASSERT_FALSE(snapshot.ptem->clusters().empty());
    collect_matter(snapshot);
    const double radius = geometry::bounding_radius(geometry::Footprint{ugv().footprint});
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> x_of(x_min, x_max), y_of(y_min, y_max), theta_of(-M_PI, M_PI);
    int tested = 0, keep_out = 0, samples = 0;
    double smallest = std::numeric_limits<double>::infinity();
    for (; tested < 200 && samples < 20000; ++samples) {
      const geometry::Pose2 X_WB{x_of(rng), y_of(rng), theta_of(rng)};
      const double matter_m = matter_distance(snapshot, X_WB.position());
      if (matter_m < radius) continue;
      ++tested;
      const v1::CollisionReply hit = collide(X_WB);
      EXPECT_FALSE(hit.hit()) << name << " at (" << X_WB.x << ", " << X_WB.y << ", " << X_WB.theta << "), " << matter_m
                              << " m from matter: " << hit.DebugString();
      const v1::ClearanceReply room = clearance(X_WB);
      EXPECT_GT(room.clearance_m(), 0.0) << name << " at (" << X_WB.x << ", " << X_WB.y << "): " << room.DebugString();
      EXPECT_GE(room.clearance_m(), matter_m - radius - 1e-6)
          << name << " at (" << X_WB.x << ", " << X_WB.y << "): " << room.DebugString();
      smallest = std::min(smallest, room.clearance_m());
      if (room.keep_out()) ++keep_out;
    }
    std::printf("%s: %d free poses of %d samples, none a hit; smallest clearance %.3f m; %d inside the keep-out\n",
                name.c_str(), tested, samples, smallest, keep_out);
    EXPECT_EQ(tested, 200) << name;
    EXPECT_GT(keep_out, 0) << name << ": no free pose near a wall reached into the keep-out";
  }

  ServerCore core_;
  std::shared_ptr<FakeSession> driver_;
  std::shared_ptr<FakeSession> querier_;
  std::uint64_t request_id_ = 0;
  std::vector<Eigen::Vector2d> cells_;
  std::vector<std::pair<Eigen::Vector2d, double>> voxels_;
  double cell_half_diagonal_ = 0.0;
};

TEST_F(PhysicalAnswers, RoomWorldFreePosesAreFreeAndClearanceNearAWallMatchesTheGrid) {
  const auto world = sim::load_sim_world(std::string(OCCGEO_SOURCE_DIR) + "/clients/sim/worlds/room.yaml");
  map(*world, -4.0, 4.0, -3.0, 3.0);
  open_querier();
  expect_free_poses_are_free("room", 19, -4.8, 4.8, -3.8, 3.8);

  // The UGV at (2.0, 1.0), half a metre from the box at (3, 2): the default models agree with the grid to a cell.
  const geometry::Pose2 X_WB{2.0, 1.0, 0.0};
  const v1::ClearanceReply grid = clearance(X_WB, {v1::MODEL_GRID});
  const v1::ClearanceReply all = clearance(X_WB);
  const double cell = core_.world("default")->snapshots().grid->cell_size();
  std::printf("room (2.0, 1.0): grid %.3f m, default models %.3f m (answered by model %d), keep-out %.3f m\n",
              grid.clearance_m(), all.clearance_m(), static_cast<int>(all.model()), all.restricted_clearance_m());
  ASSERT_TRUE(grid.found());
  EXPECT_GT(grid.clearance_m(), 0.3);
  EXPECT_NEAR(all.clearance_m(), grid.clearance_m(), cell);
  EXPECT_FALSE(collide(X_WB).hit());
}

class PhysicalAnswersRandomWorld : public PhysicalAnswers, public ::testing::WithParamInterface<std::uint32_t> {};

TEST_P(PhysicalAnswersRandomWorld, FreePosesAreFree) {
  const std::uint32_t seed = GetParam();
  const sim::PixelWorld world(random_world(seed));
  map(world, -3.5, 3.5, -2.5, 2.5);
  open_querier();
  expect_free_poses_are_free("random world " + std::to_string(seed), 100 + seed, -4.4, 4.4, -3.4, 3.4);
}

INSTANTIATE_TEST_SUITE_P(Seeds, PhysicalAnswersRandomWorld, ::testing::Values(1U, 2U, 3U, 4U));

}  // namespace
}  // namespace occgeo::service
