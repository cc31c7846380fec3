#include "occgeo/geometry/collision.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <unordered_set>
#include <vector>

#include "occgeo/geometry/convex_polygon.h"

namespace occgeo::geometry {
namespace {

using Vec = Eigen::Vector2d;

// Occupied cells held in a hash set, as simple as an OccupiedCellSource can be.
class SetCellSource : public OccupiedCellSource {
 public:
  explicit SetCellSource(double cell_size) : cell_size_(cell_size) {}

  void add(CellIndex cell) { cells_.insert(cell); }
  [[nodiscard]] const std::unordered_set<CellIndex, CellIndexHash>& cells() const { return cells_; }

  double cell_size() const override { return cell_size_; }
  void for_each_occupied(CellIndex min, CellIndex max,
                         const std::function<bool(const CellIndex&)>& visit) const override {
    for (std::int32_t iy = min.iy; iy <= max.iy; ++iy) {
      for (std::int32_t ix = min.ix; ix <= max.ix; ++ix) {
        if (cells_.contains({ix, iy}) && !visit({ix, iy})) return;
      }
    }
  }

 private:
  double cell_size_;
  std::unordered_set<CellIndex, CellIndexHash> cells_;
};

// ---------------------------------------------------------------------------------------------------------------
// Brute-force reference, written independently of the library: convex polygons in counter-clockwise order, closed
// (touching counts as overlap), distances as minima over all edge pairs. No FCL, no separating axes.

using Polygon = std::vector<Vec>;

double cross(const Vec& a, const Vec& b) { return a.x() * b.y() - a.y() * b.x(); }

double point_segment_distance(const Vec& p, const Vec& a, const Vec& b) {
  const Vec ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (a + t * ab - p).norm();
}

bool segments_intersect(const Vec& a, const Vec& b, const Vec& c, const Vec& d) {
  const double d1 = cross(b - a, c - a), d2 = cross(b - a, d - a), d3 = cross(d - c, a - c), d4 = cross(d - c, b - c);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return true;
  return point_segment_distance(c, a, b) == 0.0 || point_segment_distance(d, a, b) == 0.0 ||
         point_segment_distance(a, c, d) == 0.0 || point_segment_distance(b, c, d) == 0.0;
}

bool contains(const Polygon& polygon, const Vec& p) {
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    if (cross(polygon[(i + 1) % polygon.size()] - polygon[i], p - polygon[i]) < 0.0) return false;
  }
  return true;
}

double point_polygon_distance(const Vec& p, const Polygon& polygon) {
  if (contains(polygon, p)) return 0.0;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    best = std::min(best, point_segment_distance(p, polygon[i], polygon[(i + 1) % polygon.size()]));
  }
  return best;
}

double polygon_distance(const Polygon& a, const Polygon& b) {
  if (contains(a, b[0]) || contains(b, a[0])) return 0.0;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < a.size(); ++i) {
    const Vec& a0 = a[i];
    const Vec& a1 = a[(i + 1) % a.size()];
    for (std::size_t j = 0; j < b.size(); ++j) {
      const Vec& b0 = b[j];
      const Vec& b1 = b[(j + 1) % b.size()];
      if (segments_intersect(a0, a1, b0, b1)) return 0.0;
      best = std::min({best, point_segment_distance(a0, b0, b1), point_segment_distance(a1, b0, b1),
                       point_segment_distance(b0, a0, a1), point_segment_distance(b1, a0, a1)});
    }
  }
  return best;
}

