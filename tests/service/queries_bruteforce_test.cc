// Every query kind of the query kernels (the code the single and batch handlers share) against brute force on random
// worlds: collision, clearance with its gradient, raycast, occupancy and swept motion, at least 1000 cases each, and
// the grid's change tracking (a copy patched with the changes since its version equals a fresh window).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <random>
#include <vector>

#include "handlers/query_kernels.h"
#include "model_geometry.h"
#include "occgeo/geometry/footprint.h"
#include "occgeo/mapping/distance_field.h"
#include "occgeo/mapping/himm_grid.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/mapping/ptem.h"
#include "octree_band_field.h"

namespace occgeo::service {
namespace {

using geometry::CellIndex;
constexpr double kCell = 0.1;

// A world of width x height cells from cell (0, 0), with its models as a server publishes them.
struct RandomWorld {
  int width = 0;
  int height = 0;
  std::vector<bool> occupied;
  WorldSnapshot snapshot;

  [[nodiscard]] bool at(int x, int y) const {
    return x >= 0 && y >= 0 && x < width && y < height && occupied[static_cast<std::size_t>(y) * width + x];
  }
  [[nodiscard]] std::vector<CellIndex> occupied_cells() const {
    std::vector<CellIndex> cells;
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        if (at(x, y)) cells.push_back({x, y});
      }
    }
    return cells;
  }
};

RandomWorld make_world(std::mt19937& rng, int width, int height, int boxes, int singles) {
  RandomWorld world;
  world.width = width;
  world.height = height;
  world.occupied.assign(static_cast<std::size_t>(width) * height, false);
  std::uniform_int_distribution<int> x_of(0, width - 1);
  std::uniform_int_distribution<int> y_of(0, height - 1);
  std::uniform_int_distribution<int> side(1, 8);
  for (int b = 0; b < boxes; ++b) {
    const int x0 = x_of(rng), y0 = y_of(rng), w = side(rng), h = side(rng);
    for (int y = y0; y < std::min(y0 + h, height); ++y) {
      for (int x = x0; x < std::min(x0 + w, width); ++x) world.occupied[static_cast<std::size_t>(y) * width + x] = true;
    }
  }
  for (int s = 0; s < singles; ++s) world.occupied[static_cast<std::size_t>(y_of(rng)) * width + x_of(rng)] = true;

  mapfile::OccupancyImage image;
  image.width = static_cast<std::uint32_t>(width);
  image.height = static_cast<std::uint32_t>(height);
  image.resolution = kCell;
  image.pixels.resize(world.occupied.size());
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      image.pixels[static_cast<std::size_t>(height - 1 - y) * width + x] = world.at(x, y) ? 0 : 254;
    }
  }
  const auto grid = mapping::HimmGrid::from_image(image, mapping::HimmParams{}).snapshot();
  mapping::DistanceField field(mapping::DistanceFieldParams{});
  field.update(grid);
  static const mapping::OctoMapParams octomap_params;
  mapping::OctoMapModel octomap(octomap_params);
  mapping::PtemModel ptem(mapping::PtemParams{});
  // A few PTEM clusters from points scattered over the world.
  std::vector<Eigen::Vector2d> points;
  std::uniform_real_distribution<double> px(0.0, width * kCell), py(0.0, height * kCell);
  for (int i = 0; i < 6; ++i) points.emplace_back(px(rng), py(rng));
  mapping::PtemScan scan;
  scan.stamp_s = 1.0;
  scan.p_WS = {width * kCell / 2, height * kCell / 2};
  scan.field_of_view_rad = 2 * M_PI;
  scan.max_range_m = 100.0;
  scan.points_W = points;
  ptem.insert_scan(scan);
  world.snapshot = {grid, ptem.snapshot(), nullptr, field.snapshot(), octomap.publish(), nullptr, nullptr};
  return world;
}

// ---- Independent exact geometry (separating axes, closed sets; touching counts) ----

struct Outline {
  bool is_box = true;
  bool is_polygon = false;
  Eigen::Vector2d center;
  Eigen::Vector2d axis_x, axis_y;  // unit axes (box)
  double half_x = 0.0, half_y = 0.0, radius = 0.0;
  std::vector<Eigen::Vector2d> corners;  // polygon, world, counter-clockwise
};

double segment_point_distance(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& p) {
  const Eigen::Vector2d ab = b - a;
  const double s = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (a + s * ab - p).norm();
}

Outline outline_of(const geometry::Footprint& footprint, const geometry::Pose2& X_WB) {
  Outline o;
  o.axis_x = {std::cos(X_WB.theta), std::sin(X_WB.theta)};
  o.axis_y = {-o.axis_x.y(), o.axis_x.x()};
  if (const auto* box = std::get_if<geometry::BoxFootprint>(&footprint)) {
    o.center = X_WB.position() + box->center_x * o.axis_x;
    o.half_x = box->length / 2;
    o.half_y = box->width / 2;
  } else if (const auto* polygon = std::get_if<geometry::ConvexPolygonFootprint>(&footprint)) {
    o.is_box = false;
    o.is_polygon = true;
    o.center = Eigen::Vector2d::Zero();
    for (const Eigen::Vector2d& v : polygon->vertices_B) {
      o.corners.push_back(X_WB.position() + v.x() * o.axis_x + v.y() * o.axis_y);
      o.center += o.corners.back() / static_cast<double>(polygon->vertices_B.size());
    }
  } else {
    o.is_box = false;
    o.center = X_WB.position();
    o.radius = std::get<geometry::CylinderFootprint>(footprint).radius;
  }
  return o;
}

// Distance from point p to the outline (0 inside).
double point_distance(const Outline& o, const Eigen::Vector2d& p) {
  const Eigen::Vector2d d = p - o.center;
  if (o.is_polygon) {
    const std::size_t n = o.corners.size();
    bool inside = true;
    double best = 1e300;
    for (std::size_t k = 0; k < n; ++k) {
      const Eigen::Vector2d& a = o.corners[k];
      const Eigen::Vector2d& b = o.corners[(k + 1) % n];
      const Eigen::Vector2d ab = b - a, ap = p - a;
      if (ab.x() * ap.y() - ab.y() * ap.x() < 0.0) inside = false;
      best = std::min(best, segment_point_distance(a, b, p));
    }
    return inside ? 0.0 : best;
  }
  if (!o.is_box) return std::max(0.0, d.norm() - o.radius);
  const double ox = std::max(std::abs(d.dot(o.axis_x)) - o.half_x, 0.0);
  const double oy = std::max(std::abs(d.dot(o.axis_y)) - o.half_y, 0.0);
  return std::hypot(ox, oy);
}

