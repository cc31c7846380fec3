// The shared vocabulary every layer uses: one angle convention and one stable hash.

#include <gtest/gtest.h>

#include <cstdint>
#include <numbers>
#include <string_view>
#include <vector>

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