Polygon cell_polygon(const CellIndex& cell, double s) {
  const double x0 = cell.ix * s, y0 = cell.iy * s, x1 = (cell.ix + 1) * s, y1 = (cell.iy + 1) * s;
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

// The box outline in world, its half sizes grown by `grow` metres (negative shrinks).
Polygon box_polygon(const BoxFootprint& box, const Pose2& X_WB, double grow) {
  const double hx = box.length / 2 + grow, hy = box.width / 2 + grow;
  Polygon corners;
  for (const Vec& local : {Vec(hx, -hy), Vec(hx, hy), Vec(-hx, hy), Vec(-hx, -hy)}) {  // Counter-clockwise.
    corners.push_back(X_WB.transform(local + Vec(box.center_x, 0.0)));
  }
  return corners;
}

// The polygon footprint's outline in world, each edge moved outwards by `grow` metres (negative shrinks): vertex k
// becomes the intersection of its two edges' moved lines.
Polygon grown_polygon(const ConvexPolygonFootprint& polygon, const Pose2& X_WB, double grow) {
  Polygon placed;
  for (const Vec& v : polygon.vertices_B) placed.push_back(X_WB.transform(v));
  if (grow == 0.0) return placed;
  const std::size_t n = placed.size();
  Polygon grown;
  for (std::size_t k = 0; k < n; ++k) {
    const Vec& previous = placed[(k + n - 1) % n];
    const Vec& vertex = placed[k];
    const Vec& next = placed[(k + 1) % n];
    const Vec d1 = (vertex - previous).normalized(), d2 = (next - vertex).normalized();
    const Vec n1(d1.y(), -d1.x()), n2(d2.y(), -d2.x());
    // vertex + t: n1 . t = grow and n2 . t = grow.
    const double det = n1.x() * n2.y() - n1.y() * n2.x();
    grown.push_back(vertex + Vec(grow * (n2.y() - n1.y()), grow * (n1.x() - n2.x())) / det);
  }
  return grown;
}

// Distance from the footprint, grown by `grow` metres, to the cell; 0 when they overlap or touch.
double reference_distance(const Footprint& footprint, const Pose2& X_WB, const CellIndex& cell, double s,
                          double grow = 0.0) {
  const Polygon square = cell_polygon(cell, s);
  if (const auto* box = std::get_if<BoxFootprint>(&footprint)) {
    return polygon_distance(box_polygon(*box, X_WB, grow), square);
  }
  if (const auto* polygon = std::get_if<ConvexPolygonFootprint>(&footprint)) {
    return polygon_distance(grown_polygon(*polygon, X_WB, grow), square);
  }
  const double radius = std::get<CylinderFootprint>(footprint).radius + grow;
  return std::max(0.0, point_polygon_distance(X_WB.position(), square) - radius);
}

// Touching within this distance is a coin toss for any floating-point implementation (the reference included): such
// cases are reported as ambiguous and not compared. Random poses land there with probability ~1e-8.
constexpr double kTouchTolerance_m = 1e-9;

enum class Contact { kNo, kYes, kAmbiguous };

Contact reference_contact(const Footprint& footprint, const Pose2& X_WB, const CellIndex& cell, double s) {
  const bool grown = reference_distance(footprint, X_WB, cell, s, kTouchTolerance_m) == 0.0;
  const bool shrunk = reference_distance(footprint, X_WB, cell, s, -kTouchTolerance_m) == 0.0;
  if (grown != shrunk) return Contact::kAmbiguous;
  return grown ? Contact::kYes : Contact::kNo;
}

// ---------------------------------------------------------------------------------------------------------------
// Random maps and poses.

enum class Shape { kBox, kCylinder, kPolygon };

// Maps cover cells [-half_cells, half_cells)^2 around `origin_cell`; poses fall on and a little beyond the map.
class RandomCases {
 public:
  explicit RandomCases(std::uint32_t seed) : rng_(seed) {}

  SetCellSource make_map(double cell_size, double density, CellIndex origin_cell, int half_cells) {
    SetCellSource map(cell_size);
    std::bernoulli_distribution occupied(density);
    for (int iy = -half_cells; iy < half_cells; ++iy) {
      for (int ix = -half_cells; ix < half_cells; ++ix) {
        if (occupied(rng_)) map.add({origin_cell.ix + ix, origin_cell.iy + iy});
      }
    }
    return map;
  }

  Pose2 make_pose(const SetCellSource& map, CellIndex origin_cell, int half_cells) {
    const double extent = (half_cells + 5) * map.cell_size();
    std::uniform_real_distribution<double> offset(-extent, extent);
    std::uniform_real_distribution<double> heading(-M_PI, M_PI);
    return {origin_cell.ix * map.cell_size() + offset(rng_), origin_cell.iy * map.cell_size() + offset(rng_),
            heading(rng_)};
  }

  Footprint make_box() {
    std::uniform_real_distribution<double> length(0.2, 1.5), width(0.15, 1.0), center_x(-0.4, 0.4);
    return BoxFootprint{length(rng_), width(rng_), 1.0, center_x(rng_)};
  }
  Footprint make_cylinder() {
    std::uniform_real_distribution<double> radius(0.05, 0.8);
    return CylinderFootprint{radius(rng_), 1.2};
  }
  // 3 to 16 vertices on a tilted ellipse (strictly convex in angle order), offset so base_link may lie outside.
  Footprint make_polygon() {
    std::uniform_real_distribution<double> semi_axis(0.05, 0.8), offset(-0.4, 0.4), angle(0.0, 2 * M_PI);
    const int n = std::uniform_int_distribution<int>(3, 16)(rng_);
    const double a = semi_axis(rng_), b = semi_axis(rng_), cx = offset(rng_), cy = offset(rng_), tilt = angle(rng_);
    std::vector<double> angles;
    while (static_cast<int>(angles.size()) < n) {
      const double t = angle(rng_);
      const bool apart = std::all_of(angles.begin(), angles.end(), [&](double u) {
        const double gap = std::abs(t - u);
        return std::min(gap, 2 * M_PI - gap) > 0.05;
      });
      if (apart) angles.push_back(t);
    }
    std::sort(angles.begin(), angles.end());
    ConvexPolygonFootprint polygon{.vertices_B = {}, .height = 0.8};
    for (const double t : angles) {
      const Vec p = Eigen::Rotation2Dd(tilt) * Vec(a * std::cos(t), b * std::sin(t));
      polygon.vertices_B.push_back(p + Vec(cx, cy));
    }
    return polygon;
  }
  Footprint make(Shape shape) {
    switch (shape) {
      case Shape::kBox:
        return make_box();
      case Shape::kCylinder:
        return make_cylinder();
      case Shape::kPolygon:
        return make_polygon();
    }
    return make_box();
  }
  double make_max_distance() { return std::uniform_real_distribution<double>(0.0, 3.0)(rng_); }

 private:
  std::mt19937 rng_;
};

struct MapSpec {
  double cell_size;
  double density;
  CellIndex origin_cell;
};

// Three cell sizes, densities from nearly empty to half full, and one map 700 m from the origin for precision.
const std::vector<MapSpec> kMaps = {
    {0.1, 0.003, {0, 0}}, {0.1, 0.01, {0, 0}},        {0.1, 0.05, {0, 0}},  {0.1, 0.2, {3, -7}},
    {0.1, 0.5, {0, 0}},   {0.25, 0.005, {2, 2}},      {0.25, 0.02, {0, 0}}, {0.25, 0.1, {-4, 11}},
    {0.05, 0.05, {0, 0}}, {0.1, 0.05, {7000, -5000}},
};
constexpr int kHalfCells = 30;
constexpr int kPosesPerMap = 320;

struct Tally {
  int compared = 0;
  int ambiguous = 0;
  int hits = 0;
};

void check_collision_against_reference(Shape shape, std::uint32_t seed) {
  RandomCases random(seed);
  Tally tally;
  for (const MapSpec& spec : kMaps) {
    const SetCellSource map = random.make_map(spec.cell_size, spec.density, spec.origin_cell, kHalfCells);
    for (int i = 0; i < kPosesPerMap; ++i) {
      const Footprint footprint = random.make(shape);
      const Pose2 pose = random.make_pose(map, spec.origin_cell, kHalfCells);
      bool any_yes = false, any_ambiguous = false;
      for (const CellIndex& cell : map.cells()) {
        const Contact contact = reference_contact(footprint, pose, cell, map.cell_size());
        any_yes |= contact == Contact::kYes;
        any_ambiguous |= contact == Contact::kAmbiguous;
      }
      const CollisionResult result = check_collision({footprint, pose}, map);
      if (result.hit) {
        ASSERT_TRUE(result.cell.has_value());
        ASSERT_TRUE(map.cells().contains(*result.cell));
        // The reported cell must touch the footprint, up to the touching tolerance.
        EXPECT_NE(reference_contact(footprint, pose, *result.cell, map.cell_size()), Contact::kNo)
            << "pose " << pose.x << " " << pose.y << " " << pose.theta;
      } else {
        EXPECT_FALSE(result.cell.has_value());
      }
      if (any_ambiguous && !any_yes) {
        ++tally.ambiguous;
        continue;
      }
      ++tally.compared;
      tally.hits += any_yes;
      ASSERT_EQ(result.hit, any_yes) << "cell size " << spec.cell_size << " density " << spec.density << " pose "
                                     << pose.x << " " << pose.y << " " << pose.theta;
    }
  }
  // Nearly every case is compared, and both outcomes are well represented (3200 cases, ~55% hits, with the seeds here).
  EXPECT_GE(tally.compared, 3000);
  EXPECT_LE(tally.ambiguous, 2);
  EXPECT_GE(tally.hits, tally.compared / 4);
  EXPECT_LE(tally.hits, tally.compared * 3 / 4);
}

// Reference and library both compute closed-form distances in double precision, so they differ by rounding only
// (~1e-13 m at 700 m from the origin); 1e-9 m is far above that and far below anything that matters.
constexpr double kDistanceTolerance_m = 1e-9;

void check_clearance_against_reference(Shape shape, std::uint32_t seed) {
  RandomCases random(seed);
  int compared = 0, in_contact = 0, apart = 0;
  for (const MapSpec& spec : kMaps) {
    const SetCellSource map = random.make_map(spec.cell_size, spec.density, spec.origin_cell, kHalfCells);
    const double s = map.cell_size();
    for (int i = 0; i < kPosesPerMap; ++i) {
      const Footprint footprint = random.make(shape);
      const Pose2 pose = random.make_pose(map, spec.origin_cell, kHalfCells);
      const double max_distance = random.make_max_distance();
      double nearest = std::numeric_limits<double>::infinity();
      for (const CellIndex& cell : map.cells()) {
        nearest = std::min(nearest, reference_distance(footprint, pose, cell, s));
      }
      const ClearanceResult result = compute_clearance({footprint, pose, max_distance}, map);
      ++compared;
      if (std::abs(nearest - max_distance) > kDistanceTolerance_m) {
        ASSERT_EQ(result.found, nearest <= max_distance) << "pose " << pose.x << " " << pose.y << " " << pose.theta;
      }
      if (!result.found) {
        EXPECT_EQ(result.clearance_m, max_distance);
        EXPECT_FALSE(result.nearest_cell.has_value());
        continue;
      }
      in_contact += result.clearance_m == 0.0;
      apart += result.clearance_m > 0.0;
      ASSERT_NEAR(result.clearance_m, nearest, kDistanceTolerance_m)
          << "pose " << pose.x << " " << pose.y << " " << pose.theta;
      ASSERT_TRUE(result.nearest_cell.has_value());
      ASSERT_TRUE(map.cells().contains(*result.nearest_cell));
      EXPECT_NEAR(reference_distance(footprint, pose, *result.nearest_cell, s), nearest, kDistanceTolerance_m);
      // The nearest point lies on the nearest cell, as far from the footprint as the clearance.
      const Polygon square = cell_polygon(*result.nearest_cell, s);
      const Vec p = result.nearest_point_W;
      EXPECT_TRUE(p.x() >= square[0].x() - 1e-12 && p.x() <= square[2].x() + 1e-12 && p.y() >= square[0].y() - 1e-12 &&
                  p.y() <= square[2].y() + 1e-12);
      if (result.clearance_m > 0.0) {
        double point_distance = 0.0;
        if (const auto* box = std::get_if<BoxFootprint>(&footprint)) {
          point_distance = point_polygon_distance(p, box_polygon(*box, pose, 0.0));
        } else if (const auto* polygon = std::get_if<ConvexPolygonFootprint>(&footprint)) {
          point_distance = point_polygon_distance(p, grown_polygon(*polygon, pose, 0.0));
        } else {
          point_distance = (p - pose.position()).norm() - std::get<CylinderFootprint>(footprint).radius;
        }
        EXPECT_NEAR(point_distance, result.clearance_m, kDistanceTolerance_m);
      }
    }
  }
  // Contact and clear cases are both well represented (3200 cases, over 1000 of each, with the seeds here).
  EXPECT_GE(compared, 3000);
  EXPECT_GE(in_contact, compared / 4);
  EXPECT_GE(apart, compared / 4);
}

TEST(CollisionRandomized, BoxAgreesWithBruteForce) { check_collision_against_reference(Shape::kBox, 20240601); }
TEST(CollisionRandomized, CylinderAgreesWithBruteForce) {
  check_collision_against_reference(Shape::kCylinder, 20240602);
}
TEST(CollisionRandomized, PolygonAgreesWithBruteForce) { check_collision_against_reference(Shape::kPolygon, 20240605); }
TEST(ClearanceRandomized, BoxAgreesWithBruteForce) { check_clearance_against_reference(Shape::kBox, 20240603); }
TEST(ClearanceRandomized, CylinderAgreesWithBruteForce) {
  check_clearance_against_reference(Shape::kCylinder, 20240604);
}
TEST(ClearanceRandomized, PolygonAgreesWithBruteForce) { check_clearance_against_reference(Shape::kPolygon, 20240606); }

// Axis-aligned poses on a binary-exact lattice (cell size 0.25 m, positions in 1/8 m) make touching exact in floating
// point, so here the comparison includes touching and allows no tolerance.
TEST(CollisionLattice, TouchingCountsAsContactExactly) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> eighths(-24, 24), size_in_eighths(1, 10);
  SetCellSource map(0.25);
  std::bernoulli_distribution occupied(0.08);
  for (int iy = -12; iy < 12; ++iy) {
    for (int ix = -12; ix < 12; ++ix) {
      if (occupied(rng)) map.add({ix, iy});
    }
  }
  int touching_only = 0;
  for (int i = 0; i < 2000; ++i) {
    const Pose2 pose{eighths(rng) / 8.0, eighths(rng) / 8.0, 0.0};
    Footprint footprint =
        i % 2 == 0 ? Footprint{BoxFootprint{size_in_eighths(rng) / 8.0, size_in_eighths(rng) / 8.0, 1.0, 0.0}}
                   : Footprint{CylinderFootprint{size_in_eighths(rng) / 8.0, 1.0}};
    if (i % 3 == 0) {
      // A lattice rectangle with one corner cut at 45 degrees: a pentagon whose edges, slanted one included, meet
      // cells exactly.
      const double x0 = -size_in_eighths(rng) / 8.0, y0 = -size_in_eighths(rng) / 8.0;
      const double x1 = size_in_eighths(rng) / 8.0, y1 = size_in_eighths(rng) / 8.0;
      const double cut = std::min(x1 - x0, y1 - y0) / 2.0;
      footprint = ConvexPolygonFootprint{.vertices_B = {{x0 + cut, y0}, {x1, y0}, {x1, y1}, {x0, y1}, {x0, y0 + cut}},
                                         .height = 1.0};
    }
    bool expected = false, overlapping = false;
    for (const CellIndex& cell : map.cells()) {
      expected |= reference_distance(footprint, pose, cell, 0.25) == 0.0;
      overlapping |= reference_distance(footprint, pose, cell, 0.25, -kTouchTolerance_m) == 0.0;
    }
    touching_only += expected && !overlapping;
    ASSERT_EQ(check_collision({footprint, pose}, map).hit, expected) << "case " << i;
    ASSERT_EQ(compute_clearance({footprint, pose, 1.0}, map).clearance_m == 0.0, expected) << "case " << i;
  }
  EXPECT_GE(touching_only, 50);  // The lattice really does produce exact touching.
}