// Distance between the outline and a cell's closed square (0 when they overlap): the minimum over the segment pairs
// and containment, evaluated by dense enough vertex/edge tests for convex polygons, or disc-square.
double cell_distance(const Outline& o, const CellIndex& c) {
  const Eigen::Vector2d lo(c.ix * kCell, c.iy * kCell);
  const Eigen::Vector2d hi = lo + Eigen::Vector2d::Constant(kCell);
  if (!o.is_box && !o.is_polygon) {
    const Eigen::Vector2d q = o.center.cwiseMax(lo).cwiseMin(hi);
    return std::max(0.0, (o.center - q).norm() - o.radius);
  }
  // Separating axis test for overlap: the axes of both outlines' edges.
  std::vector<Eigen::Vector2d> box_corners = o.corners;
  std::vector<Eigen::Vector2d> axes = {Eigen::Vector2d(1, 0), Eigen::Vector2d(0, 1)};
  if (o.is_polygon) {
    for (std::size_t k = 0; k < o.corners.size(); ++k) {
      const Eigen::Vector2d edge = o.corners[(k + 1) % o.corners.size()] - o.corners[k];
      axes.emplace_back(-edge.y(), edge.x());
    }
  } else {
    for (const double sx : {-1.0, 1.0}) {
      for (const double sy : {-1.0, 1.0}) {
        box_corners.push_back(o.center + sx * o.half_x * o.axis_x + sy * o.half_y * o.axis_y);
      }
    }
    axes.push_back(o.axis_x);
    axes.push_back(o.axis_y);
  }
  const std::array<Eigen::Vector2d, 4> cell_corners = {lo, Eigen::Vector2d(hi.x(), lo.y()), hi,
                                                       Eigen::Vector2d(lo.x(), hi.y())};
  bool separated = false;
  for (const Eigen::Vector2d& axis : axes) {
    double a0 = 1e300, a1 = -1e300, b0 = 1e300, b1 = -1e300;
    for (const auto& p : box_corners) a0 = std::min(a0, p.dot(axis)), a1 = std::max(a1, p.dot(axis));
    for (const auto& p : cell_corners) b0 = std::min(b0, p.dot(axis)), b1 = std::max(b1, p.dot(axis));
    if (a1 < b0 || b1 < a0) separated = true;
  }
  if (!separated) return 0.0;
  // Disjoint convex polygons: the closest pair includes a vertex of one of them.
  double best = 1e300;
  for (const auto& p : box_corners) best = std::min(best, (p - p.cwiseMax(lo).cwiseMin(hi)).norm());
  for (const auto& p : cell_corners) best = std::min(best, point_distance(o, p));
  return best;
}

double brute_clearance(const std::vector<CellIndex>& cells, const Outline& o) {
  double best = 1e300;
  for (const CellIndex& c : cells) best = std::min(best, cell_distance(o, c));
  return best;
}

geometry::Footprint random_footprint(std::mt19937& rng) {
  std::uniform_real_distribution<double> size(0.15, 0.9);
  if (std::bernoulli_distribution(0.5)(rng)) {
    return geometry::BoxFootprint{size(rng), size(rng), 0.5, std::uniform_real_distribution<double>(-0.3, 0.3)(rng)};
  }
  return geometry::CylinderFootprint{size(rng) / 2, 0.5};
}

// A convex polygon of 3 to 12 vertices on an ellipse (points on an ellipse in angle order are strictly convex), up
// to 0.4 m across each semi-axis and offset up to 0.25 m from base_link, so base_link may lie outside it.
geometry::Footprint random_polygon_footprint(std::mt19937& rng) {
  std::uniform_real_distribution<double> semi_axis(0.08, 0.4), offset(-0.25, 0.25), angle(0.0, 2 * M_PI);
  const int n = std::uniform_int_distribution<int>(3, 12)(rng);
  const double a = semi_axis(rng), b = semi_axis(rng), cx = offset(rng), cy = offset(rng), tilt = angle(rng);
  std::vector<double> angles;
  while (static_cast<int>(angles.size()) < n) {
    const double t = angle(rng);
    // Vertices at least 0.05 rad apart, so no edge is degenerate.
    if (std::all_of(angles.begin(), angles.end(), [&](double u) {
          const double gap = std::abs(t - u);
          return std::min(gap, 2 * M_PI - gap) > 0.05;
        })) {
      angles.push_back(t);
    }
  }
  std::sort(angles.begin(), angles.end());
  geometry::ConvexPolygonFootprint polygon{.vertices_B = {}, .height = 0.5};
  for (const double t : angles) {
    const Eigen::Vector2d p(a * std::cos(t), b * std::sin(t));
    polygon.vertices_B.emplace_back(cx + std::cos(tilt) * p.x() - std::sin(tilt) * p.y(),
                                    cy + std::sin(tilt) * p.x() + std::cos(tilt) * p.y());
  }
  return polygon;
}

using FootprintMaker = geometry::Footprint (*)(std::mt19937&);

geometry::Pose2 random_pose(std::mt19937& rng, const RandomWorld& world) {
  std::uniform_real_distribution<double> x(-0.5, world.width * kCell + 0.5), y(-0.5, world.height * kCell + 0.5),
      theta(-M_PI, M_PI);
  return {x(rng), y(rng), theta(rng)};
}

const std::vector<v1::Model> kGrid = {v1::MODEL_GRID};

void check_collision_cases(unsigned seed, FootprintMaker make_footprint) {
  std::mt19937 rng(seed);
  int cases = 0, hits = 0, shortcut = 0;
  for (int w = 0; w < 6; ++w) {
    const RandomWorld world = make_world(rng, 60, 50, 10, 40);
    const auto cells = world.occupied_cells();
    for (int i = 0; i < 400; ++i, ++cases) {
      const geometry::Footprint footprint = make_footprint(rng);
      const geometry::Pose2 pose = random_pose(rng, world);
      v1::CollisionReply reply;
      answer_collision(world.snapshot, footprint, geometry::bounding_radius(footprint), pose, kGrid, reply);
      const Outline o = outline_of(footprint, pose);
      const bool expected = brute_clearance(cells, o) == 0.0;
      ASSERT_EQ(reply.hit(), expected) << "case " << cases << " pose " << pose.x << "," << pose.y << "," << pose.theta;
      if (reply.hit()) {
        ++hits;
        EXPECT_EQ(reply.model(), v1::MODEL_GRID);
        const CellIndex c{reply.cell().ix(), reply.cell().iy()};
        EXPECT_TRUE(world.at(c.ix, c.iy)) << "the contact cell is occupied";
        EXPECT_EQ(cell_distance(o, c), 0.0) << "and touches the footprint";
      } else if (reply.cells_tested() == 0) {
        ++shortcut;
      }
    }
  }
  std::printf("%d cases, %d hits, %d answered by the distance field alone\n", cases, hits, shortcut);
  EXPECT_GE(cases, 1000);
  EXPECT_GT(hits, cases / 10);
  EXPECT_GT(shortcut, 0) << "the distance-field shortcut was never taken";
}

