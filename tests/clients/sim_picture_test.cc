// occgeo-sim --png-out's picture (run_picture): a pixel world keeps its pixels, a shape world is rasterised at
// 0.05 m, and the trajectory and final pose are drawn in the world frame.
#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <vector>

#include "occgeo/sim/run_picture.h"
#include "occgeo/sim/shape_world.h"
#include "occgeo/sim/sim_world.h"

namespace occgeo::sim {
namespace {

constexpr mapfile::Rgb kBlack{0, 0, 0};
constexpr mapfile::Rgb kWhite{255, 255, 255};

TEST(RunPicture, PixelWorldKeepsItsPixelsAndDrawsTheTrajectory) {
  // 8 x 6 pixels of 0.5 m from (0, 0); the obstacle is pixel (5, 3), i.e. x in [2.5, 3), y in [1, 1.5).
  const PixelWorld world(
      World::from_rows({"........", "........", "........", ".....#..", "........", "........"}, 0.5, {0.0, 0.0}));
  // Along y = 0.25 (the bottom row) from x = 0.25 to x = 3.75.
  const std::vector<geometry::Pose2> trajectory = {{0.25, 0.25, 0.0}, {3.75, 0.25, 0.0}};
  const mapfile::MapPicture picture = run_picture(world, trajectory, 0.0);
  ASSERT_EQ(picture.image.width(), 8U);
  ASSERT_EQ(picture.image.height(), 6U);
  EXPECT_EQ(picture.image.at(5, 3), kBlack);
  EXPECT_EQ(picture.image.at(4, 3), kWhite);
  EXPECT_EQ(picture.image.at(2, 5), mapfile::kTrajectoryColour);
  EXPECT_EQ(picture.image.at(2, 4), kWhite);
  // The final pose's marker covers the last trajectory pixel (7, 5).
  EXPECT_EQ(picture.image.at(7, 5), mapfile::kMarkerColour);
}

TEST(RunPicture, ShapeWorldIsRasterisedAtFiveCentimetres) {
  // A disc of radius 0.5 m at (2, 2) inside bounds (0, 0)-(4, 3): 80 x 60 pixels.
  const ShapeWorld world({Shape::circle({2.0, 2.0}, 0.5)}, {},
                         std::pair{Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(4.0, 3.0)});
  const mapfile::MapPicture picture = run_picture(world, {}, 0.0);
  ASSERT_EQ(picture.image.width(), 80U);
  ASSERT_EQ(picture.image.height(), 60U);
  EXPECT_DOUBLE_EQ(picture.pixel_size_m, kShapePictureResolution_m);
  // The centre (2, 2) is canvas (40, 20): pixels around it are black, 0.55 m away white.
  EXPECT_EQ(picture.image.at(40, 20), kBlack);
  EXPECT_EQ(picture.image.at(39, 19), kBlack);
  EXPECT_EQ(picture.image.at(40 + 9, 20), kBlack);   // centre 0.475 m out
  EXPECT_EQ(picture.image.at(40 + 10, 20), kWhite);  // 0.525 m out
  EXPECT_EQ(picture.image.at(40, 20 - 11), kWhite);

  // Without bounds: the shapes' box plus the trajectory, with 1 m of margin.
  const ShapeWorld unbounded({Shape::box({0.0, 0.0}, 2.0, 1.0, 0.0)}, {});
  const mapfile::MapPicture around = run_picture(unbounded, {{3.0, 0.0, 0.0}}, 0.0);
  // x from -2 to 4, y from -1.5 to 1.5: 120 x 60 pixels.
  EXPECT_EQ(around.image.width(), 120U);
  EXPECT_EQ(around.image.height(), 60U);
  EXPECT_EQ(around.image.at(40, 30), kBlack);  // (0, 0)
}

}  // namespace
}  // namespace occgeo::sim