// ---------------------------------------------------------------------------------------------------------------
// Literal cases.

TEST(Collision, BoxFullyInsideOneOccupiedCell) {
  SetCellSource map(1.0);
  map.add({0, 0});
  const CollisionRequest request{BoxFootprint{0.2, 0.1, 0.5, 0.0}, {0.5, 0.5, 0.3}};
  const CollisionResult result = check_collision(request, map);
  EXPECT_TRUE(result.hit);
  EXPECT_EQ(result.cell, (CellIndex{0, 0}));
  EXPECT_EQ(result.cells_tested, 1);
  const ClearanceResult clearance = compute_clearance({request.footprint, request.pose}, map);
  EXPECT_TRUE(clearance.found);
  EXPECT_EQ(clearance.clearance_m, 0.0);
  EXPECT_EQ(clearance.nearest_cell, (CellIndex{0, 0}));
  EXPECT_EQ(clearance.nearest_point_W, Vec(0.5, 0.5));  // In contact: the cell point nearest the footprint centre.
}

TEST(Collision, BoxExactlyTouchingIsAHitAndAMicronAwayIsNot) {
  SetCellSource map(0.25);
  map.add({4, 0});                              // [1.0, 1.25] x [0, 0.25]
  const BoxFootprint box{1.0, 0.5, 1.0, 0.25};  // base_link 0.25 m behind the box centre
  const CollisionResult touching = check_collision({box, {0.25, 0.25, 0.0}}, map);  // box [0, 1] x [0, 0.5]
  EXPECT_TRUE(touching.hit);
  EXPECT_EQ(touching.cell, (CellIndex{4, 0}));
  EXPECT_EQ(compute_clearance({box, {0.25, 0.25, 0.0}}, map).clearance_m, 0.0);

  const Pose2 apart{0.25 - 1e-6, 0.25, 0.0};
  EXPECT_FALSE(check_collision({box, apart}, map).hit);
  const ClearanceResult clearance = compute_clearance({box, apart}, map);
  EXPECT_TRUE(clearance.found);
  EXPECT_NEAR(clearance.clearance_m, 1e-6, 1e-12);
  EXPECT_EQ(clearance.nearest_cell, (CellIndex{4, 0}));
  EXPECT_DOUBLE_EQ(clearance.nearest_point_W.x(), 1.0);
}

