// HimmGrid <-> map_server image conversion.

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "../support/temp_dir.h"
#include "cell_printer.h"
#include "occgeo/mapfile/map_file.h"
#include "occgeo/mapping/himm_grid.h"

namespace occgeo::mapping {
namespace {

using geometry::CellIndex;
using CellState = mapfile::OccupancyImage::CellState;

// round(254 * (1 - c / 15)) for c = 0..15: the grey levels of the default parameters.
const std::vector<std::uint8_t> kDefaultGreyLevels = {254, 237, 220, 203, 186, 169, 152, 135,
                                                      119, 102, 85,  68,  51,  34,  17,  0};

mapfile::OccupancyImage one_row_image(const std::vector<std::uint8_t>& pixels) {
  mapfile::OccupancyImage image;
  image.width = static_cast<std::uint32_t>(pixels.size());
  image.height = 1;
  image.resolution = 0.1;
  image.pixels = pixels;
  return image;
}

// The pixel of image showing cell c, for an image whose origin is the corner of a cell.
std::uint8_t pixel_of(const mapfile::OccupancyImage& image, const CellIndex& c) {
  const auto col = static_cast<std::uint32_t>(c.ix - static_cast<int>(std::lround(image.origin_x / image.resolution)));
  const auto row_from_bottom =
      static_cast<std::uint32_t>(c.iy - static_cast<int>(std::lround(image.origin_y / image.resolution)));
  return image.pixel(col, image.height - 1 - row_from_bottom);
}

// Expects a and b to hold the same cells over a's tiles.
void expect_same_cells(const HimmGrid& a, const HimmGrid& b) {
  ASSERT_EQ(a.tile_bounds(), b.tile_bounds());
  EXPECT_EQ(a.tile_count(), b.tile_count());
  EXPECT_EQ(a.occupied_cell_count(), b.occupied_cell_count());
  const CellBox box = *a.tile_bounds();
  for (int iy = box.min.iy; iy <= box.max.iy; ++iy) {
    for (int ix = box.min.ix; ix <= box.max.ix; ++ix) {
      ASSERT_EQ(a.observed({ix, iy}), b.observed({ix, iy})) << ix << ", " << iy;
      ASSERT_EQ(a.certainty({ix, iy}), b.certainty({ix, iy})) << ix << ", " << iy;
    }
  }
}

TEST(HimmImageTest, DefaultGreyLevelsAreTheUniformScale) {
  std::vector<std::uint8_t> pixels = kDefaultGreyLevels;
  pixels.push_back(205);
  const HimmGrid grid = HimmGrid::from_image(one_row_image(pixels), HimmParams{});
  for (int c = 0; c <= 15; ++c) {
    EXPECT_TRUE(grid.observed({c, 0}));
    EXPECT_EQ(grid.certainty({c, 0}), c);
  }
  EXPECT_FALSE(grid.observed({16, 0}));

  const mapfile::OccupancyImage image = grid.to_image();
  EXPECT_EQ(image.width, 64U);  // One 64-cell tile.
  EXPECT_EQ(image.height, 64U);
  EXPECT_EQ(image.origin_x, 0.0);
  EXPECT_EQ(image.origin_y, 0.0);
  for (int c = 0; c <= 15; ++c) EXPECT_EQ(pixel_of(image, {c, 0}), kDefaultGreyLevels[static_cast<std::size_t>(c)]);
  EXPECT_EQ(pixel_of(image, {16, 0}), 205);
  EXPECT_EQ(pixel_of(image, {0, 1}), 205);
  // 205 lies between certainty 2 (220) and 3 (203): thresholds halfway between their probabilities.
  EXPECT_NEAR(image.occupied_thresh, 51.0 / 255.0, 1e-12);
  EXPECT_NEAR(image.free_thresh, 42.5 / 255.0, 1e-12);
}

TEST(HimmImageTest, ForeignImagesGoByTheirTrinaryReading) {
  // 237 and 51 are grey levels of certainties 1 and 12; 50 and 230 are not (p = 0.80 and 0.10), nor is 100
  // (p = 0.61, between map_server's default thresholds 0.196 and 0.65).
  const HimmGrid grid = HimmGrid::from_image(one_row_image({0, 205, 254, 237, 51, 50, 230, 100}), HimmParams{});
  EXPECT_EQ(grid.certainty({0, 0}), 15);
  EXPECT_FALSE(grid.observed({1, 0}));
  EXPECT_EQ(grid.certainty({2, 0}), 0);
  EXPECT_EQ(grid.certainty({3, 0}), 1);
  EXPECT_EQ(grid.certainty({4, 0}), 12);
  EXPECT_EQ(grid.certainty({5, 0}), 15);
  EXPECT_TRUE(grid.observed({6, 0}));
  EXPECT_EQ(grid.certainty({6, 0}), 0);
  EXPECT_FALSE(grid.observed({7, 0}));

  mapfile::OccupancyImage negated = one_row_image({255, 237, 0});
  negated.negate = true;  // p = pixel / 255; no exact grey-level matching.
  const HimmGrid from_negated = HimmGrid::from_image(negated, HimmParams{});
  EXPECT_EQ(from_negated.certainty({0, 0}), 15);
  EXPECT_EQ(from_negated.certainty({1, 0}), 15);
  EXPECT_EQ(from_negated.certainty({2, 0}), 0);
}

TEST(HimmImageTest, ImageRowsGoDownAndOriginsSnapToCellCorners) {
  mapfile::OccupancyImage image;
  image.width = 2;
  image.height = 2;
  image.resolution = 0.1;
  image.origin_x = -1.02;             // Nearest cell corner: -1.0, cell -10.
  image.origin_y = 0.98;              // Nearest cell corner: 1.0, cell 10.
  image.pixels = {0, 254, 254, 205};  // Top row first.
  const HimmGrid grid = HimmGrid::from_image(image, HimmParams{});
  EXPECT_EQ(grid.certainty({-10, 11}), 15);
  EXPECT_TRUE(grid.observed({-9, 11}));
  EXPECT_TRUE(grid.observed({-10, 10}));
  EXPECT_FALSE(grid.observed({-9, 10}));
  EXPECT_EQ(grid.occupied_cell_count(), 1U);
}

TEST(HimmImageTest, SavedGridReadsBackLosslessly) {
  HimmGrid grid{HimmParams{}};
  // Beams and hits around the origin, across four tiles, with repeated hits for a spread of certainties.
  for (int i = 0; i < 6; ++i) {
    grid.insert_ray({-2.05, -1.95}, {3.45, 2.15}, true);
    grid.insert_ray({0.55, 0.45}, {-4.05, 0.45 - 0.1 * i}, true);
    grid.insert_ray({0.55, 0.45}, {0.55, -3.05 + 0.1 * i}, i % 2 == 0);
  }
  occgeo::testing::TempDir dir;
  mapfile::write_map(dir.path() / "world", grid.to_image());
  const mapfile::OccupancyImage image = mapfile::read_map_yaml(dir.path() / "world.yaml");
  EXPECT_EQ(image.origin_x, -6.4);
  EXPECT_EQ(image.origin_y, -6.4);
  expect_same_cells(grid, HimmGrid::from_image(image, HimmParams{}));
}

TEST(HimmImageTest, MapServerReadingAgreesWithTheGridForEveryThreshold) {
  for (const int max_certainty : {15, 10, 4, 1}) {
    for (int threshold = 1; threshold <= max_certainty; ++threshold) {
      SCOPED_TRACE("max_certainty " + std::to_string(max_certainty) + ", occupied_threshold " +
                   std::to_string(threshold));
      HimmParams params;
      params.max_certainty = max_certainty;
      params.occupied_threshold = threshold;
      params.increment = 1;
      params.growth_neighbour_weight = 0.0;
      HimmGrid grid(params);
      // Certainty c at cell (2c, 0), hit c times from below; cells (2c + 1, 0) stay unobserved.
      const geometry::GridGeometry& cells = grid.grid_geometry();
      grid.insert_ray(cells.center_of({0, -3}), cells.center_of({0, 0}), false);
      for (int c = 1; c <= max_certainty; ++c) {
        for (int i = 0; i < c; ++i) grid.insert_ray(cells.center_of({2 * c, -3}), cells.center_of({2 * c, 0}), true);
        ASSERT_EQ(grid.certainty({2 * c, 0}), c);
      }

      occgeo::testing::TempDir dir;
      mapfile::write_map(dir.path() / "grid", grid.to_image());
      const mapfile::OccupancyImage image = mapfile::read_map_yaml(dir.path() / "grid.yaml");
      for (std::uint32_t row = 0; row < image.height; ++row) {
        for (std::uint32_t col = 0; col < image.width; ++col) {
          const mapfile::MapPoint p = image.pixel_center(col, row);
          const CellIndex c = cells.cell_of({p.x, p.y});
          const CellState expected = !grid.observed(c)  ? CellState::unknown
                                     : grid.occupied(c) ? CellState::occupied
                                                        : CellState::free;
          ASSERT_EQ(image.state(col, row), expected) << "cell " << c.ix << ", " << c.iy;
        }
      }
      expect_same_cells(grid, HimmGrid::from_image(image, params));
    }
  }
}

TEST(HimmImageTest, EmptyGridGivesAnEmptyImage) {
  const mapfile::OccupancyImage image = HimmGrid{HimmParams{}}.to_image();
  EXPECT_EQ(image.width, 0U);
  EXPECT_EQ(image.height, 0U);
  EXPECT_EQ(image.resolution, 0.1);
  EXPECT_EQ(HimmGrid::from_image(image, HimmParams{}).tile_count(), 0U);
}

TEST(HimmImageTest, RejectsImagesThatDoNotFitTheGrid) {
  const auto message_for = [](const mapfile::OccupancyImage& image) -> std::string {
    try {
      (void)HimmGrid::from_image(image, HimmParams{});
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  mapfile::OccupancyImage image = one_row_image({0, 254});
  image.resolution = 0.05;
  EXPECT_EQ(message_for(image), "from_image: image resolution 0.05 differs from cell_size_m 0.1");
  image.resolution = 0.1;
  image.origin_yaw = 0.3;
  EXPECT_EQ(message_for(image), "from_image: origin_yaw 0.3 is not supported (only 0)");
  image.origin_yaw = 0.0;
  image.pixels.pop_back();
  EXPECT_EQ(message_for(image), "from_image: pixels holds 1 values, width * height is 2");
  image.pixels.push_back(0);
  image.origin_x = 1e12;
  EXPECT_EQ(message_for(image), "from_image: the image is not finite or lies too far from the origin");
}

}  // namespace
}  // namespace occgeo::mapping