TEST(QueriesBruteForce, CollisionAgreesWithExactGeometryAndNamesATouchingCell) {
  check_collision_cases(1, random_footprint);
}

TEST(QueriesBruteForce, PolygonCollisionAgreesWithExactGeometryAndNamesATouchingCell) {
  check_collision_cases(11, random_polygon_footprint);
}

void check_clearance_cases(unsigned seed, FootprintMaker make_footprint) {
  std::mt19937 rng(seed);
  int cases = 0, with_gradient = 0;
  const double max_distance = 2.0;
  for (int w = 0; w < 5; ++w) {
    const RandomWorld world = make_world(rng, 60, 50, 6, 20);
    const auto cells = world.occupied_cells();
    for (int i = 0; i < 250; ++i, ++cases) {
      const geometry::Footprint footprint = make_footprint(rng);
      const geometry::Pose2 pose = random_pose(rng, world);
      v1::ClearanceReply reply;
      answer_clearance(world.snapshot, footprint, pose, max_distance, kGrid, reply);
      const Outline o = outline_of(footprint, pose);
      const double exact = brute_clearance(cells, o);
      if (exact > max_distance + kCell) {
        EXPECT_FALSE(reply.found()) << "case " << cases;
        continue;
      }
      if (exact < max_distance - kCell) {
        ASSERT_TRUE(reply.found()) << "case " << cases;
      }
      if (!reply.found()) continue;
      EXPECT_GE(reply.clearance_m(), exact - 1e-9) << "case " << cases;
      EXPECT_LE(reply.clearance_m(), exact + kCell + 1e-9) << "case " << cases;
      const Eigen::Vector2d nearest(reply.nearest_point().x(), reply.nearest_point().y());
      const Eigen::Vector2d gradient(reply.gradient().x(), reply.gradient().y());
      // In contact the nearest point is the cell's point nearest the footprint's centre, and the gradient points
      // from it to that centre.
      if (reply.clearance_m() <= 1e-6) continue;
      EXPECT_NEAR(point_distance(o, nearest), reply.clearance_m(), 1e-9) << "case " << cases;
      ++with_gradient;
      ASSERT_NEAR(gradient.norm(), 1.0, 1e-9) << "case " << cases;
      // Moving the footprint along the gradient moves it away from the nearest obstacle point at unit rate.
      const double step = 0.01;
      const geometry::Pose2 moved{pose.x + step * gradient.x(), pose.y + step * gradient.y(), pose.theta};
      EXPECT_NEAR(point_distance(outline_of(footprint, moved), nearest), reply.clearance_m() + step, 1e-6)
          << "case " << cases;
    }
  }
  EXPECT_GE(cases, 1000);
  EXPECT_GT(with_gradient, cases / 2);
}

TEST(QueriesBruteForce, ClearanceIsWithinACellOfExactAndItsGradientPointsAway) {
  check_clearance_cases(2, random_footprint);
}

TEST(QueriesBruteForce, PolygonClearanceIsWithinACellOfExactAndItsGradientPointsAway) {
  check_clearance_cases(12, random_polygon_footprint);
}

// Range at which the ray enters the closed square of c, by the slab method; negative when it misses.
double brute_entry(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const CellIndex& c) {
  double t0 = 0.0, t1 = 1e300;
  for (int a = 0; a < 2; ++a) {
    const double lo = (a == 0 ? c.ix : c.iy) * kCell, hi = lo + kCell;
    if (d[a] == 0.0) {
      if (o[a] < lo || o[a] > hi) return -1.0;
      continue;
    }
    const double ta = (lo - o[a]) / d[a], tb = (hi - o[a]) / d[a];
    t0 = std::max(t0, std::min(ta, tb));
    t1 = std::min(t1, std::max(ta, tb));
  }
  return t0 <= t1 ? t0 : -1.0;
}

TEST(QueriesBruteForce, RaycastFindsTheNearestOccupiedCell) {
  std::mt19937 rng(3);
  int cases = 0, hits = 0;
  for (int w = 0; w < 5; ++w) {
    const RandomWorld world = make_world(rng, 60, 50, 8, 30);
    const auto cells = world.occupied_cells();
    for (int i = 0; i < 300; ++i, ++cases) {
      const geometry::Pose2 ray = random_pose(rng, world);
      const double max_range = std::uniform_real_distribution<double>(0.5, 8.0)(rng);
      v1::RaycastResult result;
      answer_raycast(world.snapshot, ray, max_range, 0.3, kGrid, result);
      const Eigen::Vector2d o = ray.position(), d(std::cos(ray.theta), std::sin(ray.theta));
      double expected = max_range;
      bool expected_hit = false;
      for (const CellIndex& c : cells) {
        const double t = brute_entry(o, d, c);
        if (t >= 0.0 && t <= max_range && t < expected + 1e-12) {
          expected = std::min(expected, t);
          expected_hit = true;
        }
      }
      ASSERT_EQ(result.hit(), expected_hit) << "case " << cases;
      ASSERT_EQ(result.per_model_size(), 1);
      EXPECT_NEAR(result.range_m(), expected, 1e-9) << "case " << cases;
      if (result.hit()) {
        ++hits;
        EXPECT_EQ(result.model(), v1::MODEL_GRID);
        EXPECT_TRUE(world.at(result.per_model(0).cell().ix(), result.per_model(0).cell().iy()));
      }
    }
  }
  EXPECT_GE(cases, 1000);
  EXPECT_GT(hits, cases / 5);
}

TEST(QueriesBruteForce, OccupancyReadsTheGridCellAndTheThreatSum) {
  std::mt19937 rng(4);
  int cases = 0;
  const std::vector<v1::Model> all = {v1::MODEL_GRID, v1::MODEL_OCTOMAP, v1::MODEL_PTEM};
  for (int w = 0; w < 3; ++w) {
    const RandomWorld world = make_world(rng, 40, 40, 6, 30);
    const auto& ptem = *world.snapshot.ptem;
    ASSERT_FALSE(ptem.clusters().empty());
    for (int i = 0; i < 400; ++i, ++cases) {
      const geometry::Pose2 at = random_pose(rng, world);
      v1::OccupancySample sample;
      answer_occupancy(world.snapshot, {at.x, at.y, 0.3}, all, sample);
      const int ix = static_cast<int>(std::floor(at.x / kCell)), iy = static_cast<int>(std::floor(at.y / kCell));
      EXPECT_EQ(sample.cell().ix(), ix);
      EXPECT_EQ(sample.cell().iy(), iy);
      const bool inside = ix >= 0 && iy >= 0 && ix < world.width && iy < world.height;
      EXPECT_EQ(sample.observed(), inside);
      EXPECT_EQ(sample.occupied(), world.at(ix, iy));
      EXPECT_EQ(sample.certainty(), world.at(ix, iy) ? 15U : 0U);
      EXPECT_FALSE(sample.octree_known()) << "nothing was inserted into the octree";
      double threat = 0.0;
      for (const mapping::PtemCluster& cluster : ptem.clusters()) {
        const double s2 = cluster.sigma_m * cluster.sigma_m;
        threat +=
            std::exp(-(Eigen::Vector2d(at.x, at.y) - cluster.centre_W).squaredNorm() / (2 * s2)) / (2 * M_PI * s2);
      }
      EXPECT_NEAR(sample.threat(), threat, 1e-9 * std::max(1.0, threat));
      EXPECT_EQ(sample.restricted(), ptem.restricted({at.x, at.y}));
    }
  }
  EXPECT_GE(cases, 1000);
}