TEST(Collision, BoxRotated45DegreesMissesTheCellItsAxisAlignedTwinHits) {
  SetCellSource map(0.1);
  map.add({4, 4});  // [0.4, 0.5]^2: inside the axis-aligned unit box, beyond the diamond's edge x + y = sqrt(2)/2.
  const BoxFootprint unit_box{1.0, 1.0, 1.0, 0.0};
  EXPECT_TRUE(check_collision({unit_box, {0.0, 0.0, 0.0}}, map).hit);
  const Pose2 diamond{0.0, 0.0, M_PI / 4};
  EXPECT_FALSE(check_collision({unit_box, diamond}, map).hit);
  const ClearanceResult clearance = compute_clearance({unit_box, diamond}, map);
  // From the cell corner (0.4, 0.4) to the edge x + y = sqrt(2)/2.
  EXPECT_NEAR(clearance.clearance_m, 0.8 / std::sqrt(2.0) - 0.5, 1e-12);
  EXPECT_NEAR((clearance.nearest_point_W - Vec(0.4, 0.4)).norm(), 0.0, 1e-12);

  map.add({7, 0});  // [0.7, 0.8] x [0, 0.1] holds the diamond's corner (sqrt(2)/2, 0).
  const CollisionResult hit = check_collision({unit_box, diamond}, map);
  EXPECT_TRUE(hit.hit);
  EXPECT_EQ(hit.cell, (CellIndex{7, 0}));
}

