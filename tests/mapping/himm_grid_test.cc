#include "occgeo/mapping/himm_grid.h"

#include <gtest/gtest.h>

#include "../support/error_message.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "cell_printer.h"

namespace occgeo::mapping {
namespace {

using geometry::CellIndex;

// Marks an unobserved cell in the expected pictures below.
constexpr int U = -1;

// Certainties of the width x height cells from min, as a picture: first row = largest iy, U for unobserved cells.
std::vector<std::vector<int>> picture(const HimmGrid& grid, CellIndex min, int width, int height) {
  std::vector<std::vector<int>> rows;
  for (int iy = min.iy + height - 1; iy >= min.iy; --iy) {
    std::vector<int>& row = rows.emplace_back();
    for (int ix = min.ix; ix < min.ix + width; ++ix) {
      row.push_back(grid.observed({ix, iy}) ? grid.certainty({ix, iy}) : U);
    }
  }
  return rows;
}

// World centre of cell (ix, iy) of grid, metres.
Eigen::Vector2d center(const HimmGrid& grid, int ix, int iy) { return grid.grid_geometry().center_of({ix, iy}); }

TEST(HimmGridTest, SingleHitClearsTheBeamAndMarksTheEndCell) {
  HimmGrid grid{HimmParams{}};
  grid.insert_ray(center(grid, 0, 2), center(grid, 4, 2), true);
  // Beam cells observed at 0; hit cell 0 + 3, then the growth operator: 1.0 * 3 + 0.5 * 0 = 3.
  EXPECT_EQ(picture(grid, {0, 0}, 7, 5), (std::vector<std::vector<int>>{
                                             {U, U, U, U, U, U, U},
                                             {U, U, U, U, U, U, U},
                                             {0, 0, 0, 0, 3, U, U},
                                             {U, U, U, U, U, U, U},
                                             {U, U, U, U, U, U, U},
                                         }));
  EXPECT_EQ(grid.version(), 1U);
  EXPECT_TRUE(grid.occupied({4, 2}));
  EXPECT_FALSE(grid.occupied({3, 2}));
  EXPECT_EQ(grid.occupied_cell_count(), 1U);
}

TEST(HimmGridTest, DiagonalBeamFollowsTheExactTraversal) {
  HimmGrid grid{HimmParams{}};
  // From the centre of cell (0, 0) to a point of cell (3, 2): x crosses at t = 1/6, 1/2, 5/6, y at 1/4, 3/4.
  grid.insert_ray(center(grid, 0, 0), {0.35, 0.25}, true);
  EXPECT_EQ(picture(grid, {0, 0}, 5, 4), (std::vector<std::vector<int>>{
                                             {U, U, U, U, U},
                                             {U, U, 0, 3, U},
                                             {U, 0, 0, U, U},
                                             {0, 0, U, U, U},
                                         }));
}

TEST(HimmGridTest, RepeatedHitsSaturateAtMaxCertainty) {
  HimmGrid grid{HimmParams{}};
  std::vector<int> after_each_hit;
  for (int i = 0; i < 7; ++i) {
    grid.insert_ray(center(grid, 0, 0), center(grid, 5, 0), true);
    after_each_hit.push_back(grid.certainty({5, 0}));
  }
  EXPECT_EQ(after_each_hit, (std::vector<int>{3, 6, 9, 12, 15, 15, 15}));
  EXPECT_EQ(grid.certainty({4, 0}), 0);
  EXPECT_EQ(grid.version(), 7U);
}

TEST(HimmGridTest, GrowthOperatorPullsAHitUpToOccupiedNeighbours) {
  HimmGrid grid{HimmParams{}};
  // Hit each neighbour of (10, 10) five times with a beam that crosses no other neighbour.
  const auto hit_five_times = [&grid](CellIndex from, CellIndex to) {
    for (int i = 0; i < 5; ++i) grid.insert_ray(center(grid, from.ix, from.iy), center(grid, to.ix, to.iy), true);
  };
  for (const int ix : {9, 10, 11}) {
    hit_five_times({ix, 14}, {ix, 11});
    hit_five_times({ix, 6}, {ix, 9});
  }
  hit_five_times({6, 10}, {9, 10});
  hit_five_times({14, 10}, {11, 10});
  ASSERT_FALSE(grid.observed({10, 10}));
  // The beam into (10, 10) lowers (10, 11) to 14; the hit gives 0 + 3 = 3, then 3 + 0.5 * (7 * 15 + 14) -> 15.
  grid.insert_ray(center(grid, 10, 14), center(grid, 10, 10), true);
  EXPECT_EQ(picture(grid, {8, 8}, 5, 5), (std::vector<std::vector<int>>{
                                             {U, 0, 0, 0, U},
                                             {U, 15, 14, 15, U},
                                             {0, 15, 15, 15, 0},
                                             {U, 15, 15, 15, U},
                                             {U, 0, 0, 0, U},
                                         }));
  EXPECT_EQ(grid.occupied_cell_count(), 9U);
}

TEST(HimmGridTest, GrowthOperatorReadsNeighboursAcrossTilesWithoutAllocatingThem) {
  HimmParams params;
  params.tile_cells = 8;
  HimmGrid grid(params);
  // (7, 3) is on the east edge of tile (0, 0); its east neighbours are in tile (1, 0), never written.
  grid.insert_ray(center(grid, 2, 3), center(grid, 7, 3), true);
  EXPECT_EQ(grid.tile_count(), 1U);
  EXPECT_EQ(grid.certainty({7, 3}), 3);
  // A second beam observes (8, 4) in tile (1, 0) at 15 worth of hits; the next hit on (7, 3) sees it.
  for (int i = 0; i < 5; ++i) grid.insert_ray(center(grid, 8, 9), center(grid, 8, 4), true);
  ASSERT_EQ(grid.certainty({8, 4}), 15);
  grid.insert_ray(center(grid, 2, 3), center(grid, 7, 3), true);
  EXPECT_EQ(grid.certainty({7, 3}), 13);  // 3 + 3 = 6, then 6 + 0.5 * 15 = 13.5 -> 13.
  EXPECT_EQ(grid.tile_count(), 3U);       // Tiles (0, 0), (1, 0), (1, 1).
}

TEST(HimmGridTest, MaxRangeReadingClearsItsBeamAndMarksNothing) {
  HimmGrid grid{HimmParams{}};
  for (int i = 0; i < 3; ++i) grid.insert_ray(center(grid, 0, 0), center(grid, 4, 0), true);
  ASSERT_EQ(grid.certainty({4, 0}), 9);
  grid.insert_ray(center(grid, 0, 0), center(grid, 4, 0), false);
  EXPECT_EQ(grid.certainty({4, 0}), 8);
  grid.insert_ray(center(grid, 0, 1), center(grid, 5, 1), false);
  EXPECT_EQ(picture(grid, {0, 0}, 7, 3), (std::vector<std::vector<int>>{
                                             {U, U, U, U, U, U, U},
                                             {0, 0, 0, 0, 0, 0, U},
                                             {0, 0, 0, 0, 8, U, U},
                                         }));
}

TEST(HimmGridTest, ScanReadingsAtOrBeyondRangeMaxAreTracedToRangeMaxUnmarked) {
  HimmGrid grid{HimmParams{}};
  const std::vector<float> ranges = {0.5F, 2.0F, std::numeric_limits<float>::infinity()};
  // Sensor at the centre of cell (0, 0) facing +x; beams at -90, 0 and +90 degrees, range_max 0.3 m.
  grid.insert_scan({0.05, 0.05, 0.0}, -std::numbers::pi_v<float> / 2, std::numbers::pi_v<float> / 2, ranges, 0.3F);
  EXPECT_EQ(picture(grid, {-1, -4}, 6, 9), (std::vector<std::vector<int>>{
                                               {U, U, U, U, U, U},
                                               {U, 0, U, U, U, U},
                                               {U, 0, U, U, U, U},
                                               {U, 0, U, U, U, U},
                                               {U, 0, 0, 0, 0, U},
                                               {U, 0, U, U, U, U},
                                               {U, 0, U, U, U, U},
                                               {U, 0, U, U, U, U},
                                               {U, U, U, U, U, U},
                                           }));
  EXPECT_EQ(grid.occupied_cell_count(), 0U);
  EXPECT_EQ(grid.version(), 1U);
}

TEST(HimmGridTest, ScanBeamsStartAtTheSensorNotTheRobot) {
  HimmGrid grid{HimmParams{}};
  // Robot facing +y at (1.03, 2.04); the sensor sits 0.5 m ahead of it, so at (1.03, 2.54), cell (10, 25).
  const geometry::Pose2 X_WB{1.03, 2.04, std::numbers::pi / 2};
  const geometry::Pose2 X_BS{0.5, 0.0, 0.0};
  const geometry::Pose2 X_WS = X_WB.compose(X_BS);
  // Beams at -90, 0, +90 degrees in the sensor frame: world east, north, west.
  const std::vector<float> ranges = {0.2F, 0.3F, 0.2F};
  grid.insert_scan(X_WS, -std::numbers::pi_v<float> / 2, std::numbers::pi_v<float> / 2, ranges, 4.0F);
  EXPECT_EQ(picture(grid, {7, 19}, 7, 11), (std::vector<std::vector<int>>{
                                               {U, U, U, U, U, U, U},  // iy = 29
                                               {U, U, U, 3, U, U, U},
                                               {U, U, U, 0, U, U, U},
                                               {U, U, U, 0, U, U, U},
                                               {U, 3, 0, 0, 0, 3, U},  // iy = 25: the sensor's row
                                               {U, U, U, U, U, U, U},
                                               {U, U, U, U, U, U, U},
                                               {U, U, U, U, U, U, U},
                                               {U, U, U, U, U, U, U},
                                               {U, U, U, U, U, U, U},  // iy = 20: the robot's row
                                               {U, U, U, U, U, U, U},
                                           }));
}

// Something that stood at 1 m for 20 scans and left: the scans that see through its cell (their beams now end on a
// wall at 3 m) clear it within two with the default seen_through_decrement; plain HIMM (0) takes a scan per
// certainty point. The wall's cells, which the beams end in, stay.
TEST(HimmGridTest, TwoScansThatSeeThroughACellClearIt) {
  const auto scans_to_clear = [](int seen_through_decrement) {
    HimmParams params;
    params.seen_through_decrement = seen_through_decrement;
    HimmGrid grid(params);
    const geometry::Pose2 X_WS{0.05, 0.05, 0.0};
    const std::vector<float> standing = {1.0F, 1.0F, 1.0F};
    const std::vector<float> gone = {3.0F, 3.0F, 3.0F};
    // Three beams 0.5 degrees apart: all end in cell (10, 0) at 1 m, and in (30, 0) at 3 m.
    const float step = 0.5F * std::numbers::pi_v<float> / 180.0F;
    for (int k = 0; k < 20; ++k) grid.insert_scan(X_WS, -step, step, standing, 4.0F);
    EXPECT_EQ(grid.certainty({10, 0}), params.max_certainty);
    int scans = 0;
    while (grid.occupied({10, 0}) && scans < 100) {
      grid.insert_scan(X_WS, -step, step, gone, 4.0F);
      ++scans;
    }
    EXPECT_TRUE(grid.occupied({30, 0}));
    return scans;
  };
  EXPECT_EQ(scans_to_clear(HimmParams{}.seen_through_decrement), 2);
  EXPECT_GT(scans_to_clear(0), 2);
}

// Beams flagged as ending on something moving clear the cells before the return and mark nothing: a person who walks
// into a cell leaves it as it was, and one who stood there (a full cell) is cleared by the beams that now pass it.
TEST(HimmGridTest, BeamsEndingOnSomethingMovingMarkNothing) {
  HimmGrid grid{HimmParams{}};
  const geometry::Pose2 X_WS{0.05, 0.05, 0.0};
  const float step = 0.5F * std::numbers::pi_v<float> / 180.0F;
  const std::vector<float> at_1m = {1.0F, 1.0F, 1.0F};
  const std::vector<std::uint8_t> moving = {1, 1, 1};
  for (int k = 0; k < 5; ++k) grid.insert_scan(X_WS, -step, step, at_1m, 4.0F, {}, moving);
  EXPECT_FALSE(grid.occupied({10, 0}));
  EXPECT_FALSE(grid.observed({10, 0}));  // the return's own cell is left as it was
  EXPECT_TRUE(grid.observed({5, 0}));
  EXPECT_EQ(grid.certainty({5, 0}), 0);
  // Unflagged, the same beams mark the cell; flagged beams ending behind it (the walker moved on) clear it.
  for (int k = 0; k < 5; ++k) grid.insert_scan(X_WS, -step, step, at_1m, 4.0F);
  EXPECT_TRUE(grid.occupied({10, 0}));
  const std::vector<float> at_2m = {2.0F, 2.0F, 2.0F};
  for (int k = 0; k < 2; ++k) grid.insert_scan(X_WS, -step, step, at_2m, 4.0F, {}, moving);
  EXPECT_FALSE(grid.occupied({10, 0}));
  EXPECT_FALSE(grid.occupied({20, 0}));
  // One flag per reading, or the scan is refused whole, naming the mismatch.
  const std::uint64_t version = grid.version();
  try {
    grid.insert_scan(X_WS, -step, step, at_1m, 4.0F, {}, std::vector<std::uint8_t>{1});
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ended_on_moving has 1 flags for 3 readings"), std::string::npos) << e.what();
  }
  EXPECT_EQ(grid.version(), version);
}

TEST(HimmGridTest, TilesGrowInAllFourQuadrants) {
  HimmGrid grid{HimmParams{}};
  EXPECT_EQ(grid.tile_count(), 0U);
  EXPECT_FALSE(grid.tile_bounds().has_value());
  for (const double sx : {1.0, -1.0}) {
    for (const double sy : {1.0, -1.0}) {
      grid.insert_ray({sx * 3.05, sy * 3.05}, {sx * 3.45, sy * 3.05}, true);
    }
  }
  EXPECT_EQ(grid.tile_count(), 4U);
  EXPECT_EQ(grid.tile_bounds(), (CellBox{{-64, -64}, {63, 63}}));
  EXPECT_EQ(grid.certainty({34, 30}), 3);
  EXPECT_EQ(grid.certainty({-35, 30}), 3);
  EXPECT_EQ(grid.certainty({34, -31}), 3);
  EXPECT_EQ(grid.certainty({-35, -31}), 3);
  EXPECT_EQ(grid.certainty({-31, -31}), 0);
  EXPECT_TRUE(grid.observed({-31, -31}));
  EXPECT_EQ(grid.occupied_cell_count(), 4U);
}

TEST(HimmGridTest, MemoryFollowsTheAreaSeen) {
  HimmGrid grid{HimmParams{}};                         // 64 x 64 cells of 0.1 m: 6.4 m tiles.
  grid.insert_ray({0.05, 0.05}, {20.05, 0.05}, true);  // Cells 0..200 of row 0.
  EXPECT_EQ(grid.tile_count(), 4U);
  EXPECT_EQ(grid.tile_bounds(), (CellBox{{0, 0}, {255, 63}}));
  // Far away: only the tiles under the new beam appear, none in between.
  grid.insert_ray({-1000.05, 500.05}, {-1000.05, 501.05}, true);
  EXPECT_EQ(grid.tile_count(), 5U);
  EXPECT_EQ(grid.tile_bounds(), (CellBox{{-10048, 0}, {255, 5055}}));
  // Reading cells does not allocate.
  EXPECT_EQ(grid.certainty({100000, -100000}), 0);
  EXPECT_FALSE(grid.observed({100000, -100000}));
  EXPECT_EQ(grid.tile_count(), 5U);
}

TEST(HimmGridTest, CustomIncrementsAndWeights) {
  HimmParams params;
  params.increment = 5;
  params.decrement = 2;
  params.growth_center_weight = 0.5;
  params.growth_neighbour_weight = 0.0;
  params.max_certainty = 10;
  HimmGrid grid(params);
  grid.insert_ray(center(grid, 0, 0), center(grid, 3, 0), true);
  EXPECT_EQ(grid.certainty({3, 0}), 2);  // (0 + 5) * 0.5 = 2.5 -> 2.
  grid.insert_ray(center(grid, 0, 0), center(grid, 3, 0), true);
  EXPECT_EQ(grid.certainty({3, 0}), 3);  // (2 + 5) * 0.5 = 3.5 -> 3.
  grid.insert_ray(center(grid, 0, 0), center(grid, 4, 0), false);
  EXPECT_EQ(grid.certainty({3, 0}), 1);
  EXPECT_EQ(grid.certainty({4, 0}), 0);
}

using occgeo::testing::invalid_argument_message;

TEST(HimmGridTest, ParamsValidationNamesTheField) {
  const auto message_for = [](auto change) {
    HimmParams params;
    change(params);
    return invalid_argument_message([&params] { params.validate(); });
  };
  EXPECT_EQ(message_for([](HimmParams&) {}), "");
  EXPECT_EQ(message_for([](HimmParams& p) { p.cell_size_m = 0.0; }),
            "HimmParams.cell_size_m must be a finite number > 0, got 0");
  EXPECT_EQ(message_for([](HimmParams& p) { p.max_certainty = 16; }),
            "HimmParams.max_certainty must be in [1, 15], got 16");
  EXPECT_EQ(message_for([](HimmParams& p) { p.increment = 0; }), "HimmParams.increment must be in [1, 15], got 0");
  EXPECT_EQ(message_for([](HimmParams& p) { p.decrement = 20; }), "HimmParams.decrement must be in [1, 15], got 20");
  EXPECT_EQ(message_for([](HimmParams& p) { p.occupied_threshold = 0; }),
            "HimmParams.occupied_threshold must be in [1, 15], got 0");
  EXPECT_EQ(message_for([](HimmParams& p) { p.growth_center_weight = -1.0; }),
            "HimmParams.growth_center_weight must be a finite number >= 0, got -1");
  EXPECT_EQ(message_for([](HimmParams& p) { p.growth_neighbour_weight = std::numeric_limits<double>::infinity(); }),
            "HimmParams.growth_neighbour_weight must be a finite number >= 0, got inf");
  EXPECT_EQ(message_for([](HimmParams& p) { p.tile_cells = 48; }),
            "HimmParams.tile_cells must be a power of two in [2, 1024], got 48");
  HimmParams bad;
  bad.tile_cells = 2048;
  EXPECT_THROW(HimmGrid{bad}, std::invalid_argument);
}

TEST(HimmGridTest, BadReadingsAreRejectedWithoutChangingTheGrid) {
  HimmGrid grid{HimmParams{}};
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<float> ranges = {1.0F, 2.0F, nan};
  EXPECT_EQ(invalid_argument_message([&] {
              grid.insert_scan({0, 0, 0}, 0.0F, 0.1F, ranges, 4.0F);
            }),
            "insert_scan: ranges[2] is NaN or negative (nan)");
  const std::vector<float> negative = {-1.0F};
  EXPECT_EQ(invalid_argument_message([&] {
              grid.insert_scan({0, 0, 0}, 0.0F, 0.1F, negative, 4.0F);
            }),
            "insert_scan: ranges[0] is NaN or negative (-1)");
  EXPECT_EQ(invalid_argument_message([&] {
              grid.insert_scan({0, 0, 0}, 0.0F, 0.1F, ranges, 0.0F);
            }),
            "insert_scan: range_max must be finite and > 0, got 0");
  EXPECT_EQ(invalid_argument_message([&] {
              grid.insert_scan({0, 0, nan}, 0.0F, 0.1F, ranges, 4.0F);
            }),
            "insert_scan: X_WS is not finite");
  EXPECT_EQ(invalid_argument_message([&] {
              grid.insert_scan({1e12, 0, 0}, 0.0F, 0.1F, negative, 4.0F);
            }),
            "insert_scan: X_WS is too far from the origin");
  EXPECT_EQ(invalid_argument_message([&] {
              grid.insert_ray({0, 0}, {std::nan(""), 0}, true);
            }),
            "insert_ray: hit_point_W is not finite or too far from the origin");
  EXPECT_EQ(grid.version(), 0U);
  EXPECT_EQ(grid.tile_count(), 0U);
}

}  // namespace
}  // namespace occgeo::mapping
