// The shared vocabulary every layer uses: one angle convention, one stable hash, one world-to-cell conversion.

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <numbers>
#include <string_view>
#include <vector>

#include "occgeo/geometry/cell.h"
#include "occgeo/geometry/fnv1a.h"
#include "occgeo/geometry/pose.h"

namespace occgeo::geometry {
namespace {

constexpr double kPi = std::numbers::pi;

TEST(WrapAngle, WrapsIntoMinusPiExclusivePiInclusive) {
  EXPECT_DOUBLE_EQ(wrap_angle(kPi), kPi) << "straight behind is +pi";
  EXPECT_DOUBLE_EQ(wrap_angle(-kPi), kPi);
  EXPECT_DOUBLE_EQ(wrap_angle(3.0 * kPi), kPi);
  EXPECT_NEAR(wrap_angle(2.0 * kPi), 0.0, 1e-15);
  EXPECT_NEAR(wrap_angle(-0.5 * kPi - 4.0 * kPi), -0.5 * kPi, 1e-12);
  EXPECT_NEAR(wrap_angle(kPi + 0.1), -kPi + 0.1, 1e-12);
  for (const double a : {0.0, 0.25, -0.25, 1.5, -1.5, 3.1, -3.1}) EXPECT_NEAR(wrap_angle(a), a, 1e-15);
}

// Cells are half-open squares anchored at the origin: points on a cell's lower edge belong to it, negative
// coordinates round down. Points that are not finite or 2^30 cells or more away have no cell, rather than a wrapped
// int32 that names some other cell.
TEST(GridGeometry, CheckedCellOfAgreesWithCellOfAndRefusesWhatHasNoCell) {
  const GridGeometry cells(0.1);
  for (const Eigen::Vector2d& p : {Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(0.25, -0.25), Eigen::Vector2d(-0.05, 3.0),
                                   Eigen::Vector2d(-1.0e6, 1.0e6)}) {
    const std::optional<CellIndex> checked = cells.checked_cell_of(p);
    ASSERT_TRUE(checked.has_value()) << p.transpose();
    EXPECT_EQ(*checked, cells.cell_of(p)) << p.transpose();
  }
  EXPECT_EQ(cells.checked_cell_of({-0.05, 0.0}), (CellIndex{-1, 0}));
  EXPECT_EQ(cells.checked_cell_of({0.1, 0.2}), (CellIndex{1, 2}));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(cells.checked_cell_of({nan, 0.0}).has_value());
  EXPECT_FALSE(cells.checked_cell_of({0.0, -inf}).has_value());
  const double edge_m = GridGeometry::kMaxCellIndex * 0.1;
  EXPECT_FALSE(cells.checked_cell_of({edge_m, 0.0}).has_value()) << "2^30 cells out";
  EXPECT_FALSE(cells.checked_cell_of({0.0, -edge_m - 0.1}).has_value());
  EXPECT_TRUE(cells.checked_cell_of({edge_m - 1.0, 0.0}).has_value());
}

TEST(Fnv1a, MatchesTheReferenceVectorsAndChains) {
  // Reference values of 64-bit FNV-1a (Fowler, Noll, Vo).
  EXPECT_EQ(fnv1a(std::string_view{}), 0xcbf29ce484222325ULL);
  EXPECT_EQ(fnv1a(std::string_view("a")), 0xaf63dc4c8601ec8cULL);
  EXPECT_EQ(fnv1a(std::string_view("foobar")), 0x85944171f73967e8ULL);
  EXPECT_EQ(fnv1a(std::string_view("bar"), fnv1a(std::string_view("foo"))), fnv1a(std::string_view("foobar")));
  const std::vector<std::uint8_t> bytes{'f', 'o', 'o', 'b', 'a', 'r'};
  EXPECT_EQ(fnv1a(std::span<const std::uint8_t>(bytes)), fnv1a(std::string_view("foobar")));
}

}  // namespace
}  // namespace occgeo::geometry