TEST(Collision, CylinderTouchingAndDiagonalClearance) {
  SetCellSource map(0.25);
  const CylinderFootprint cylinder{0.5, 1.0};
  map.add({2, 2});  // Corner (0.5, 0.5) is sqrt(0.5) from the axis.
  EXPECT_FALSE(check_collision({cylinder, {0.0, 0.0, 1.0}}, map).hit);
  const ClearanceResult clearance = compute_clearance({cylinder, {0.0, 0.0, 1.0}}, map);
  EXPECT_NEAR(clearance.clearance_m, std::sqrt(0.5) - 0.5, 1e-15);
  EXPECT_EQ(clearance.nearest_point_W, Vec(0.5, 0.5));

  map.add({2, -1});  // [0.5, 0.75] x [-0.25, 0]: touches the circle at (0.5, 0).
  const CollisionResult touching = check_collision({cylinder, {0.0, 0.0, 1.0}}, map);
  EXPECT_TRUE(touching.hit);
  EXPECT_EQ(touching.cell, (CellIndex{2, -1}));
  EXPECT_EQ(compute_clearance({cylinder, {0.0, 0.0, 1.0}}, map).clearance_m, 0.0);
  EXPECT_FALSE(check_collision({cylinder, {-1e-9, 0.0, 1.0}}, map).hit);
}

