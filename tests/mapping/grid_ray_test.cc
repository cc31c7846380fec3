#include "occgeo/geometry/grid_ray.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "cell_printer.h"

namespace occgeo::geometry {
namespace {

std::vector<CellIndex> ray_cells(double cell_size, const Eigen::Vector2d& p_start, const Eigen::Vector2d& p_end) {
  std::vector<CellIndex> cells;
  for_each_ray_cell(GridGeometry(cell_size), p_start, p_end, [&cells](const CellIndex& c) { cells.push_back(c); });
  return cells;
}

using Cells = std::vector<CellIndex>;

TEST(GridRayTest, AxisParallelSegments) {
  EXPECT_EQ(ray_cells(1.0, {0.5, 0.5}, {3.5, 0.5}), (Cells{{0, 0}, {1, 0}, {2, 0}, {3, 0}}));
  EXPECT_EQ(ray_cells(1.0, {0.5, 0.5}, {0.5, -2.5}), (Cells{{0, 0}, {0, -1}, {0, -2}, {0, -3}}));
  EXPECT_EQ(ray_cells(1.0, {-0.5, 2.5}, {-3.5, 2.5}), (Cells{{-1, 2}, {-2, 2}, {-3, 2}, {-4, 2}}));
  EXPECT_EQ(ray_cells(1.0, {4.5, -1.5}, {4.5, 1.5}), (Cells{{4, -2}, {4, -1}, {4, 0}, {4, 1}}));
}

TEST(GridRayTest, ZeroLengthSegmentIsItsCell) {
  EXPECT_EQ(ray_cells(1.0, {2.3, -1.7}, {2.3, -1.7}), (Cells{{2, -2}}));
  int visited = 0;
  const CellIndex end = for_each_cell_before_end(GridGeometry(1.0), {2.3, -1.7}, {2.3, -1.7},
                                                 [&visited](const CellIndex&) { ++visited; });
  EXPECT_EQ(visited, 0);
  EXPECT_EQ(end, (CellIndex{2, -2}));
}

TEST(GridRayTest, SegmentInsideOneCell) { EXPECT_EQ(ray_cells(1.0, {-0.9, -0.9}, {-0.1, -0.2}), (Cells{{-1, -1}})); }

TEST(GridRayTest, SlopedSegmentVisitsEveryCrossedCellInOrder) {
  // x crosses 1, 2, 3 at t = 1/6, 1/2, 5/6; y crosses 1, 2 at t = 1/4, 3/4.
  EXPECT_EQ(ray_cells(1.0, {0.5, 0.5}, {3.5, 2.5}), (Cells{{0, 0}, {1, 0}, {1, 1}, {2, 1}, {2, 2}, {3, 2}}));
}

TEST(GridRayTest, NegativeCoordinatesAndDirections) {
  // x crosses -1, -2, -3 at t = 0.19, 0.56, 0.93; y crosses 0, 1 at t = 0.26, 0.79.
  EXPECT_EQ(ray_cells(1.0, {-0.5, -0.5}, {-3.2, 1.4}), (Cells{{-1, -1}, {-2, -1}, {-2, 0}, {-3, 0}, {-3, 1}, {-4, 1}}));
  EXPECT_EQ(ray_cells(0.1, {-0.05, 0.25}, {0.15, 0.25}), (Cells{{-1, 2}, {0, 2}, {1, 2}}));
}

TEST(GridRayTest, ExactCornerCrossingStepsXFirst) {
  EXPECT_EQ(ray_cells(1.0, {0.5, 0.5}, {2.5, 2.5}), (Cells{{0, 0}, {1, 0}, {1, 1}, {2, 1}, {2, 2}}));
  EXPECT_EQ(ray_cells(1.0, {0.5, 0.5}, {-1.5, -1.5}), (Cells{{0, 0}, {-1, 0}, {-1, -1}, {-2, -1}, {-2, -2}}));
}

TEST(GridRayTest, StartOnACellSideMovingBackwards) {
  // x = 1.0 belongs to cell 1; moving towards -x leaves it at once.
  EXPECT_EQ(ray_cells(1.0, {1.0, 0.5}, {-0.5, 0.5}), (Cells{{1, 0}, {0, 0}, {-1, 0}}));
}

TEST(GridRayTest, CellsBeforeEndExcludeTheEndCell) {
  Cells before_end;
  const CellIndex end = for_each_cell_before_end(GridGeometry(1.0), {0.5, 0.5}, {3.5, 2.5},
                                                 [&before_end](const CellIndex& c) { before_end.push_back(c); });
  EXPECT_EQ(before_end, (Cells{{0, 0}, {1, 0}, {1, 1}, {2, 1}, {2, 2}}));
  EXPECT_EQ(end, (CellIndex{3, 2}));
}

TEST(GridRayTest, TraversalReportsRemainingCells) {
  GridRayTraversal traversal(GridGeometry(1.0), {0.5, 0.5}, {3.5, 2.5});
  EXPECT_EQ(traversal.end_cell(), (CellIndex{3, 2}));
  EXPECT_EQ(traversal.remaining_cells(), 5);
  traversal.advance();
  EXPECT_EQ(traversal.cell(), (CellIndex{1, 0}));
  EXPECT_EQ(traversal.remaining_cells(), 4);
}

TEST(GridRayTest, RejectsPointsItCannotIndex) {
  const GridGeometry grid(0.1);
  constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(GridRayTraversal(grid, {kNan, 0.0}, {1.0, 1.0}), std::invalid_argument);
  EXPECT_THROW(GridRayTraversal(grid, {0.0, 0.0}, {1.0, std::numeric_limits<double>::infinity()}),
               std::invalid_argument);
  EXPECT_THROW(GridRayTraversal(grid, {0.0, 0.0}, {1e9, 0.0}), std::invalid_argument);
  EXPECT_FALSE(is_traversable_point(grid, {0.1 * kMaxRayCellCoordinate, 0.0}));
  EXPECT_TRUE(is_traversable_point(grid, {-1e7, 1e7}));
}

// True when the segment p0-p1 meets the closed square of cell c, grown by a rounding margin (cell units).
bool segment_meets_cell(const Eigen::Vector2d& u0, const Eigen::Vector2d& u1, const CellIndex& c) {
  constexpr double kMargin = 1e-9;  // Far above the rounding of coordinates below 1e3 cells.
  double t_min = 0.0;
  double t_max = 1.0;
  for (int axis = 0; axis < 2; ++axis) {
    const double low = (axis == 0 ? c.ix : c.iy) - kMargin;
    const double high = (axis == 0 ? c.ix : c.iy) + 1.0 + kMargin;
    const double d = u1[axis] - u0[axis];
    if (d == 0.0) {
      if (u0[axis] < low || u0[axis] > high) return false;
      continue;
    }
    const double t_low = (low - u0[axis]) / d;
    const double t_high = (high - u0[axis]) / d;
    t_min = std::max(t_min, std::min(t_low, t_high));
    t_max = std::min(t_max, std::max(t_low, t_high));
  }
  return t_min <= t_max;
}

TEST(GridRayTest, RandomSegmentsGiveSideConnectedCellsOnTheSegment) {
  std::mt19937 random(7);
  std::uniform_real_distribution<double> coordinate(-30.0, 30.0);
  for (const double cell_size : {0.05, 0.1, 1.0}) {
    const GridGeometry grid(cell_size);
    for (int trial = 0; trial < 2000; ++trial) {
      const Eigen::Vector2d p0(coordinate(random), coordinate(random));
      const Eigen::Vector2d p1 = trial % 10 == 0 ? Eigen::Vector2d(p0.x(), coordinate(random))
                                                 : Eigen::Vector2d(coordinate(random), coordinate(random));
      const Cells cells = ray_cells(cell_size, p0, p1);
      const CellIndex first = grid.cell_of(p0);
      const CellIndex last = grid.cell_of(p1);
      ASSERT_EQ(cells.front(), first);
      ASSERT_EQ(cells.back(), last);
      ASSERT_EQ(cells.size(),
                static_cast<std::size_t>(std::abs(last.ix - first.ix) + std::abs(last.iy - first.iy) + 1));
      for (std::size_t i = 0; i < cells.size(); ++i) {
        ASSERT_TRUE(segment_meets_cell(p0 / cell_size, p1 / cell_size, cells[i])) << "trial " << trial << " cell " << i;
        if (i > 0) {
          ASSERT_EQ(std::abs(cells[i].ix - cells[i - 1].ix) + std::abs(cells[i].iy - cells[i - 1].iy), 1);
        }
      }
    }
  }
}

}  // namespace
}  // namespace occgeo::geometry