void check_swept_cases(unsigned seed, FootprintMaker make_footprint) {
  std::mt19937 rng(seed);
  int cases = 0, hits = 0;
  for (int w = 0; w < 5; ++w) {
    const RandomWorld world = make_world(rng, 50, 40, 5, 15);
    const auto cells = world.occupied_cells();
    for (int i = 0; i < 200; ++i, ++cases) {
      const geometry::Footprint footprint = make_footprint(rng);
      v1::SweptMotion motion;
      const geometry::Pose2 start = random_pose(rng, world);
      const bool as_path = i % 3 == 0;
      if (as_path) {
        geometry::Pose2 p = start;
        for (int k = 0; k < 4; ++k) {
          auto* pose = motion.add_path();
          pose->set_x(p.x);
          pose->set_y(p.y);
          pose->set_theta(p.theta);
          p = {p.x + std::uniform_real_distribution<double>(-0.6, 0.6)(rng),
               p.y + std::uniform_real_distribution<double>(-0.6, 0.6)(rng),
               geometry::wrap_angle(p.theta + std::uniform_real_distribution<double>(-1.0, 1.0)(rng))};
        }
        motion.set_path_dt_s(0.5);
      } else {
        motion.mutable_start()->set_x(start.x);
        motion.mutable_start()->set_y(start.y);
        motion.mutable_start()->set_theta(start.theta);
        motion.set_linear_mps(std::uniform_real_distribution<double>(-0.8, 0.8)(rng));
        motion.set_angular_radps(std::uniform_real_distribution<double>(-1.5, 1.5)(rng));
        motion.set_duration_s(std::uniform_real_distribution<double>(0.0, 3.0)(rng));
      }
      v1::SweptResult result;
      answer_swept(world.snapshot, footprint, kGrid, motion, result);
      // Brute force: the first contact on a dense sampling of the motion (every 10 mm of the fastest point's travel);
      // any contact found this way is a real one, which the server must not have stepped over.
      const double radius = geometry::bounding_radius(footprint);
      std::vector<std::pair<double, geometry::Pose2>> samples;  // (seconds, pose)
      if (as_path) {
        for (int k = 0; k + 1 < motion.path_size(); ++k) {
          const auto& a = motion.path(k);
          const auto& b = motion.path(k + 1);
          const double dtheta = geometry::wrap_angle(b.theta() - a.theta());
          const double travel = std::hypot(b.x() - a.x(), b.y() - a.y()) + std::abs(dtheta) * radius;
          const int n = std::max(1, static_cast<int>(std::ceil(travel / 0.01)));
          for (int j = 0; j <= n; ++j) {
            const double s = static_cast<double>(j) / n;
            samples.push_back(
                {(k + s) * 0.5, {a.x() + s * (b.x() - a.x()), a.y() + s * (b.y() - a.y()), a.theta() + s * dtheta}});
          }
        }
      } else {
        const double rate = std::abs(motion.linear_mps()) + std::abs(motion.angular_radps()) * radius;
        const int n = std::max(1, static_cast<int>(std::ceil(rate * motion.duration_s() / 0.01)));
        for (int j = 0; j <= n; ++j) {
          const double t = motion.duration_s() * j / n;
          samples.push_back({t, geometry::integrate(start, {motion.linear_mps(), motion.angular_radps()}, t)});
        }
      }
      // Only cells near the motion can touch it.
      Eigen::AlignedBox2d reach;
      for (const auto& sample : samples) reach.extend(sample.second.position());
      reach.min().array() -= radius + 2 * kCell;
      reach.max().array() += radius + 2 * kCell;
      std::vector<CellIndex> near;
      for (const CellIndex& c : cells) {
        if (reach.contains(Eigen::Vector2d((c.ix + 0.5) * kCell, (c.iy + 0.5) * kCell))) near.push_back(c);
      }
      std::optional<double> first_contact;
      for (const auto& [t, pose] : samples) {
        if (brute_clearance(near, outline_of(footprint, pose)) == 0.0) {
          first_contact = t;
          break;
        }
      }
      if (first_contact) {
        ASSERT_TRUE(result.hit()) << "case " << cases << ": contact at " << *first_contact << " s was stepped over";
        EXPECT_LE(result.time_s(), *first_contact + 1e-9) << "case " << cases;
      }
      if (result.hit()) {
        ++hits;
        const geometry::Pose2 at{result.pose().x(), result.pose().y(), result.pose().theta()};
        EXPECT_LE(brute_clearance(cells, outline_of(footprint, at)), kSweptContact_m + 1e-9)
            << "case " << cases << ": reported contact at a pose clear of everything";
      }
    }
  }
  EXPECT_GE(cases, 1000);
  EXPECT_GT(hits, cases / 10);
}

TEST(QueriesBruteForce, SweptMotionNeverStepsOverAContact) { check_swept_cases(5, random_footprint); }

TEST(QueriesBruteForce, PolygonSweptMotionNeverStepsOverAContact) { check_swept_cases(15, random_polygon_footprint); }

TEST(QueriesBruteForce, ChangesSinceAVersionPatchAWindowIntoTheFreshOne) {
  std::mt19937 rng(6);
  mapping::HimmGrid grid(mapping::HimmParams{});
  std::uniform_real_distribution<double> where(-6.0, 6.0), angle(-M_PI, M_PI), range(0.3, 5.0);
  int cases = 0, unchanged_tiles_skipped = 0;
  for (int round = 0; round < 1000; ++round, ++cases) {
    const auto before = grid.snapshot();
    const mapping::CellBox box{{static_cast<int>(where(rng) / kCell), static_cast<int>(where(rng) / kCell)}, {}};
    mapping::CellBox window = box;
    window.max = {window.min.ix + std::uniform_int_distribution<int>(0, 150)(rng),
                  window.min.iy + std::uniform_int_distribution<int>(0, 150)(rng)};
    const int width = window.max.ix - window.min.ix + 1, height = window.max.iy - window.min.iy + 1;
    std::vector<std::uint8_t> copy = before->window(window.min, width, height);
    const int scans = std::uniform_int_distribution<int>(0, 3)(rng);
    for (int s = 0; s < scans; ++s) {
      std::vector<float> ranges(90);
      for (float& r : ranges) r = static_cast<float>(range(rng));
      grid.insert_scan({where(rng), where(rng), angle(rng)}, -1.5F, 0.035F, ranges, 5.0F);
    }
    const auto after = grid.snapshot();
    const auto parts = after->changed_since(before->version(), window);
    if (scans == 0) {
      EXPECT_TRUE(parts.empty());
    }
    for (const mapping::CellBox& part : parts) {
      ASSERT_GE(part.min.ix, window.min.ix);
      ASSERT_LE(part.max.ix, window.max.ix);
      const int pw = part.max.ix - part.min.ix + 1, ph = part.max.iy - part.min.iy + 1;
      const auto cells = after->window(part.min, pw, ph);
      for (int y = 0; y < ph; ++y) {
        std::copy_n(cells.begin() + static_cast<std::ptrdiff_t>(y) * pw, pw,
                    copy.begin() + static_cast<std::ptrdiff_t>(part.min.iy - window.min.iy + y) * width +
                        (part.min.ix - window.min.ix));
      }
    }
    unchanged_tiles_skipped += static_cast<int>(after->tile_count()) - static_cast<int>(parts.size());
    ASSERT_EQ(copy, after->window(window.min, width, height)) << "round " << round;
  }
  EXPECT_GE(cases, 1000);
  EXPECT_GT(unchanged_tiles_skipped, 0);
}

