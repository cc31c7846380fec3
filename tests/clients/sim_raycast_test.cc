#include <gtest/gtest.h>

#include <cmath>

#include "occgeo/sim/raycast.h"

namespace occgeo::sim {
namespace {

// Distances come from one division per crossing; 1e-12 m allows for the rounding of that division and of the inputs.
constexpr double kTolerance_m = 1e-12;

// 12 x 8 pixels of 0.25 m from (-1, -1): x in [-1, 2], y in [-1, 1]; column 10 (x from 1.5 to 1.75) is a wall.
World wall_world() {
  return World::from_rows({"..........#.", "..........#.", "..........#.", "..........#.", "..........#.",
                           "..........#.", "..........#.", "..........#."},
                          0.25, {-1.0, -1.0});
}

TEST(CastRay, HitsAWallAtTheExactDistance) {
  const World world = wall_world();
  const auto hit = cast_ray(world, {0.0, 0.1}, {1.0, 0.0}, 8.0);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->distance_m, 1.5);  // binary fractions: exact
  EXPECT_EQ(hit->pixels, (std::vector<Pixel>{{10, 3}}));
}

TEST(CastRay, HitsAWallObliquelyAtTheExactDistance) {
  const World world = wall_world();
  const double angle = 20.0 * M_PI / 180.0;
  const auto hit = cast_ray(world, {0.0, 0.1}, {std::cos(angle), std::sin(angle)}, 8.0);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->distance_m, 1.5 / std::cos(angle), kTolerance_m);
  // Enters at y = 0.1 + 1.5 tan(20°) = 0.646, in row 1 (y from 0.5 to 0.75).
  EXPECT_EQ(hit->pixels, (std::vector<Pixel>{{10, 1}}));
}

TEST(CastRay, ReportsNoHitBeyondMaxRangeOrOutsideTheImage) {
  const World world = wall_world();
  EXPECT_FALSE(cast_ray(world, {0.0, 0.1}, {1.0, 0.0}, 1.0));
  EXPECT_FALSE(cast_ray(world, {0.0, 0.1}, {1.0, 0.0}, 1.5)) << "a hit exactly at max range is no return";
  EXPECT_TRUE(cast_ray(world, {0.0, 0.1}, {1.0, 0.0}, 1.5000001));
  EXPECT_FALSE(cast_ray(world, {0.0, 0.1}, {-1.0, 0.0}, 100.0)) << "leaves the image through free pixels";
  EXPECT_FALSE(cast_ray(world, {0.0, 0.1}, {0.0, 1.0}, 100.0));
}

TEST(CastRay, EntersTheImageFromOutside) {
  const World world = wall_world();
  const auto hit = cast_ray(world, {-5.0, 0.1}, {1.0, 0.0}, 8.0);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->distance_m, 6.5);
  EXPECT_FALSE(cast_ray(world, {-5.0, 0.1}, {1.0, 0.0}, 6.0));
  EXPECT_FALSE(cast_ray(world, {-5.0, 3.0}, {1.0, 0.0}, 100.0)) << "passes above the image";
}

TEST(CastRay, StartsInsideAnObstacleAtDistanceZero) {
  const World world = wall_world();
  const auto hit = cast_ray(world, {1.6, 0.1}, {-1.0, 0.0}, 8.0);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->distance_m, 0.0);
}

TEST(CastRay, TravelsLeftAndUpThroughEdgesExactly) {
  const World world = World::from_rows({"#...", "....", "...."}, 1.0, {0.0, 0.0});  // obstacle x 0..1, y 2..3
  // From (3.5, 0.5) towards (0.5, 2.5): direction (-3, 2)/|.|; enters the obstacle through x = 1 at y = 2.1667.
  const Eigen::Vector2d direction = Eigen::Vector2d(-3.0, 2.0).normalized();
  const auto hit = cast_ray(world, {3.5, 0.5}, direction, 10.0);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->distance_m, 2.5 / (3.0 / std::sqrt(13.0)), kTolerance_m);
  EXPECT_EQ(hit->pixels, (std::vector<Pixel>{{0, 0}}));
}

TEST(CastRay, StartsOnACornerInThePixelItMovesInto) {
  // Obstacles at x 2..3, y 2..3 (col 2, row 0) and x 1..2, y 1..2 (col 1, row 1); the rays start at their shared
  // corner.
  const World world = World::from_rows({"..#..", ".#...", "....."}, 1.0, {0.0, 0.0});
  const auto down_left = cast_ray(world, {2.0, 2.0}, Eigen::Vector2d(-1.0, -1.0).normalized(), 10.0);
  ASSERT_TRUE(down_left);
  EXPECT_EQ(down_left->distance_m, 0.0);
  EXPECT_EQ(down_left->pixels, (std::vector<Pixel>{{1, 1}}));
  const auto up_right = cast_ray(world, {2.0, 2.0}, Eigen::Vector2d(1.0, 1.0).normalized(), 10.0);
  ASSERT_TRUE(up_right);
  EXPECT_EQ(up_right->pixels, (std::vector<Pixel>{{2, 0}}));
  EXPECT_FALSE(cast_ray(world, {2.0, 2.0}, Eigen::Vector2d(1.0, -1.0).normalized(), 10.0));
  EXPECT_FALSE(cast_ray(world, {2.0, 2.0}, Eigen::Vector2d(-1.0, 1.0).normalized(), 10.0));
}

