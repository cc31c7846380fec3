// The height band layer: a depth sensor's cloud of a kerb and an overhang (seed 000 Fig 5.2) inserted into a real
// OctoMap blocks the straight way and bends the global path round them for a robot of the Bearcat's height, while the
// floor's returns and an overhang above the robot's top do not; with no octree the planner is the grid's own.
#include "height_band_layer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "occgeo/mapfile/map_file.h"
#include "occgeo/mapping/himm_grid.h"
#include "occgeo/service/control/behaviour.h"

namespace occgeo::service::control {
namespace {

constexpr double kBearcatHeight_m = 1.2;

// A box of material [x0, x1] x [y0, y1] x [z0, z1] as the points a dense sensor would return from its faces, and the
// floor z = 0 around it, sampled every 2 cm, in the world frame.
void add_box(std::vector<Eigen::Vector3f>& points, Eigen::Vector3d lo, Eigen::Vector3d hi) {
  constexpr double kStep = 0.02;
  for (double x = lo.x(); x <= hi.x() + 1e-9; x += kStep) {
    for (double y = lo.y(); y <= hi.y() + 1e-9; y += kStep) {
      for (double z = lo.z(); z <= hi.z() + 1e-9; z += kStep) {
        const bool face = x - lo.x() < kStep || hi.x() - x < kStep || y - lo.y() < kStep || hi.y() - y < kStep ||
                          z - lo.z() < kStep || hi.z() - z < kStep;
        if (face) points.emplace_back(Eigen::Vector3d(x, y, z).cast<float>());
      }
    }
  }
}

void add_floor(std::vector<Eigen::Vector3f>& points, double x0, double x1, double y0, double y1) {
  for (double x = x0; x <= x1; x += 0.04) {
    for (double y = y0; y <= y1; y += 0.04) points.emplace_back(Eigen::Vector3d(x, y, 0.0).cast<float>());
  }
}

// An octree of the points seen by a sensor 1.1 m above the origin (so every ray crosses free space first).
std::shared_ptr<const mapping::OctoMapSnapshot> octree_of(const std::vector<Eigen::Vector3f>& points_W) {
  mapping::OctoMapParams params;
  params.outlier_filter_enabled = false;
  mapping::OctoMapModel model(params);
  const geometry::Pose3 X_WS = geometry::Pose3::from_xyz_rpy(0.0, 0.0, 1.1, 0.0, 0.0, 0.0);
  std::vector<Eigen::Vector3f> points_S;
  for (const Eigen::Vector3f& p : points_W) points_S.emplace_back(p - Eigen::Vector3f(0.0F, 0.0F, 1.1F));
  model.insert_cloud(X_WS, points_S);
  return model.publish();
}

// A grid of the area that knows nothing yet: every cell unobserved.
std::shared_ptr<const mapping::GridSnapshot> unknown_grid() {
  return mapping::HimmGrid(mapping::HimmParams{}).snapshot();
}

// The kerb and the overhang of clients/sim/worlds/short_and_overhang.yaml, with the floor around them.
std::vector<Eigen::Vector3f> kerb_and_overhang(double overhang_base_m) {
  std::vector<Eigen::Vector3f> points;
  add_floor(points, 0.5, 6.0, -2.0, 2.0);
  add_box(points, {1.8, -0.5, 0.0}, {2.2, 0.5, 0.3});
  add_box(points, {3.8, -0.75, overhang_base_m}, {4.2, 0.75, overhang_base_m + 0.3});
  return points;
}

TEST(HeightBandLayer, KerbAndOverhangBlockTheStraightWayButNotTheWayBeside) {
  const auto octree = octree_of(kerb_and_overhang(0.9));
  const HeightBandLayer band(*octree, kBearcatHeight_m);
  EXPECT_FALSE(band.segment_clear({0.0, 0.0}, {6.0, 0.0}, 0.4));
  EXPECT_FALSE(band.segment_clear({0.0, 0.0}, {3.0, 0.0}, 0.4)) << "the kerb alone";
  EXPECT_FALSE(band.segment_clear({3.0, 0.0}, {6.0, 0.0}, 0.4)) << "the overhang alone";
  EXPECT_TRUE(band.segment_clear({0.0, 1.3}, {6.0, 1.3}, 0.4)) << "beside both, 0.4 m clear of the overhang";
  EXPECT_FALSE(band.segment_clear({0.0, 1.1}, {6.0, 1.1}, 0.4)) << "within 0.4 m of the overhang's side";
  EXPECT_TRUE(band.segment_clear({0.0, 0.0}, {1.2, 0.0}, 0.4)) << "short of the kerb";
}

TEST(HeightBandLayer, FloorAndWhatIsAboveTheRobotDoNotBlock) {
  std::vector<Eigen::Vector3f> floor;
  add_floor(floor, 0.5, 6.0, -2.0, 2.0);
  const auto floor_only = octree_of(floor);
  EXPECT_GT(floor_only->leaf_count(), 0U);
  EXPECT_TRUE(HeightBandLayer(*floor_only, kBearcatHeight_m).segment_clear({0.0, 0.0}, {6.0, 0.0}, 0.4));
  // The overhang lifted to 1.5 m: a 1.2 m robot passes under it; a 1.6 m one does not.
  const auto high = octree_of(kerb_and_overhang(1.5));
  EXPECT_TRUE(HeightBandLayer(*high, kBearcatHeight_m).segment_clear({3.0, 0.0}, {6.0, 0.0}, 0.4));
  EXPECT_FALSE(HeightBandLayer(*high, 1.6).segment_clear({3.0, 0.0}, {6.0, 0.0}, 0.4));
}

TEST(HeightBandLayer, MarksTheCellsOfTheColumnsInThePlanningWindow) {
  const auto octree = octree_of(kerb_and_overhang(0.9));
  PlanningWindow window;
  window.origin = {0, -20};
  window.width = 60;
  window.height = 40;
  window.cell_size_m = 0.1;
  window.cells.assign(static_cast<std::size_t>(window.width * window.height), PlanningCell::kFree);
  EXPECT_GT(HeightBandLayer(*octree, kBearcatHeight_m).mark_occupied(window), 0U);
  const auto at = [&](double x, double y) {
    const int col = static_cast<int>(std::floor(x / 0.1)) - window.origin.ix;
    const int row = static_cast<int>(std::floor(y / 0.1)) - window.origin.iy;
    return window.cells[static_cast<std::size_t>(row * window.width + col)];
  };
  EXPECT_EQ(at(1.85, 0.0), PlanningCell::kOccupied) << "the kerb's near face";
  EXPECT_EQ(at(3.85, 0.6), PlanningCell::kOccupied) << "the overhang's near face";
  EXPECT_EQ(at(1.0, 0.0), PlanningCell::kFree) << "the floor before the kerb";
  EXPECT_EQ(at(3.0, 1.5), PlanningCell::kFree) << "the floor beside";
  // Nothing spills beyond the obstacles' squares: every marked cell's square touches the kerb or the overhang.
  for (int row = 0; row < window.height; ++row) {
    for (int col = 0; col < window.width; ++col) {
      if (window.cells[static_cast<std::size_t>(row * window.width + col)] != PlanningCell::kOccupied) continue;
      const double x0 = (window.origin.ix + col) * 0.1;
      const double y0 = (window.origin.iy + row) * 0.1;
      const bool kerb = x0 + 0.1 > 1.75 && x0 < 2.25 && y0 + 0.1 > -0.55 && y0 < 0.55;
      const bool overhang = x0 + 0.1 > 3.75 && x0 < 4.25 && y0 + 0.1 > -0.8 && y0 < 0.8;
      EXPECT_TRUE(kerb || overhang) << "cell at (" << x0 << ", " << y0 << ")";
    }
  }
}

TEST(HeightBandLayer, GlobalPathGoesRoundWhatOnlyTheOctreeHolds) {
  const auto grid = unknown_grid();
  const auto octree = octree_of(kerb_and_overhang(0.9));
  const HeightBandLayer band(*octree, kBearcatHeight_m);
  GlobalPathParams params;
  params.footprint_radius_m = 0.4;
  params.unknown_extra_cost = 0.0;
  const Eigen::Vector2d start(0.0, 0.0), goal(6.0, 0.0);
  const GlobalPathResult without = plan_global_path(*grid, nullptr, start, goal, params);
  ASSERT_EQ(without.status, GlobalPathStatus::kFound);
  EXPECT_EQ(without.waypoints_W.size(), 2U) << "the grid alone sees nothing: straight";
  const GlobalPathResult with = plan_global_path(*grid, &band, start, goal, params);
  ASSERT_EQ(with.status, GlobalPathStatus::kFound);
  EXPECT_GT(with.waypoints_W.size(), 2U);
  double farthest_aside = 0.0;
  for (std::size_t i = 0; i + 1 < with.waypoints_W.size(); ++i) {
    EXPECT_TRUE(band.segment_clear(with.waypoints_W[i], with.waypoints_W[i + 1], 0.4 - 1e-6)) << "segment " << i;
    farthest_aside = std::max(farthest_aside, std::abs(with.waypoints_W[i].y()));
  }
  EXPECT_GT(farthest_aside, 0.75 + 0.4);
  EXPECT_THROW((void)band.segment_clear({0.0, 0.0}, {1.0, 0.0}, -1.0), std::invalid_argument);
}

// goto with the deadlock escape, as the server runs it for the Bearcat: the laser sees nothing (the kerb and the
// overhang are off its plane), the grid knows nothing, the octree holds both. The look-ahead sees the straight way
// blocked at once, and the robot, driven as a unicycle, follows a path round both to the goal.
TEST(HeightBandLayer, GotoEscapeDrivesRoundWhatOnlyTheOctreeHolds) {
  RobotShape bearcat;
  bearcat.footprint = geometry::BoxFootprint{.length = 1.0, .width = 0.8, .height = kBearcatHeight_m, .center_x = 0.0};
  bearcat.laser_x_m = 0.45;
  bearcat.max_linear_mps = 1.2;
  const Eigen::Vector2d goal(6.0, 0.0);
  auto go = make_escape([&] { return make_goto(pointbug_params_for(bearcat), goal.x(), goal.y(), 0.1, 0.3); }, bearcat,
                        GuardParams{});
  const std::vector<float> open(181, 8.0F);
  const ScanView scan{-std::numbers::pi / 2, std::numbers::pi / 180, open, 8.0};
  const auto grid = unknown_grid();
  const auto octree = octree_of(kerb_and_overhang(0.9));
  const HeightBandLayer band(*octree, kBearcatHeight_m);
  geometry::Pose2 pose;
  bool reached = false;
  double farthest_aside = 0.0;
  for (int i = 0; i < 600 && !reached; ++i) {
    BehaviourInput input{scan, pose, 0.1 * i, grid.get(), nullptr, octree.get()};
    const BehaviourCommand command = go->decide(input);
    if (i == 0) {
      EXPECT_EQ(command.state, BehaviourState::kEscapeBlocked);
    }
    reached = command.state == BehaviourState::kReached;
    // The body's centre keeps the inscribed radius (0.4 m) from every column of the band.
    EXPECT_TRUE(band.segment_clear({pose.x, pose.y}, {pose.x, pose.y}, 0.4 - 0.05))
        << "at " << pose.x << ", " << pose.y;
    farthest_aside = std::max(farthest_aside, std::abs(pose.y));
    const double theta = pose.theta + command.angular_radps * 0.05;
    pose = {pose.x + command.linear_mps * 0.1 * std::cos(theta), pose.y + command.linear_mps * 0.1 * std::sin(theta),
            geometry::wrap_angle(pose.theta + command.angular_radps * 0.1)};
  }
  EXPECT_TRUE(reached) << "ended at " << pose.x << ", " << pose.y;
  EXPECT_GT(farthest_aside, 0.75 + 0.4);
}

}  // namespace
}  // namespace occgeo::service::control