// The PTEM collision check skips sampling the footprint against the sum of every PDF for poses where a bound on that
// sum stays below f_r; the answers stay those of the full check: a hit names a restricted point, and a miss leaves no
// restricted point anywhere on the footprint (sampled densely here).
void check_ptem_cases(unsigned seed, FootprintMaker make_footprint) {
  std::mt19937 rng(seed);
  const RandomWorld world = make_world(rng, 60, 50, 0, 0);
  const mapping::PtemSnapshot& ptem = *world.snapshot.ptem;
  ASSERT_TRUE(ptem.restricted_threshold());
  int hits = 0;
  constexpr int kCases = 2000;
  for (int i = 0; i < kCases; ++i) {
    const geometry::Footprint footprint = make_footprint(rng);
    const geometry::Pose2 pose = random_pose(rng, world);
    const PtemContact contact = collide_ptem(ptem, footprint, pose);
    if (contact.hit) {
      ++hits;
      EXPECT_TRUE(ptem.restricted(contact.point_W)) << "case " << i;
      continue;
    }
    // Every footprint is within 0.8 m of its outline's centre; points beyond project onto its boundary.
    const Outline o = outline_of(footprint, pose);
    for (double u = -0.85; u <= 0.85; u += 0.025) {
      for (double v = -0.85; v <= 0.85; v += 0.025) {
        const Eigen::Vector2d p_W = nearest_footprint_point(footprint, pose, o.center + Eigen::Vector2d(u, v));
        ASSERT_FALSE(ptem.restricted(p_W)) << "case " << i << ": a restricted point of the footprint was missed";
      }
    }
  }
  std::printf("%d cases, %d PTEM hits\n", kCases, hits);
  EXPECT_GT(hits, kCases / 50);
}

TEST(QueriesBruteForce, PtemCollisionSkipsOnlyPosesThatCannotHit) { check_ptem_cases(5, random_footprint); }

TEST(QueriesBruteForce, PolygonPtemCollisionSkipsOnlyPosesThatCannotHit) {
  check_ptem_cases(16, random_polygon_footprint);
}

// The polygon's outline in world with every edge moved outwards by grow metres (negative shrinks).
std::vector<Eigen::Vector2d> offset_outline(const std::vector<Eigen::Vector2d>& corners, double grow) {
  const std::size_t n = corners.size();
  std::vector<Eigen::Vector2d> moved;
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector2d d1 = (corners[k] - corners[(k + n - 1) % n]).normalized();
    const Eigen::Vector2d d2 = (corners[(k + 1) % n] - corners[k]).normalized();
    const Eigen::Vector2d n1(d1.y(), -d1.x()), n2(d2.y(), -d2.x());
    const double det = n1.x() * n2.y() - n1.y() * n2.x();
    moved.push_back(corners[k] + Eigen::Vector2d(grow * (n2.y() - n1.y()), grow * (n1.x() - n2.x())) / det);
  }
  return moved;
}

// Against the OctoMap a polygon footprint is an fcl::Convex prism lifted to the ground band: its answer agrees with
// exact geometry over the occupied voxels whose z range meets [band, height] (voxel cubes against the extruded
// polygon), its contact lies on such a voxel and on the footprint, and a rectangle answers like the box.
TEST(QueriesBruteForce, PolygonOctomapCollisionAgreesWithExactGeometry) {
  std::mt19937 rng(21);
  mapping::OctoMapParams params;
  params.voxel_filter_enabled = false;
  params.outlier_filter_enabled = false;
  mapping::OctoMapModel model(params);
  std::uniform_real_distribution<float> across(-3.0F, 3.0F), up(-0.5F, 0.6F);
  std::vector<Eigen::Vector3f> points_S;
  for (int i = 0; i < 300; ++i) points_S.emplace_back(across(rng), across(rng), up(rng));
  model.insert_cloud(geometry::Pose3::from_xyz_rpy(3.0, 3.0, 0.5, 0.0, 0.0, 0.0), points_S);
  const auto octomap = model.publish();
  const double band = octomap_ground_band_m(*octomap);
  const std::vector<mapping::OctoVoxel> voxels =
      octomap->occupied_in_box(Eigen::Vector3d(-1.0, -1.0, -1.0), Eigen::Vector3d(7.0, 7.0, 3.0));
  ASSERT_GT(voxels.size(), 100U);

  int cases = 0, compared = 0, hits = 0, box_cases = 0;
  std::uniform_real_distribution<double> where(0.0, 6.0), heading(-M_PI, M_PI), height(0.1, 1.2);
  for (int i = 0; i < 1200; ++i, ++cases) {
    auto polygon = std::get<geometry::ConvexPolygonFootprint>(random_polygon_footprint(rng));
    polygon.height = height(rng);
    const geometry::Pose2 pose{where(rng), where(rng), heading(rng)};
    const mapping::OctoCollision result = collide_octomap(*octomap, polygon, pose);
    const Outline o = outline_of(polygon, pose);
    const std::vector<Eigen::Vector2d> shrunk = offset_outline(o.corners, -1e-6);
    const std::vector<Eigen::Vector2d> grown = offset_outline(o.corners, 1e-6);
    bool surely = false, maybe = false;
    for (const mapping::OctoVoxel& voxel : voxels) {
      const double half = voxel.size_m / 2;
      const double bottom = voxel.center_W.z() - half, top = voxel.center_W.z() + half;
      if (top < band - 1e-6 || bottom > polygon.height + 1e-6) continue;
      const bool z_sure = top > band + 1e-6 && bottom < polygon.height - 1e-6;
      const Eigen::Vector2d centre = voxel.center_W.head<2>();
      const auto touches = [&](const std::vector<Eigen::Vector2d>& corners) {
        Outline shape = o;
        shape.corners = corners;
        // The voxel's square as a cell of its own size: cell_distance's cells are kCell squares, so test with the
        // polygon translated into that frame and scaled.
        const double scale = kCell / voxel.size_m;
        for (Eigen::Vector2d& c : shape.corners) c = (c - (centre - Eigen::Vector2d::Constant(half))) * scale;
        return cell_distance(shape, CellIndex{0, 0}) == 0.0;
      };
      if (touches(grown)) maybe = true;
      if (z_sure && touches(shrunk)) surely = true;
    }
    if (surely == maybe) {
      ++compared;
      ASSERT_EQ(result.hit, surely) << "case " << i << " pose " << pose.x << "," << pose.y << "," << pose.theta;
    }
    if (result.hit) {
      ++hits;
      // The contact point lies on the footprint (2D, within FCL's tolerance) and on an occupied voxel of the band.
      EXPECT_LE(point_distance(o, result.contact_W.head<2>()), 1e-4) << "case " << i;
      const bool on_voxel = std::any_of(voxels.begin(), voxels.end(), [&](const mapping::OctoVoxel& voxel) {
        return ((result.contact_W - voxel.center_W).cwiseAbs().array() <= voxel.size_m / 2 + 1e-4).all();
      });
      EXPECT_TRUE(on_voxel) << "case " << i;
    }
    // The same outline as a box answers like the box.
    if (i % 4 == 0) {
      ++box_cases;
      std::uniform_real_distribution<double> side(0.1, 0.8), shift(-0.3, 0.3);
      const geometry::BoxFootprint box{side(rng), side(rng), polygon.height, shift(rng)};
      const double hx = box.length / 2, hy = box.width / 2;
      const geometry::ConvexPolygonFootprint rectangle{
          {{box.center_x - hx, -hy}, {box.center_x + hx, -hy}, {box.center_x + hx, hy}, {box.center_x - hx, hy}},
          box.height};
      EXPECT_EQ(collide_octomap(*octomap, rectangle, pose).hit, collide_octomap(*octomap, box, pose).hit)
          << "case " << i;
    }
  }
  std::printf("%d cases, %d compared, %d hits, %d box twins\n", cases, compared, hits, box_cases);
  EXPECT_GE(compared, 1000);
  EXPECT_GT(hits, cases / 10);
  EXPECT_LT(hits, cases * 9 / 10);
}