TEST(Clearance, MaxDistanceCutsTheSearchOff) {
  SetCellSource map(0.1);
  map.add({10, 0});  // [1.0, 1.1] x [0, 0.1]: 0.5 m beyond a cylinder of radius 0.5 at the origin.
  const CylinderFootprint cylinder{0.5, 1.0};
  const ClearanceResult short_search = compute_clearance({cylinder, {}, 0.4}, map);
  EXPECT_FALSE(short_search.found);
  EXPECT_EQ(short_search.clearance_m, 0.4);
  EXPECT_FALSE(short_search.nearest_cell.has_value());

  const ClearanceResult long_search = compute_clearance({cylinder, {}, 2.0}, map);
  EXPECT_TRUE(long_search.found);
  EXPECT_NEAR(long_search.clearance_m, 0.5, 1e-12);
  EXPECT_EQ(long_search.nearest_cell, (CellIndex{10, 0}));

  const ClearanceResult zero_search = compute_clearance({cylinder, {}, 0.0}, map);
  EXPECT_FALSE(zero_search.found);
  EXPECT_EQ(zero_search.clearance_m, 0.0);
}

TEST(Clearance, FindsTheNearerOfTwoCellsInDifferentRings) {
  SetCellSource map(0.1);
  map.add({0, 30});   // Bottom edge y = 3.0: 2.5 m from a disc of radius 0.5 at the origin.
  map.add({-21, 0});  // Right edge x = -2.0: 1.5 m from the disc.
  const ClearanceResult result = compute_clearance({CylinderFootprint{0.5, 1.0}, {}, 5.0}, map);
  EXPECT_NEAR(result.clearance_m, 1.5, 1e-12);
  EXPECT_EQ(result.nearest_cell, (CellIndex{-21, 0}));
}

TEST(Collision, EmptyMapHasNothingToHit) {
  const SetCellSource map(0.1);
  const CollisionResult result = check_collision({BoxFootprint{}, {1.0, 2.0, 0.5}}, map);
  EXPECT_FALSE(result.hit);
  EXPECT_FALSE(result.cell.has_value());
  EXPECT_EQ(result.cells_tested, 0);
  const ClearanceResult clearance = compute_clearance({BoxFootprint{}, {1.0, 2.0, 0.5}, 3.0}, map);
  EXPECT_FALSE(clearance.found);
  EXPECT_EQ(clearance.clearance_m, 3.0);
}

TEST(Collision, OnlyCellsInTheFootprintsWorldAabbAreTested) {
  SetCellSource map(0.1);
  // The box at the origin spans [-0.5, 0.5] x [-0.4, 0.4]; the cells touching it run from (-6, -5) to (5, 4).
  // Surround those with occupied cells.
  for (int i = -6; i <= 6; ++i) {
    map.add({i, -6});
    map.add({i, 5});
    map.add({-7, i});
    map.add({6, i});
  }
  const CollisionResult result = check_collision({BoxFootprint{1.0, 0.8, 1.0, 0.0}, {0.0, 0.0, 0.0}}, map);
  EXPECT_FALSE(result.hit);
  EXPECT_EQ(result.cells_tested, 0);
  map.add({0, 0});
  const CollisionResult hit = check_collision({BoxFootprint{1.0, 0.8, 1.0, 0.0}, {0.02, 0.03, 0.0}}, map);
  EXPECT_TRUE(hit.hit);
}