// 1 m pixels from (0, 0): obstacles at x 2..3, y 1..2 (col 2, row 3) and x 3..4, y 3..4 (col 3, row 1).
World diagonal_world() { return World::from_rows({".....", "...#.", ".....", "..#..", "....."}, 1.0, {0.0, 0.0}); }

TEST(CastRay, GrazingACornerIsNotAHit) {
  const World world = diagonal_world();
  const Eigen::Vector2d diagonal = Eigen::Vector2d(1.0, 1.0).normalized();  // equal components: exact corner crossings
  // Along y = x the ray touches the lower obstacle only at its corner (2, 2), then enters the upper one at (3, 3).
  const auto hit = cast_ray(world, {0.5, 0.5}, diagonal, 10.0);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->distance_m, 2.5 * std::sqrt(2.0), kTolerance_m);
  EXPECT_EQ(hit->pixels, (std::vector<Pixel>{{3, 1}}));

  // A hair lower, the ray enters the lower obstacle through its left side.
  const auto low_hit = cast_ray(world, {0.5, 0.49}, diagonal, 10.0);
  ASSERT_TRUE(low_hit);
  EXPECT_NEAR(low_hit->distance_m, 1.5 / diagonal.x(), kTolerance_m);
  EXPECT_EQ(low_hit->pixels, (std::vector<Pixel>{{2, 3}}));

  // Without the upper obstacle, the grazing ray leaves the image.
  const World lower_only = World::from_rows({".....", ".....", ".....", "..#..", "....."}, 1.0, {0.0, 0.0});
  EXPECT_FALSE(cast_ray(lower_only, {0.5, 0.5}, diagonal, 10.0));
}

TEST(CastRay, AlongAnEdgeHitsOnlyWhereBothSidesAreObstacles) {
  // Rows: y 2..3, 1..2, 0..1; the ray runs along y = 1, the edge between rows 1 and 2.
  const World both = World::from_rows({".....", "...#.", "...#."}, 1.0, {0.0, 0.0});
  const auto hit = cast_ray(both, {0.5, 1.0}, {1.0, 0.0}, 10.0);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->distance_m, 2.5);
  EXPECT_EQ(hit->pixels, (std::vector<Pixel>{{3, 1}, {3, 2}}));

  const World one_side = World::from_rows({".....", "...#.", "....."}, 1.0, {0.0, 0.0});
  EXPECT_FALSE(cast_ray(one_side, {0.5, 1.0}, {1.0, 0.0}, 10.0));

  // The same along a column edge, downwards: x = 2 between columns 1 and 2.
  const World column = World::from_rows({".....", ".....", ".##.."}, 1.0, {0.0, 0.0});
  const auto down_hit = cast_ray(column, {2.0, 2.5}, {0.0, -1.0}, 10.0);
  ASSERT_TRUE(down_hit);
  EXPECT_EQ(down_hit->distance_m, 1.5);
  EXPECT_EQ(down_hit->pixels, (std::vector<Pixel>{{1, 2}, {2, 2}}));
}

TEST(CastRay, NormalIsThatOfThePixelEdgeEntered) {
  // Hitting the wall column from the left, at any angle, enters its left edge: (-1, 0).
  const World world = wall_world();
  EXPECT_EQ(cast_ray(world, {0.0, 0.1}, {1.0, 0.0}, 8.0)->normal_W, Eigen::Vector2d(-1.0, 0.0));
  const double angle = 20.0 * M_PI / 180.0;
  EXPECT_EQ(cast_ray(world, {0.0, 0.1}, {std::cos(angle), std::sin(angle)}, 8.0)->normal_W, Eigen::Vector2d(-1.0, 0.0));
  // From the right, leaving the image's last column, its right edge: (1, 0).
  EXPECT_EQ(cast_ray(world, {1.9, 0.1}, {-1.0, 0.0}, 8.0)->normal_W, Eigen::Vector2d(1.0, 0.0));

  // A ceiling row (y from 0.5 to 1) hit from below, straight or steeply: (0, -1); a floor row (y from -1 to -0.5) hit
  // from above: (0, 1).
  const World floor_and_ceiling = World::from_rows({"####", "....", "....", "...."}, 0.5, {0.0, -1.0});
  EXPECT_EQ(cast_ray(floor_and_ceiling, {1.0, 0.1}, {0.0, 1.0}, 8.0)->normal_W, Eigen::Vector2d(0.0, -1.0));
  const double steep = 70.0 * M_PI / 180.0;
  EXPECT_EQ(cast_ray(floor_and_ceiling, {0.1, 0.1}, {std::cos(steep), std::sin(steep)}, 8.0)->normal_W,
            Eigen::Vector2d(0.0, -1.0));
  const World floor = World::from_rows({"....", "....", "....", "####"}, 0.5, {0.0, -1.0});
  EXPECT_EQ(cast_ray(floor, {1.0, 0.1}, {0.0, -1.0}, 8.0)->normal_W, Eigen::Vector2d(0.0, 1.0));
}