// ---- Octree clearance: the voxels' columns within the footprint's height band, against the voxels set ----

// A voxel of the octree world by its integer index (the octree's resolution is kCell).
struct VoxelIndex {
  int x, y, z;
};

Eigen::Vector3d voxel_center(const VoxelIndex& v) {
  return {(v.x + 0.5) * kCell, (v.y + 0.5) * kCell, (v.z + 0.5) * kCell};
}

// A return 1 mm long inside the voxel: marks it occupied and crosses no other voxel.
void mark_voxel(mapping::OctoMapModel& model, const VoxelIndex& v) {
  geometry::Pose3 X_WS;
  X_WS.transform.translation() = voxel_center(v) - Eigen::Vector3d(0.0005, 0.0, 0.0);
  model.insert_ray(X_WS, 0.001, 5.0);
}

// Beams without a return starting in the voxel and ending in the next one: each lowers the voxel's occupancy (the end
// voxel is not updated), four take a once-hit voxel below the threshold.
void clear_voxel(mapping::OctoMapModel& model, const VoxelIndex& v) {
  geometry::Pose3 X_WS;
  X_WS.transform.translation() = voxel_center(v);
  for (int i = 0; i < 4; ++i) model.insert_ray(X_WS, kCell, kCell);
}

// The columns a footprint of height_m meets: a voxel counts when its closed z range overlaps [band, height_m].
std::vector<CellIndex> occupied_columns(const mapping::OctoMapSnapshot& octomap, const std::vector<VoxelIndex>& voxels,
                                        double height_m) {
  const double band = octomap_ground_band_m(octomap);
  std::vector<CellIndex> cells;
  for (const VoxelIndex& v : voxels) {
    if (!octomap.occupied(voxel_center(v))) continue;
    if ((v.z + 1) * kCell < band || v.z * kCell > height_m) continue;
    cells.push_back({v.x, v.y});
  }
  return cells;
}

geometry::Footprint random_tall_footprint(std::mt19937& rng) {
  static constexpr std::array<double, 4> kHeights = {0.35, 0.65, 1.05, 1.45};
  const double height = kHeights[std::uniform_int_distribution<std::size_t>(0, kHeights.size() - 1)(rng)];
  geometry::Footprint footprint = random_footprint(rng);
  std::visit([&](auto& shape) { shape.height = height; }, footprint);
  return footprint;
}

