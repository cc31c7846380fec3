// The terrain estimate on octrees built from synthetic clouds: a flat floor and a 0.2 m/m ramp to a platform are
// drivable, a 0.15 m kerb, a box standing on the ramp, a wall seen only at a laser's height and the floor under
// something lower than the robot are not, and nothing seen is unknown.
#include "occgeo/mapping/terrain.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace occgeo::mapping {
namespace {

constexpr double kCell_m = 0.1;
constexpr double kRobotHeight_m = 1.2;  // the Bearcat's

using Points = std::vector<Eigen::Vector3f>;

// The surface z = height(x, y) over [x0, x1] x [y0, y1], sampled every 2 cm (denser than the 5 cm voxels).
template <typename Height>
void add_surface(Points& points, double x0, double x1, double y0, double y1, Height height) {
  for (double x = x0; x <= x1 + 1e-9; x += 0.02) {
    for (double y = y0; y <= y1 + 1e-9; y += 0.02) {
      points.emplace_back(Eigen::Vector3d(x, y, height(x, y)).cast<float>());
    }
  }
}

// The faces of the box [lo, hi] a sensor above it sees: its top and its four sides.
void add_box(Points& points, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  constexpr double kStep = 0.02;
  for (double x = lo.x(); x <= hi.x() + 1e-9; x += kStep) {
    for (double y = lo.y(); y <= hi.y() + 1e-9; y += kStep) {
      for (double z = lo.z(); z <= hi.z() + 1e-9; z += kStep) {
        const bool face =
            x - lo.x() < kStep || hi.x() - x < kStep || y - lo.y() < kStep || hi.y() - y < kStep || hi.z() - z < kStep;
        if (face) points.emplace_back(Eigen::Vector3d(x, y, z).cast<float>());
      }
    }
  }
}

// The floor to x = 3, a ramp rising 0.2 m per metre to 0.8 m at x = 7, a platform to x = 9; y in [-1.4, 1.4]
// (clients/sim/worlds/ramp.yaml).
double ramp_height(double x, double /*y*/) { return x < 3.0 ? 0.0 : x < 7.0 ? 0.2 * (x - 3.0) : 0.8; }

void add_ramp(Points& points, double x_end = 9.0) { add_surface(points, 0.0, x_end, -1.4, 1.4, ramp_height); }

// An octree of the points seen from 3 m above (x_sensor, 0), so every ray crosses free space first.
std::shared_ptr<const OctoMapSnapshot> octree_of(const Points& points_W, double x_sensor = 4.5) {
  OctoMapParams params;
  params.outlier_filter_enabled = false;
  OctoMapModel model(params);
  const Eigen::Vector3f sensor_W(static_cast<float>(x_sensor), 0.0F, 3.0F);
  const geometry::Pose3 X_WS = geometry::Pose3::from_xyz_rpy(x_sensor, 0.0, 3.0, 0.0, 0.0, 0.0);
  Points points_S;
  for (const Eigen::Vector3f& p : points_W) points_S.emplace_back(p - sensor_W);
  model.insert_cloud(X_WS, points_S);
  return model.publish();
}

// The terrain of cells x in [0, 9), y in [-1.4, 1.4) for the Bearcat.
TerrainMap terrain_of(const OctoMapSnapshot& octree, const TerrainParams& params = {},
                      std::optional<Eigen::Vector2d> robot_W = std::nullopt) {
  return {octree, kCell_m, {0, -14}, {89, 13}, kRobotHeight_m, params, robot_W};
}

geometry::CellIndex cell_at(double x, double y) {
  return {static_cast<std::int32_t>(std::floor(x / kCell_m)), static_cast<std::int32_t>(std::floor(y / kCell_m))};
}

TEST(Terrain, FlatFloorIsDrivableAndItsReturnsAreTheFloors) {
  Points points;
  add_surface(points, 0.0, 9.0, -1.4, 1.4, [](double, double) { return 0.0; });
  const auto octree = octree_of(points);
  const TerrainMap terrain = terrain_of(*octree);
  for (const double x : {1.0, 4.55, 8.0}) {
    const TerrainCell cell = terrain.cell(cell_at(x, 0.25));
    EXPECT_TRUE(cell.known) << x;
    EXPECT_TRUE(cell.drivable) << x;
    EXPECT_NEAR(cell.surface_m, 0.0, 0.05 + 1e-9) << x;
    EXPECT_LT(cell.slope_rad, 0.05) << x;
    // A return in a floor cell is not the floor's (those are below the ground band): it stays an obstacle.
    EXPECT_FALSE(terrain.explains_returns(cell_at(x, 0.25))) << x;
  }
}

TEST(Terrain, RampOfTwentyPercentAndItsPlatformAreDrivable) {
  Points points;
  add_ramp(points);
  const auto octree = octree_of(points);
  const TerrainMap terrain = terrain_of(*octree);
  for (double x = 0.55; x < 8.8; x += 0.1) {
    for (const double y : {-0.75, 0.05, 0.85}) {
      const TerrainCell cell = terrain.cell(cell_at(x, y));
      ASSERT_TRUE(cell.known) << x << ", " << y;
      EXPECT_TRUE(cell.drivable) << x << ", " << y << ": slope " << cell.slope_rad << " step " << cell.step_m;
      // The surface is the top of the voxels the cell's surface lies in.
      const double highest = ramp_height(std::min(x + 0.05, 7.0), y);
      EXPECT_GE(cell.surface_m, highest - 1e-6) << x;
      EXPECT_LE(cell.surface_m, highest + 0.05 + 1e-6) << x;
      if (x > 3.6 && x < 6.4) {
        EXPECT_NEAR(cell.slope_rad, std::atan(0.2), 0.06) << x;
        EXPECT_TRUE(terrain.explains_returns(cell_at(x, y))) << x;  // the laser plane meets it at 0.6 m
      }
    }
  }
  // Over a drivable surface the robot's band is measured from it: the ramp's own voxels are below it.
  const auto [low, high] = terrain.obstacle_band(cell_at(6.05, 0.05), 0.06, kRobotHeight_m);
  EXPECT_GT(low, terrain.cell(cell_at(6.05, 0.05)).surface_m);
  EXPECT_NEAR(high - low, kRobotHeight_m - 0.01, 1e-9);
}

TEST(Terrain, KerbOfFifteenCentimetresIsAStepNotASlope) {
  Points points;
  add_surface(points, 0.0, 9.0, -1.4, 1.4,
              [](double x, double y) { return x >= 2.0 && x <= 2.4 && std::abs(y) <= 0.5 ? 0.15 : 0.0; });
  add_box(points, {2.0, -0.5, 0.0}, {2.4, 0.5, 0.15});
  const auto octree = octree_of(points, 2.2);
  const TerrainMap terrain = terrain_of(*octree);
  for (double x = 2.05; x < 2.4; x += 0.1) {
    for (double y = -0.45; y < 0.5; y += 0.1) {
      const TerrainCell cell = terrain.cell(cell_at(x, y));
      EXPECT_TRUE(cell.known) << x << ", " << y;
      EXPECT_FALSE(cell.drivable) << x << ", " << y;
      EXPECT_FALSE(terrain.explains_returns(cell_at(x, y))) << x << ", " << y;
      EXPECT_EQ(terrain.obstacle_band(cell_at(x, y), 0.06, kRobotHeight_m), std::make_pair(0.06, kRobotHeight_m));
    }
  }
  // Its edge cells are steps; the floor beyond it is the floor.
  EXPECT_GT(terrain.cell(cell_at(2.05, 0.05)).step_m, 0.08);
  EXPECT_TRUE(terrain.cell(cell_at(3.05, 0.05)).drivable);
}

TEST(Terrain, BoxStandingOnTheRampIsNotPartOfTheSurface) {
  Points points;
  add_surface(points, 0.0, 9.0, -1.4, 1.4, [](double x, double y) {
    return x >= 5.0 && x <= 5.4 && std::abs(y) <= 0.3 ? ramp_height(x, y) + 0.3 : ramp_height(x, y);
  });
  add_box(points, {5.0, -0.3, 0.35}, {5.4, 0.3, ramp_height(5.4, 0.0) + 0.3});
  const auto octree = octree_of(points);
  const TerrainMap terrain = terrain_of(*octree);
  for (double x = 5.05; x < 5.4; x += 0.1) {
    for (double y = -0.25; y < 0.3; y += 0.1) {
      EXPECT_FALSE(terrain.cell(cell_at(x, y)).drivable) << x << ", " << y;
      EXPECT_FALSE(terrain.explains_returns(cell_at(x, y))) << x << ", " << y;
    }
  }
  // The ramp beside it still is drivable.
  EXPECT_TRUE(terrain.cell(cell_at(5.25, 0.85)).drivable);
  EXPECT_TRUE(terrain.cell(cell_at(4.25, 0.05)).drivable);
}

TEST(Terrain, NothingSeenIsUnknown) {
  const auto octree = octree_of({});
  const TerrainMap terrain = terrain_of(*octree, {}, Eigen::Vector2d(4.0, 0.0));
  const TerrainCell cell = terrain.cell(cell_at(4.05, 0.05));
  EXPECT_FALSE(cell.known);
  EXPECT_FALSE(cell.drivable);
  EXPECT_FALSE(terrain.explains_returns(cell_at(4.05, 0.05)));
  EXPECT_EQ(terrain.obstacle_band(cell_at(4.05, 0.05), 0.06, kRobotHeight_m), std::make_pair(0.06, kRobotHeight_m));
  // Outside the estimated region too.
  EXPECT_FALSE(terrain.cell(cell_at(50.0, 0.0)).known);
}

TEST(Terrain, WallSeenOnlyAtALasersHeightCannotBeReached) {
  // A laser plane at 0.6 m maps a thick wall as a level band of voxels: flat, but no floor leads onto it.
  Points points;
  add_surface(points, 4.0, 4.3, -1.4, 1.4, [](double, double) { return 0.6; });
  const auto octree = octree_of(points);
  const TerrainMap terrain = terrain_of(*octree, {}, Eigen::Vector2d(1.0, 0.0));
  EXPECT_TRUE(terrain.cell(cell_at(4.15, 0.05)).known);
  EXPECT_FALSE(terrain.cell(cell_at(4.15, 0.05)).drivable);
  EXPECT_FALSE(terrain.explains_returns(cell_at(4.15, 0.05)));
}

TEST(Terrain, FloorUnderSomethingLowerThanTheRobotIsNoWayThrough) {
  for (const double base : {0.9, 1.5}) {
    Points points;
    add_surface(points, 0.0, 9.0, -1.4, 1.4, [](double, double) { return 0.0; });
    add_surface(points, 3.8, 4.2, -1.4, 1.4, [&](double, double) { return base; });
    const auto octree = octree_of(points, 1.0);  // seen from beside, below nothing
    const TerrainMap terrain = terrain_of(*octree);
    const TerrainCell under = terrain.cell(cell_at(4.05, 0.05));
    if (base < kRobotHeight_m) {
      EXPECT_FALSE(under.drivable) << base;
    } else {
      EXPECT_TRUE(under.drivable) << base;  // a table the robot passes beneath: the floor under it is the floor
      EXPECT_NEAR(under.surface_m, 0.0, 0.05 + 1e-9);
    }
  }
}

TEST(Terrain, PlatformAloneIsDrivableWhereTheRobotStandsOnIt) {
  Points points;
  add_ramp(points);
  const auto octree = octree_of(points, 8.0);
  // Only the platform in view: no floor leads onto it, the robot standing there does.
  const TerrainMap unreached(*octree, kCell_m, {75, -10}, {88, 10}, kRobotHeight_m, {});
  EXPECT_FALSE(unreached.cell(cell_at(8.05, 0.05)).drivable);
  const TerrainMap reached(*octree, kCell_m, {75, -10}, {88, 10}, kRobotHeight_m, {}, Eigen::Vector2d(8.0, 0.0));
  EXPECT_TRUE(reached.cell(cell_at(8.05, 0.05)).drivable);
  EXPECT_TRUE(reached.explains_returns(cell_at(8.55, -0.45)));
}

TEST(Terrain, DisabledKnowsNothing) {
  Points points;
  add_ramp(points);
  const auto octree = octree_of(points);
  TerrainParams params;
  params.enabled = false;
  EXPECT_FALSE(terrain_of(*octree, params).cell(cell_at(5.05, 0.05)).drivable);
}

TEST(Terrain, SteeperThanTheLimitIsNotDrivable) {
  Points points;
  add_ramp(points);
  const auto octree = octree_of(points);
  TerrainParams params;
  params.max_slope_rad = 0.1;  // the 0.2 m/m ramp is 0.197 rad
  const TerrainMap terrain = terrain_of(*octree, params);
  EXPECT_FALSE(terrain.cell(cell_at(5.05, 0.05)).drivable);
  EXPECT_TRUE(terrain.cell(cell_at(1.05, 0.05)).drivable);
}

TEST(Terrain, InvalidParametersAreRefusedByName) {
  const auto octree = octree_of({});
  const auto message = [&](TerrainParams params) {
    try {
      terrain_of(*octree, params);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  TerrainParams slope;
  slope.max_slope_rad = -0.1;
  EXPECT_NE(message(slope).find("max_slope_rad"), std::string::npos);
  TerrainParams step;
  step.max_step_m = std::nan("");
  EXPECT_NE(message(step).find("max_step_m"), std::string::npos);
  TerrainParams band;
  band.ground_band_m = 2.0;
  EXPECT_NE(message(band).find("ground_band_m"), std::string::npos);
  EXPECT_THROW(TerrainMap(*octree, 0.0, {0, 0}, {1, 1}, 1.0, {}), std::invalid_argument);
  EXPECT_THROW(TerrainMap(*octree, 0.1, {0, 0}, {1, 1}, 0.0, {}), std::invalid_argument);
}

}  // namespace
}  // namespace occgeo::mapping