// The message of the std::invalid_argument that running `query` throws, or "no exception".
template <typename Query>
std::string error_of(const Query& query) {
  try {
    query();
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "no exception";
}

TEST(Collision, RejectsBadRequestsNamingTheField) {
  const SetCellSource map(0.1);
  const auto collision_error = [&map](const CollisionRequest& request) {
    return error_of([&] { check_collision(request, map); });
  };
  const auto clearance_error = [&map](const ClearanceRequest& request) {
    return error_of([&] { compute_clearance(request, map); });
  };
  EXPECT_EQ(collision_error({BoxFootprint{}, {NAN, 0.0, 0.0}}), "CollisionRequest.pose must be finite");
  EXPECT_EQ(collision_error({BoxFootprint{-1.0, 0.8, 1.0, 0.0}, {}}),
            "CollisionRequest.footprint.length must be positive and finite, got -1.000000");
  EXPECT_EQ(clearance_error({CylinderFootprint{0.0, 1.0}, {}}),
            "ClearanceRequest.footprint.radius must be positive and finite, got 0.000000");
  EXPECT_EQ(clearance_error({CylinderFootprint{}, {}, -1.0}),
            "ClearanceRequest.max_distance_m must be finite and >= 0, got -1.000000");
  EXPECT_EQ(collision_error({CylinderFootprint{}, {1e12, 0.0, 0.0}}),
            "CollisionRequest.pose: search area outside the int32 cell index range");
  EXPECT_EQ(clearance_error({CylinderFootprint{}, {}, 1e9}),
            "ClearanceRequest.pose and max_distance_m: search area outside the int32 cell index range");
  const std::vector<Vec> square = {{0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}, {-0.5, -0.5}};
  EXPECT_EQ(collision_error({ConvexPolygonFootprint{square, 0.0}, {}}),
            "CollisionRequest.footprint.height must be positive and finite, got 0.000000");
  const std::vector<Vec> clockwise(square.rbegin(), square.rend());
  EXPECT_EQ(collision_error({ConvexPolygonFootprint{clockwise, 1.0}, {}}),
            "CollisionRequest.footprint.polygon.vertices must be counter-clockwise");
  EXPECT_EQ(clearance_error({ConvexPolygonFootprint{{{0.0, 0.0}, {1.0, 0.0}}, 1.0}, {}}),
            "ClearanceRequest.footprint.polygon.vertices needs at least 3 vertices, got 2");
}

// A polygon footprint answers exactly like the box with the same outline, on random maps and poses (collision, the
// contact cell, clearance and its nearest cell), and a lattice-placed square exactly touching a cell is a hit.
TEST(PolygonFootprint, AnswersLikeTheBoxWithTheSameOutline) {
  RandomCases random(20240607);
  int cases = 0, hits = 0;
  for (const MapSpec& spec : kMaps) {
    const SetCellSource map = random.make_map(spec.cell_size, spec.density, spec.origin_cell, kHalfCells);
    for (int i = 0; i < 100; ++i, ++cases) {
      const auto box = std::get<BoxFootprint>(random.make_box());
      const double hx = box.length / 2, hy = box.width / 2, cx = box.center_x;
      const ConvexPolygonFootprint polygon{{{cx - hx, -hy}, {cx + hx, -hy}, {cx + hx, hy}, {cx - hx, hy}}, box.height};
      const Pose2 pose = random.make_pose(map, spec.origin_cell, kHalfCells);
      const CollisionResult by_box = check_collision({box, pose}, map);
      const CollisionResult by_polygon = check_collision({polygon, pose}, map);
      ASSERT_EQ(by_polygon.hit, by_box.hit) << "case " << cases;
      hits += by_box.hit;
      const ClearanceResult box_clearance = compute_clearance({box, pose, 1.5}, map);
      const ClearanceResult polygon_clearance = compute_clearance({polygon, pose, 1.5}, map);
      ASSERT_EQ(polygon_clearance.found, box_clearance.found) << "case " << cases;
      EXPECT_NEAR(polygon_clearance.clearance_m, box_clearance.clearance_m, 1e-12) << "case " << cases;
    }
  }
  EXPECT_GE(cases, 1000);
  EXPECT_GT(hits, cases / 5);
  EXPECT_LT(hits, cases * 4 / 5);

  SetCellSource one_cell(0.25);
  one_cell.add({2, 0});  // x in [0.5, 0.75], y in [0, 0.25].
  const ConvexPolygonFootprint triangle{{{0.0, 0.0}, {0.5, 0.0}, {0.0, 0.5}}, 1.0};
  EXPECT_TRUE(check_collision({triangle, {0.0, 0.0, 0.0}}, one_cell).hit) << "touching the cell's corner counts";
  EXPECT_FALSE(check_collision({triangle, {-0.125, 0.0, 0.0}}, one_cell).hit);
  const ClearanceResult clear = compute_clearance({triangle, {-0.125, 0.0, 0.0}, 1.0}, one_cell);
  ASSERT_TRUE(clear.found);
  EXPECT_NEAR(clear.clearance_m, 0.125, 1e-12);
  EXPECT_NEAR((clear.nearest_point_W - Vec(0.5, 0.0)).norm(), 0.0, 1e-12);
}

TEST(PolygonFootprint, ValidationNamesTheOffendingVertex) {
  using Vertices = std::vector<Vec>;
  const auto problem = [](const Vertices& vertices) {
    return convex_polygon_problem(vertices, Orientation::counter_clockwise);
  };
  EXPECT_EQ(problem({{0, 0}, {1, 0}, {1, 1}, {0, 1}}), "");
  EXPECT_EQ(problem({{0, 0}, {1, 0}, {0.5, 0.2}, {1, 1}, {0, 1}}),
            "vertices[2] makes the outline non-convex (or is collinear with its neighbours)");
  EXPECT_EQ(problem({{0, 0}, {1, 0}, {2, 0}, {1, 1}}),
            "vertices[1] makes the outline non-convex (or is collinear with its neighbours)");
  EXPECT_EQ(problem({{0, 0}, {1, 0}, {1, 0}, {0, 1}}), "vertices[1] repeats the next vertex");
  EXPECT_EQ(problem({{0, 0}, {1, 0}, {NAN, 1}}), "vertices[2] must be finite");
  EXPECT_EQ(problem({{0, 0}, {1, 1}, {2, 2}}), "vertices must enclose a non-zero area");
  EXPECT_EQ(problem({{0, 0}, {0, 1}, {1, 1}, {1, 0}}), "vertices must be counter-clockwise");
  EXPECT_EQ(convex_polygon_problem({{0, 0}, {0, 1}, {1, 1}, {1, 0}}, Orientation::either), "");
  // A pentagram's vertices all turn left, but it winds twice.
  Vertices star;
  for (int k = 0; k < 5; ++k) star.emplace_back(std::cos(4 * M_PI * k / 5), std::sin(4 * M_PI * k / 5));
  EXPECT_EQ(problem(star), "vertices wind around more than once: the outline crosses itself");
  Vertices many;
  for (int k = 0; k < 65; ++k) many.emplace_back(std::cos(2 * M_PI * k / 65), std::sin(2 * M_PI * k / 65));
  EXPECT_EQ(problem(many), "vertices holds 65 vertices, at most 64 allowed");
  many.pop_back();
  EXPECT_EQ(problem(many), "");
}

TEST(PolygonFootprint, RadiiAndPrismMesh) {
  const ConvexPolygonFootprint pentagon{{{-0.2, -0.3}, {0.4, -0.3}, {0.6, 0.0}, {0.4, 0.3}, {-0.2, 0.3}}, 0.7};
  EXPECT_NEAR(bounding_radius(pentagon), 0.6, 1e-15);
  EXPECT_NEAR(origin_inscribed_radius(pentagon.vertices_B), 0.2, 1e-15);
  EXPECT_EQ(origin_inscribed_radius({{0.1, 0.1}, {1.0, 0.1}, {0.1, 1.0}}), 0.0) << "origin outside";
  const PrismMesh mesh = prism_mesh(pentagon);
  ASSERT_EQ(mesh.vertices_B.size(), 10U);
  EXPECT_EQ(mesh.face_count, 7);
  // Every face's normal (right-hand rule over its listed vertices) points away from the prism's interior.
  const Eigen::Vector3d inside(0.2, 0.0, 0.35);
  std::size_t at = 0;
  for (int face = 0; face < mesh.face_count; ++face) {
    const int count = mesh.faces[at];
    ASSERT_GE(count, 3);
    const Eigen::Vector3d& a = mesh.vertices_B[static_cast<std::size_t>(mesh.faces[at + 1])];
    const Eigen::Vector3d& b = mesh.vertices_B[static_cast<std::size_t>(mesh.faces[at + 2])];
    const Eigen::Vector3d& c = mesh.vertices_B[static_cast<std::size_t>(mesh.faces[at + 3])];
    EXPECT_GT((b - a).cross(c - a).dot(a - inside), 0.0) << "face " << face;
    at += static_cast<std::size_t>(count) + 1;
  }
  EXPECT_EQ(at, mesh.faces.size());
}

}  // namespace
}  // namespace occgeo::geometry
