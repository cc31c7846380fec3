#include <gtest/gtest.h>

#include <cmath>

#include "occgeo/sim/footprint_collision.h"

namespace occgeo::sim {
namespace {

// The Bearcat's body: 1.0 m long, 0.8 m wide, centred on base_link.
const geometry::BoxFootprint kBearcatBox{.length = 1.0, .width = 0.8, .height = 1.2, .center_x = 0.0};

// 0.5 m pixels from (0, 0), 8 x 6: one obstacle at col 5, row 3, the square x 2.5..3.0, y 1.0..1.5.
World one_pixel_world() {
  return World::from_rows({"........", "........", "........", ".....#..", "........", "........"}, 0.5, {0.0, 0.0});
}

TEST(FindCollision, ClearWhenTheBoxIsAway) {
  EXPECT_FALSE(find_collision(one_pixel_world(), kBearcatBox, {1.0, 1.25, 0.0}));
}

TEST(FindCollision, TouchingIsNotACollision) {
  // The box's front face x = 2.0 + 0.5 lies exactly on the pixel's left edge (binary fractions: exact).
  EXPECT_FALSE(find_collision(one_pixel_world(), kBearcatBox, {2.0, 1.25, 0.0}));
  // A 0.5 m wide box whose left face y = 0.75 + 0.25 lies on the pixel's bottom edge, and one a hair higher.
  const geometry::BoxFootprint narrow_box{.length = 1.0, .width = 0.5, .height = 1.2, .center_x = 0.0};
  EXPECT_FALSE(find_collision(one_pixel_world(), narrow_box, {2.75, 0.75, 0.0}));
  EXPECT_TRUE(find_collision(one_pixel_world(), narrow_box, {2.75, 0.7501, 0.0}));
}

TEST(FindCollision, OverlapIsACollision) {
  const auto pixel = find_collision(one_pixel_world(), kBearcatBox, {2.01, 1.25, 0.0});
  ASSERT_TRUE(pixel);
  EXPECT_EQ(*pixel, (Pixel{5, 3}));
}

TEST(FindCollision, AnObstacleInsideTheBoxIsACollision) {
  EXPECT_TRUE(find_collision(one_pixel_world(), kBearcatBox, {2.75, 1.25, 0.3}));
}

TEST(FindCollision, UsesTheRotatedBoxNotItsBoundingBox) {
  // Turned 45°, the box's right corner reaches x = 2.0 + 0.9/sqrt(2) = 2.636 inside the pixel's rows: a collision.
  EXPECT_TRUE(find_collision(one_pixel_world(), kBearcatBox, {2.0, 1.25, M_PI / 4.0}));
  // Centred at (2.0, 0.7) its bounding box (up to x = 2.636, y = 1.336) overlaps the pixel but the box does not: its
  // edge x + y = 2.7 + 0.5 sqrt(2) = 3.407 passes below the pixel's nearest corner (2.5, 1.0), where x + y = 3.5.
  EXPECT_FALSE(find_collision(one_pixel_world(), kBearcatBox, {2.0, 0.7, M_PI / 4.0}));
}

TEST(FindCollision, HonoursTheBoxOffsetAlongX) {
  const geometry::BoxFootprint forward_box{.length = 1.0, .width = 0.8, .height = 1.2, .center_x = 0.3};
  EXPECT_FALSE(find_collision(one_pixel_world(), kBearcatBox, {1.8, 1.25, 0.0}));
  EXPECT_TRUE(find_collision(one_pixel_world(), forward_box, {1.8, 1.25, 0.0}));
}

TEST(FindCollision, NothingOutsideTheImage) {
  EXPECT_FALSE(find_collision(one_pixel_world(), kBearcatBox, {-10.0, 40.0, 1.0}));
}

}  // namespace
}  // namespace occgeo::sim