TEST(CastRay, NormalThroughACornerOrFromInsideIsTheMostOpposedAxis) {
  // Through the exact corner (3, 3) of the upper obstacle of diagonal_world: no single edge; the diagonal ray's
  // components tie, so the x edge's normal.
  const World world = diagonal_world();
  const auto corner = cast_ray(world, {0.5, 0.5}, Eigen::Vector2d(1.0, 1.0).normalized(), 10.0);
  ASSERT_TRUE(corner);
  EXPECT_EQ(corner->normal_W, Eigen::Vector2d(-1.0, 0.0));
  // From inside the lower obstacle, steeper than 45° downwards: the y edge the direction most opposes, (0, 1).
  const auto inside = cast_ray(world, {2.5, 1.5}, Eigen::Vector2d(0.3, -1.0).normalized(), 10.0);
  ASSERT_TRUE(inside);
  EXPECT_EQ(inside->distance_m, 0.0);
  EXPECT_EQ(inside->normal_W, Eigen::Vector2d(0.0, 1.0));
  // Along a shared edge the ray enters through a column edge.
  const World both = World::from_rows({".....", "...#.", "...#."}, 1.0, {0.0, 0.0});
  EXPECT_EQ(cast_ray(both, {0.5, 1.0}, {1.0, 0.0}, 10.0)->normal_W, Eigen::Vector2d(-1.0, 0.0));
}

TEST(CastRay, NormalAtTheImageBorderIsTheBordersEdge) {
  // A ray from outside the image entering an obstacle in its first column through the image's left border.
  const World world = World::from_rows({"#...", "#...", "#...", "#..."}, 1.0, {0.0, 0.0});
  const auto hit = cast_ray(world, {-1.0, 2.2}, Eigen::Vector2d(1.0, 0.2).normalized(), 10.0);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->normal_W, Eigen::Vector2d(-1.0, 0.0));
  // Entering the bottom row from below the image.
  const World bottom = World::from_rows({"....", "....", "....", "####"}, 1.0, {0.0, 0.0});
  const auto up = cast_ray(bottom, {1.5, -1.0}, Eigen::Vector2d(0.2, 1.0).normalized(), 10.0);
  ASSERT_TRUE(up);
  EXPECT_EQ(up->normal_W, Eigen::Vector2d(0.0, -1.0));
}

TEST(CastRay, IsExactAtTheSimulatorsResolution) {
  // 0.1 m pixels from (-30, -30) like the shipped worlds; one obstacle at column 305, x from 0.5 to 0.6.
  std::vector<std::string> rows(600, std::string(600, '.'));
  rows[299][305] = '#';  // row 299 holds y from 0 to 0.1
  const World world = World::from_rows(std::vector<std::string_view>(rows.begin(), rows.end()), 0.1, {-30.0, -30.0});
  const auto hit = cast_ray(world, {0.45, 0.05}, {1.0, 0.0}, 8.0);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->distance_m, 0.05, 1e-12);
  EXPECT_EQ(hit->pixels, (std::vector<Pixel>{{305, 299}}));
}

TEST(CastRay, RejectsNonFiniteInput) {
  const World world = wall_world();
  EXPECT_THROW(cast_ray(world, {NAN, 0.0}, {1.0, 0.0}, 8.0), std::invalid_argument);
  EXPECT_THROW(cast_ray(world, {0.0, 0.0}, {1.0, 0.0}, INFINITY), std::invalid_argument);
}

TEST(World, MapsPointsToPixelsWithRowZeroAtTheTop) {
  const World world = wall_world();
  EXPECT_EQ(world.column_of(-1.0), 0);
  EXPECT_EQ(world.column_of(-1.0001), -1);
  EXPECT_EQ(world.column_of(1.5), 10);
  EXPECT_EQ(world.column_of(2.0), 12);
  EXPECT_EQ(world.row_of(0.99), 0);
  EXPECT_EQ(world.row_of(1.0), -1);
  EXPECT_EQ(world.row_of(-1.0), 7);
  EXPECT_EQ(world.row_of(-1.01), 8);
  EXPECT_EQ(world.center_of({10, 7}), Eigen::Vector2d(1.625, -0.875));
  EXPECT_TRUE(world.is_obstacle({10, 0}));
  EXPECT_FALSE(world.is_obstacle({9, 0}));
  EXPECT_FALSE(world.is_obstacle({10, -1})) << "outside the image is free";
}

TEST(World, RejectsBadLiteralRows) {
  EXPECT_THROW(World::from_rows({"...", ".."}, 1.0, {0.0, 0.0}), WorldError);
  EXPECT_THROW(World::from_rows({}, 1.0, {0.0, 0.0}), WorldError);
  EXPECT_THROW(World::from_rows({"..."}, 0.0, {0.0, 0.0}), WorldError);
}

}  // namespace
}  // namespace occgeo::sim