TEST(QueriesBruteForce, OctomapClearanceIsWithinAVoxelOfTheBandsColumnsAcrossUpdates) {
  std::mt19937 rng(21);
  const std::vector<v1::Model> octomap_only = {v1::MODEL_OCTOMAP};
  constexpr int kWidth = 50, kHeight = 40;
  constexpr double kMaxDistance = 1.5;
  mapping::OctoMapParams params;
  params.resolution_m = kCell;
  mapping::OctoMapModel model(params);
  std::vector<VoxelIndex> voxels;
  std::uniform_int_distribution<int> x_of(0, kWidth - 1), y_of(0, kHeight - 1), z_of(0, 15), side(1, 5);
  const auto add_boxes = [&](int boxes) {
    for (int b = 0; b < boxes; ++b) {
      const int x0 = x_of(rng), y0 = y_of(rng), w = side(rng), h = side(rng), z0 = z_of(rng), z1 = z0 + side(rng);
      for (int x = x0; x < std::min(x0 + w, kWidth); ++x) {
        for (int y = y0; y < std::min(y0 + h, kHeight); ++y) {
          for (int z = z0; z < z1; ++z) {
            voxels.push_back({x, y, z});
            mark_voxel(model, voxels.back());
          }
        }
      }
    }
  };
  struct Case {
    geometry::Footprint footprint;
    geometry::Pose2 pose;
    bool found;
    double clearance_m;
  };
  int cases = 0, found = 0;
  // Answers the poses on snapshot against its occupied columns; returns what it answered.
  const auto check = [&](const std::shared_ptr<const mapping::OctoMapSnapshot>& octomap, int poses) {
    WorldSnapshot world{
        nullptr, mapping::PtemModel(mapping::PtemParams{}).snapshot(), nullptr, nullptr, octomap, nullptr, nullptr};
    std::vector<Case> answered;
    for (int i = 0; i < poses; ++i, ++cases) {
      Case c{random_tall_footprint(rng), {}, false, 0.0};
      c.pose = {std::uniform_real_distribution<double>(-0.5, kWidth * kCell + 0.5)(rng),
                std::uniform_real_distribution<double>(-0.5, kHeight * kCell + 0.5)(rng),
                std::uniform_real_distribution<double>(-M_PI, M_PI)(rng)};
      v1::ClearanceReply reply;
      answer_clearance(world, c.footprint, c.pose, kMaxDistance, octomap_only, reply);
      const double height = std::visit([](const auto& shape) { return shape.height; }, c.footprint);
      const double exact = brute_clearance(occupied_columns(*octomap, voxels, height), outline_of(c.footprint, c.pose));
      c.found = reply.found();
      c.clearance_m = reply.clearance_m();
      answered.push_back(c);
      if (exact > kMaxDistance + kCell) {
        EXPECT_FALSE(reply.found()) << "case " << cases;
        continue;
      }
      if (exact < kMaxDistance - kCell) {
        EXPECT_TRUE(reply.found()) << "case " << cases << " exact " << exact;
      }
      if (!reply.found()) continue;
      ++found;
      EXPECT_EQ(reply.model(), v1::MODEL_OCTOMAP);
      EXPECT_GE(reply.clearance_m(), exact - 1e-9) << "case " << cases;
      EXPECT_LE(reply.clearance_m(), exact + kCell + 1e-9) << "case " << cases;
    }
    return answered;
  };
  const auto answer_again = [&](const std::shared_ptr<const mapping::OctoMapSnapshot>& octomap,
                                const std::vector<Case>& before) {
    WorldSnapshot world{
        nullptr, mapping::PtemModel(mapping::PtemParams{}).snapshot(), nullptr, nullptr, octomap, nullptr, nullptr};
    for (const Case& c : before) {
      v1::ClearanceReply reply;
      answer_clearance(world, c.footprint, c.pose, kMaxDistance, octomap_only, reply);
      ASSERT_EQ(reply.found(), c.found);
      if (c.found) {
        EXPECT_EQ(reply.clearance_m(), c.clearance_m);
      }
    }
  };

  add_boxes(12);
  const auto first = model.publish();
  const std::vector<Case> first_answers = check(first, 500);
  // Add voxels, and clear some of the first ones.
  add_boxes(8);
  std::size_t cleared = 0;
  for (std::size_t i = 0; i < voxels.size(); i += 7, ++cleared) clear_voxel(model, voxels[i]);
  const auto second = model.publish();
  std::size_t still_occupied = 0;
  for (std::size_t i = 0; i < voxels.size(); i += 7)
    still_occupied += second->occupied(voxel_center(voxels[i])) ? 1 : 0;
  EXPECT_LT(still_occupied, cleared / 2) << "clearing beams removed few voxels";
  check(second, 500);
  // The first snapshot still answers as it did.
  answer_again(first, first_answers);
  EXPECT_GE(cases, 1000);
  EXPECT_GT(found, cases / 3);
}

// The octree's clearance from its maintained band fields (OctreeBandField, one per footprint height, updated snapshot
// by snapshot from the tiles each publish rebuilt) against the voxels' columns: within a voxel, over two clusters of
// boxes in different tiles (30 m apart) while only one of them changes per publish, voxels added and cleared, and an
// older snapshot with its fields answering as it did.
TEST(QueriesBruteForce, OctomapClearanceFromTheBandFieldsIsWithinAVoxelAcrossTilesAndUpdates) {
  std::mt19937 rng(33);
  const std::vector<v1::Model> octomap_only = {v1::MODEL_OCTOMAP};
  constexpr int kWidth = 50, kHeight = 40, kFarX = 300;  // the second cluster starts 30 m away: another tile
  constexpr double kMaxDistance = 1.5;
  static constexpr std::array<double, 2> kHeights = {0.65, 1.45};
  mapping::OctoMapParams params;
  params.resolution_m = kCell;
  mapping::OctoMapModel model(params);
  std::vector<VoxelIndex> voxels;
  std::uniform_int_distribution<int> x_of(0, kWidth - 1), y_of(0, kHeight - 1), z_of(0, 15), side(1, 5);
  const auto add_boxes = [&](int boxes, int x_offset) {
    for (int b = 0; b < boxes; ++b) {
      const int x0 = x_of(rng), y0 = y_of(rng), w = side(rng), h = side(rng), z0 = z_of(rng), z1 = z0 + side(rng);
      for (int x = x0; x < std::min(x0 + w, kWidth); ++x) {
        for (int y = y0; y < std::min(y0 + h, kHeight); ++y) {
          for (int z = z0; z < z1; ++z) {
            voxels.push_back({x + x_offset, y, z});
            mark_voxel(model, voxels.back());
          }
        }
      }
    }
  };
  mapping::DistanceFieldParams field_params;
  field_params.max_distance_m = 1.0;  // below the queries' reach: the exact fallback is exercised too
  std::vector<OctreeBandField> bands;
  for (const double height : kHeights) bands.emplace_back(height, field_params);
  const auto world_of = [&](const std::shared_ptr<const mapping::OctoMapSnapshot>& octomap) {
    auto snapshots = std::make_shared<std::vector<OctreeBandSnapshot>>();
    for (OctreeBandField& band : bands) {
      band.update(*octomap);
      snapshots->push_back(band.snapshot());
    }
    return WorldSnapshot{
        nullptr, mapping::PtemModel(mapping::PtemParams{}).snapshot(), nullptr, nullptr, octomap, std::move(snapshots),
        nullptr};
  };
  struct Case {
    geometry::Footprint footprint;
    geometry::Pose2 pose;
    bool found;
    double clearance_m;
  };
  int cases = 0, found = 0;
  const auto check = [&](const WorldSnapshot& world, int poses) {
    std::vector<Case> answered;
    for (int i = 0; i < poses; ++i, ++cases) {
      Case c{random_footprint(rng), {}, false, 0.0};
      const double height = kHeights[std::uniform_int_distribution<std::size_t>(0, kHeights.size() - 1)(rng)];
      std::visit([&](auto& shape) { shape.height = height; }, c.footprint);
      if (find_octree_band(world.octree_bands.get(), height) == nullptr) {
        ADD_FAILURE() << "no band for height " << height;
        continue;
      }
      const double x_offset = (i % 2 == 0) ? 0.0 : kFarX * kCell;
      c.pose = {x_offset + std::uniform_real_distribution<double>(-0.5, kWidth * kCell + 0.5)(rng),
                std::uniform_real_distribution<double>(-0.5, kHeight * kCell + 0.5)(rng),
                std::uniform_real_distribution<double>(-M_PI, M_PI)(rng)};
      v1::ClearanceReply reply;
      answer_clearance(world, c.footprint, c.pose, kMaxDistance, octomap_only, reply);
      const double exact =
          brute_clearance(occupied_columns(*world.octomap, voxels, height), outline_of(c.footprint, c.pose));
      c.found = reply.found();
      c.clearance_m = reply.clearance_m();
      answered.push_back(c);
      if (exact > kMaxDistance + kCell) {
        EXPECT_FALSE(reply.found()) << "case " << cases;
        continue;
      }
      if (exact < kMaxDistance - kCell) {
        EXPECT_TRUE(reply.found()) << "case " << cases << " exact " << exact;
      }
      if (!reply.found()) continue;
      ++found;
      EXPECT_GE(reply.clearance_m(), exact - 1e-9) << "case " << cases;
      EXPECT_LE(reply.clearance_m(), exact + kCell + 1e-9) << "case " << cases;
    }
    return answered;
  };

  add_boxes(12, 0);
  add_boxes(12, kFarX);
  const WorldSnapshot first = world_of(model.publish());
  const std::vector<Case> first_answers = check(first, 400);
  // Only the near cluster changes: boxes added, every 7th voxel cleared.
  add_boxes(8, 0);
  for (std::size_t i = 0; i < voxels.size(); i += 7) {
    if (voxels[i].x < kFarX) clear_voxel(model, voxels[i]);
  }
  const WorldSnapshot second = world_of(model.publish());
  ASSERT_TRUE(second.octomap->changed_columns().has_value());
  EXPECT_EQ(second.octomap->changed_columns()->size(), 1U) << "one tile's columns changed";
  check(second, 400);
  // Then only the far one.
  add_boxes(8, kFarX);
  for (std::size_t i = 3; i < voxels.size(); i += 5) {
    if (voxels[i].x >= kFarX) clear_voxel(model, voxels[i]);
  }
  check(world_of(model.publish()), 400);
  // The first snapshot and its fields still answer as they did.
  for (const Case& c : first_answers) {
    v1::ClearanceReply reply;
    answer_clearance(first, c.footprint, c.pose, kMaxDistance, octomap_only, reply);
    ASSERT_EQ(reply.found(), c.found);
    if (c.found) {
      EXPECT_EQ(reply.clearance_m(), c.clearance_m);
    }
  }
  EXPECT_GE(cases, 1200);
  EXPECT_GT(found, cases / 3);
}

// Clearance over every model (grid, octree band field, PTEM extents) against the exact distance to the nearest of their
// obstacles: never below it, at most a cell above, in either order of the grid and the octree, and never below the
// exact distance of the model said to hold the nearest obstacle. The worlds put the grid's and the octree's obstacles
// in different places, so that either can hold the nearest one. (A later model asked only for an obstacle more than
// its resolution nearer than the answer so far fails this: its own answer may lie up to a cell above its exact one.)
TEST(QueriesBruteForce, AllModelsClearanceIsWithinACellOfTheNearestObstacleOfAnyModel) {
  std::mt19937 rng(41);
  constexpr double kMaxDistance = 1.5;
  constexpr double kBandTop = 0.65;
  int cases = 0, found = 0, octree_nearest = 0, grid_nearest = 0;
  for (int w = 0; w < 3; ++w) {
    const RandomWorld world = make_world(rng, 50, 40, 5, 15);
    mapping::OctoMapParams params;
    params.resolution_m = kCell;
    mapping::OctoMapModel model(params);
    std::vector<VoxelIndex> voxels;
    std::uniform_int_distribution<int> x_of(0, 49), y_of(0, 39), side(1, 5);
    for (int b = 0; b < 8; ++b) {
      const int x0 = x_of(rng), y0 = y_of(rng), wx = side(rng), wy = side(rng);
      for (int x = x0; x < std::min(x0 + wx, 50); ++x) {
        for (int y = y0; y < std::min(y0 + wy, 40); ++y) {
          for (int z = 2; z < 6; ++z) {
            voxels.push_back({x, y, z});
            mark_voxel(model, voxels.back());
          }
        }
      }
    }
    const auto octomap = model.publish();
    OctreeBandField band(kBandTop, mapping::DistanceFieldParams{});
    band.update(*octomap);
    WorldSnapshot snapshot = world.snapshot;
    snapshot.octomap = octomap;
    snapshot.octree_bands = std::make_shared<const std::vector<OctreeBandSnapshot>>(1, band.snapshot());
    const auto grid_cells = world.occupied_cells();
    const auto columns = occupied_columns(*octomap, voxels, kBandTop);
    for (int i = 0; i < 400; ++i, ++cases) {
      geometry::Footprint footprint = random_footprint(rng);
      std::visit([&](auto& shape) { shape.height = kBandTop; }, footprint);
      const geometry::Pose2 pose = random_pose(rng, world);
      const Outline outline = outline_of(footprint, pose);
      const double grid_exact = brute_clearance(grid_cells, outline);
      const double octree_exact = brute_clearance(columns, outline);
      double ptem_exact = 1e300;
      for (const mapping::PtemCluster& cluster : snapshot.ptem->clusters()) {
        for (const Eigen::Vector2d& p : cluster.extent_W) ptem_exact = std::min(ptem_exact, point_distance(outline, p));
      }
      const double exact = std::min({grid_exact, octree_exact, ptem_exact});
      octree_nearest += octree_exact < grid_exact ? 1 : 0;
      grid_nearest += grid_exact < octree_exact ? 1 : 0;
      for (const std::vector<v1::Model>& models :
           {std::vector<v1::Model>{v1::MODEL_GRID, v1::MODEL_OCTOMAP, v1::MODEL_PTEM},
            std::vector<v1::Model>{v1::MODEL_OCTOMAP, v1::MODEL_GRID, v1::MODEL_PTEM}}) {
        v1::ClearanceReply reply;
        answer_clearance(snapshot, footprint, pose, kMaxDistance, models, reply);
        if (exact < kMaxDistance - kCell) {
          ASSERT_TRUE(reply.found()) << "case " << cases << " exact " << exact;
        }
        if (!reply.found()) {
          EXPECT_GT(exact, kMaxDistance - kCell) << "case " << cases;
          continue;
        }
        ++found;
        EXPECT_GE(reply.clearance_m(), exact - 1e-9) << "case " << cases;
        EXPECT_LE(reply.clearance_m(), exact + kCell + 1e-9)
            << "case " << cases << ": grid " << grid_exact << " m, octree " << octree_exact << " m, ptem " << ptem_exact
            << " m, answered by model " << reply.model() << ", model " << models[0] << " asked first";
        const double model_exact = reply.model() == v1::MODEL_GRID      ? grid_exact
                                   : reply.model() == v1::MODEL_OCTOMAP ? octree_exact
                                                                        : ptem_exact;
        EXPECT_GE(reply.clearance_m(), model_exact - 1e-9) << "case " << cases << ": not the answering model's";
      }
    }
  }
  EXPECT_GE(cases, 1200);
  EXPECT_GT(found, cases);  // two orders per case
  EXPECT_GT(octree_nearest, cases / 10);
  EXPECT_GT(grid_nearest, cases / 10);
}

}  // namespace
}  // namespace occgeo::service
