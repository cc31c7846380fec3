#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "occgeo/geometry/pose.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/robot.h"
#include "occgeo/sim/shape_world.h"
#include "occgeo/sim/sim_world.h"
#include "occgeo/sim/simulation.h"

namespace occgeo::sim {
namespace {

const std::filesystem::path kWorlds = std::filesystem::path(OCCGEO_SOURCE_DIR) / "clients" / "sim" / "worlds";
constexpr double kLaserHeight_m = 0.6;

const RobotPreset& bearcat() { return *find_robot_preset("bearcat"); }

// The WorldError message parsing text gives, or "" when it parses.
std::string parse_error(const std::string& text) {
  try {
    (void)ShapeWorld::parse(text, "test.yaml");
  } catch (const WorldError& error) {
    return error.what();
  }
  return "";
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(ShapeWorldParse, ReadsEveryShapeKindWithHeightsAndDefaults) {
  const ShapeWorld world = ShapeWorld::parse(R"(
occgeo_world: 1
bounds: [[-1, -2], [3, 4]]
shapes:
  - circle: {center: [1.75, 0], radius: 0.055}
  - box: {center: [2, 1], size: [0.4, 1.0], yaw: 0.5, top_height: 0.3}
  - polygon: {points: [[0, 0], [0, 1], [1, 0]], base_height: 0.9}
moving:
  - shape: {circle: {radius: 0.15, top_height: 0.7}}
    waypoints: [[3.3, 0], [0, 0]]
    speed: 0.1
    loop: false
)",
                                             "test.yaml");
  ASSERT_EQ(world.shapes().size(), 3u);
  EXPECT_EQ(world.shapes()[0].kind, Shape::Kind::circle);
  EXPECT_DOUBLE_EQ(world.shapes()[0].radius_m, 0.055);
  EXPECT_DOUBLE_EQ(world.shapes()[0].base_height_m, 0.0);
  EXPECT_DOUBLE_EQ(world.shapes()[0].top_height_m, 2.0);
  EXPECT_EQ(world.shapes()[1].kind, Shape::Kind::polygon);
  EXPECT_EQ(world.shapes()[1].points.size(), 4u);
  EXPECT_DOUBLE_EQ(world.shapes()[1].top_height_m, 0.3);
  EXPECT_DOUBLE_EQ(world.shapes()[2].base_height_m, 0.9);
  ASSERT_EQ(world.moving().size(), 1u);
  EXPECT_DOUBLE_EQ(world.moving()[0].speed_mps, 0.1);
  EXPECT_FALSE(world.moving()[0].loop);
  EXPECT_TRUE(world.moving()[0].shape.center.isZero());
  ASSERT_TRUE(world.bounds());
  EXPECT_DOUBLE_EQ(world.bounds()->second.y(), 4.0);
  EXPECT_TRUE(world.has_moving_obstacles());
}

TEST(ShapeWorldParse, UnknownKeysAreErrorsNamingTheKeyAndFile) {
  const std::string top = parse_error("shapes: []\nshape: []\n");
  EXPECT_TRUE(contains(top, "test.yaml")) << top;
  EXPECT_TRUE(contains(top, "unknown key 'shape'")) << top;

  const std::string nested = parse_error("shapes:\n  - circle: {center: [1, 0], radus: 0.1}\n");
  EXPECT_TRUE(contains(nested, "test.yaml: shapes[0].circle.radus: unknown key 'radus'")) << nested;

  const std::string kind = parse_error("shapes:\n  - cylinder: {center: [1, 0], radius: 0.1}\n");
  EXPECT_TRUE(contains(kind, "unknown key 'cylinder'")) << kind;

  const std::string moving = parse_error(
      "shapes: []\nmoving:\n  - {shape: {circle: {radius: 1}}, waypoints: [[0, "
      "0]], speed: 1, looping: true}\n");
  EXPECT_TRUE(contains(moving, "moving[0].looping: unknown key 'looping'")) << moving;
}

TEST(ShapeWorldParse, BadValuesNameTheirKey) {
  EXPECT_TRUE(
      contains(parse_error("shapes:\n  - circle: {center: [1, 0]}\n"), "shapes[0].circle: missing key 'radius'"));
  EXPECT_TRUE(contains(parse_error("shapes:\n  - circle: {center: [1, 0], radius: -1}\n"), "shapes[0].circle"));
  EXPECT_TRUE(contains(parse_error("shapes:\n  - box: {center: [1, 0], size: [1, x]}\n"), "shapes[0].box.size[1]"));
  EXPECT_TRUE(contains(parse_error("shapes:\n  - polygon: {points: [[0, 0], [2, 0], [1, 0.2], [1, 2], [0, 2]]}\n"),
                       "not convex"));
  EXPECT_TRUE(
      contains(parse_error("shapes:\n  - box: {center: [1, 0], size: [1, 1], base_height: 1, top_height: 0.5}\n"),
               "shapes[0].box: need 0 <= base_height < top_height"));
  EXPECT_TRUE(contains(parse_error("occgeo_world: 2\n"), "occgeo_world: only version 1"));
  EXPECT_TRUE(contains(parse_error("bounds: [[0, 0], [1, 1]]\n"), "needs 'shapes:' or 'occgeo_world: 1'"));
}

TEST(ShapeRayCast, CircleDistancesAreExact) {
  const Shape circle = Shape::circle({3.0, 0.0}, 0.5);
  EXPECT_DOUBLE_EQ(*ray_distance(circle, {0.0, 0.0}, {1.0, 0.0}), 2.5);
  const Shape diagonal = Shape::circle({2.0, 2.0}, 1.0);
  EXPECT_NEAR(*ray_distance(diagonal, {0.0, 0.0}, Eigen::Vector2d(1.0, 1.0).normalized()), 2.0 * std::sqrt(2.0) - 1.0,
              1e-12);
  EXPECT_FALSE(ray_distance(circle, {0.0, 0.5}, {1.0, 0.0}));            // tangent passes
  EXPECT_FALSE(ray_distance(circle, {0.0, 0.0}, {-1.0, 0.0}));           // behind
  EXPECT_DOUBLE_EQ(*ray_distance(circle, {3.1, 0.0}, {1.0, 0.0}), 0.0);  // starts inside
}

TEST(ShapeRayCast, RotatedBoxDistanceIsExact) {
  // A 2 x 1 box at (3, 0) turned 45 degrees: along the x axis its inside is |x - 3| < 0.5 / sin 45.
  const Shape box = Shape::box({3.0, 0.0}, 2.0, 1.0, M_PI / 4.0);
  EXPECT_NEAR(*ray_distance(box, {0.0, 0.0}, {1.0, 0.0}), 3.0 - 0.5 * std::sqrt(2.0), 1e-12);
  // Straight down through the centre: by symmetry the inside along x = 3 is |y| < 0.5 / sin 45 as well.
  EXPECT_NEAR(*ray_distance(box, {3.0, 5.0}, {0.0, -1.0}), 5.0 - 0.5 * std::sqrt(2.0), 1e-12);
}

TEST(ShapeRayCast, NormalsAreTheSurfacesAtTheEntryPoint) {
  // Circle: radial at the entry point, pointing back out of the circle.
  const Shape circle = Shape::circle({3.0, 0.0}, 0.5);
  const auto head_on = ray_hit(circle, {0.0, 0.0}, {1.0, 0.0});
  ASSERT_TRUE(head_on);
  EXPECT_NEAR((head_on->normal_W - Eigen::Vector2d(-1.0, 0.0)).norm(), 0.0, 1e-12);
  // Off centre at y = 0.3: enters at (3 - 0.4, 0.3), so the normal is (-0.4, 0.3) / 0.5.
  const auto off_centre = ray_hit(circle, {0.0, 0.3}, {1.0, 0.0});
  ASSERT_TRUE(off_centre);
  EXPECT_NEAR(off_centre->distance_m, 2.6, 1e-12);
  EXPECT_NEAR((off_centre->normal_W - Eigen::Vector2d(-0.8, 0.6)).norm(), 0.0, 1e-12);
  // Starting inside, no surface was crossed: the reversed direction.
  EXPECT_EQ(ray_hit(circle, {3.1, 0.0}, {0.0, 1.0})->normal_W, Eigen::Vector2d(0.0, -1.0));

  // A 2 x 1 box at (3, 0) turned 30°: a ray at the midpoint of its long side y = -0.5 (box frame), head on, gets that
  // side's outward normal, rotated with the box.
  const double yaw = M_PI / 6.0;
  const Shape box = Shape::box({3.0, 0.0}, 2.0, 1.0, yaw);
  const Eigen::Vector2d long_side_normal(std::sin(yaw), -std::cos(yaw));  // outward normal of the y = -0.5 side
  const auto square = ray_hit(box, Eigen::Vector2d(3.0, 0.0) + 2.0 * long_side_normal, -long_side_normal);
  ASSERT_TRUE(square);
  EXPECT_NEAR(square->distance_m, 1.5, 1e-12);
  EXPECT_NEAR((square->normal_W - long_side_normal).norm(), 0.0, 1e-12);
  // Obliquely, entering the same side 0.5 m from its midpoint along the side: still that side's normal.
  const Eigen::Vector2d along(std::cos(yaw), std::sin(yaw));
  const Eigen::Vector2d entry = Eigen::Vector2d(3.0, 0.0) - 0.5 * -long_side_normal + 0.5 * along;
  const Eigen::Vector2d oblique = (-long_side_normal + 0.5 * along).normalized();
  const auto slanted = ray_hit(box, entry - 2.0 * oblique, oblique);
  ASSERT_TRUE(slanted);
  EXPECT_NEAR(slanted->distance_m, 2.0, 1e-12);
  EXPECT_NEAR((slanted->normal_W - long_side_normal).norm(), 0.0, 1e-12);
}

TEST(ShapeWorldCast, NormalComesFromTheNearestShapeIncludingMovingOnes) {
  MovingObstacle mover{
      .shape = Shape::circle({0.0, 0.0}, 0.5), .waypoints = {{2.0, 0.0}, {2.0, 5.0}}, .speed_mps = 1.0, .loop = false};
  const ShapeWorld world({Shape::box({5.0, 0.0}, 1.0, 1.0, 0.0)}, {mover});
  // At t = 0 the moving circle at (2, 0) is nearest: radial normal (-1, 0); at t = 3 it is out of the way at (2, 3)
  // and the box's left face, normal (-1, 0), is hit at 4.5 m; from above, the box's top face gives (0, 1).
  const auto first = world.cast({0.0, 0.0}, {1.0, 0.0}, 8.0, 0.0, kLaserHeight_m);
  ASSERT_TRUE(first);
  EXPECT_NEAR(first->distance_m, 1.5, 1e-12);
  EXPECT_NEAR((first->normal_W - Eigen::Vector2d(-1.0, 0.0)).norm(), 0.0, 1e-12);
  const auto later = world.cast({0.0, 0.0}, {1.0, 0.0}, 8.0, 3.0, kLaserHeight_m);
  ASSERT_TRUE(later);
  EXPECT_NEAR(later->distance_m, 4.5, 1e-12);
  EXPECT_NEAR((later->normal_W - Eigen::Vector2d(-1.0, 0.0)).norm(), 0.0, 1e-12);
  const auto top = world.cast({5.0, 3.0}, {0.0, -1.0}, 8.0, 0.0, kLaserHeight_m);
  ASSERT_TRUE(top);
  EXPECT_NEAR((top->normal_W - Eigen::Vector2d(0.0, 1.0)).norm(), 0.0, 1e-12);
}

TEST(ShapeRayCast, PolygonDistanceIsExactEitherWinding) {
  // Left edge from (3, -1) to (2, 1): at y = 0 it lies at x = 2.5; at y = 0.5 at x = 2.25.
  const Shape ccw = Shape::polygon({{3.0, -1.0}, {5.0, -1.0}, {5.0, 1.0}, {2.0, 1.0}});
  const Shape cw = Shape::polygon({{2.0, 1.0}, {5.0, 1.0}, {5.0, -1.0}, {3.0, -1.0}});
  for (const Shape* polygon : {&ccw, &cw}) {
    EXPECT_NEAR(*ray_distance(*polygon, {0.0, 0.0}, {1.0, 0.0}), 2.5, 1e-12);
    EXPECT_NEAR(*ray_distance(*polygon, {0.0, 0.5}, {1.0, 0.0}), 2.25, 1e-12);
    EXPECT_NEAR(*ray_distance(*polygon, {10.0, 0.0}, {-1.0, 0.0}), 5.0, 1e-12);
    EXPECT_FALSE(ray_distance(*polygon, {0.0, 1.0}, {1.0, 0.0}));  // along the top edge
    EXPECT_FALSE(ray_distance(*polygon, {0.0, 2.0}, {1.0, 0.0}));
  }
}

TEST(ShapeWorldCast, ReturnsTheNearestShapeWithinRange) {
  const ShapeWorld world({Shape::circle({5.0, 0.0}, 0.5), Shape::box({3.0, 0.0}, 1.0, 1.0, 0.0)}, {});
  EXPECT_DOUBLE_EQ(world.cast({0.0, 0.0}, {1.0, 0.0}, 8.0, 0.0, kLaserHeight_m)->distance_m, 2.5);
  EXPECT_FALSE(world.cast({0.0, 0.0}, {1.0, 0.0}, 2.5, 0.0, kLaserHeight_m));  // not closer than the range
  EXPECT_FALSE(world.cast({0.0, 0.0}, {0.0, 1.0}, 8.0, 0.0, kLaserHeight_m));
}

TEST(ShapeWorldHeights, ShortObstacleIsInvisibleToTheLaserButCollides) {
  Shape kerb = Shape::box({2.0, 0.0}, 0.4, 1.0, 0.0);
  kerb.top_height_m = 0.3;
  const ShapeWorld world({kerb}, {});
  EXPECT_FALSE(world.cast({0.45, 0.0}, {1.0, 0.0}, 8.0, 0.0, kLaserHeight_m));
  EXPECT_TRUE(world.cast({0.45, 0.0}, {1.0, 0.0}, 8.0, 0.0, 0.2));                // a laser at 0.2 m would see it
  EXPECT_TRUE(world.find_collision(bearcat().footprint, {1.4, 0.0, 0.0}, 0.0));   // front at 1.9
  EXPECT_FALSE(world.find_collision(bearcat().footprint, {1.3, 0.0, 0.0}, 0.0));  // front touches at 1.8
}

TEST(ShapeWorldHeights, OverhangIsInvisibleToTheLaserButCollidesWithTheTallBody) {
  Shape beam = Shape::box({4.0, 0.0}, 0.4, 1.5, 0.0);
  beam.base_height_m = 0.9;
  const ShapeWorld world({beam}, {});
  EXPECT_FALSE(world.cast({0.45, 0.0}, {1.0, 0.0}, 8.0, 0.0, kLaserHeight_m));
  EXPECT_TRUE(world.find_collision(bearcat().footprint, {4.0, 0.0, 0.0}, 0.0));

  Shape high = beam;
  high.base_height_m = 1.3;  // above the 1.2 m tall robot
  EXPECT_FALSE(ShapeWorld({high}, {}).find_collision(bearcat().footprint, {4.0, 0.0, 0.0}, 0.0));
}

TEST(ShapeWorldHeights, RobotDrivesIntoTheUnseenShortObstacleOfTheShippedWorld) {
  const auto world = load_sim_world(kWorlds / "short_and_overhang.yaml");
  RobotPreset preset = bearcat();
  preset.laser()->range_noise_sigma_m = 0.0;
  Simulation simulation(load_sim_world(kWorlds / "short_and_overhang.yaml"), preset, {0.0, 0.0, 0.0}, 1);
  const SensorBatch batch = simulation.take_batch();
  const v1::LaserScan& laser = *batch.laser_scan();
  for (const float range : laser.ranges()) EXPECT_FLOAT_EQ(range, 8.0f);  // sees nothing

  SimulatedRobot robot(*world, preset, {0.0, 0.0, 0.0});
  for (int i = 0; i < 500; ++i) {
    if (i % 40 == 0) robot.command({.left_mps = 0.5, .right_mps = 0.5});
    robot.step();
  }
  EXPECT_EQ(robot.collisions(), 1u);
  EXPECT_LE(robot.pose().x, 1.3);  // the front (x + 0.5) stopped at the kerb at x = 1.8
  EXPECT_GT(robot.pose().x, 1.29);
}

TEST(MovingObstacle, FollowsItsWaypointsAtConstantSpeed) {
  MovingObstacle crossing{.shape = Shape::circle({0.0, 0.0}, 0.15),
                          .waypoints = {{1.75, -1.0}, {1.75, 1.0}},
                          .speed_mps = 0.2,
                          .loop = false};
  EXPECT_TRUE(crossing.center_at(0.0).isApprox(Eigen::Vector2d(1.75, -1.0)));
  EXPECT_TRUE(crossing.center_at(5.0).isApprox(Eigen::Vector2d(1.75, 0.0)));
  EXPECT_TRUE(crossing.center_at(10.0).isApprox(Eigen::Vector2d(1.75, 1.0)));
  EXPECT_TRUE(crossing.center_at(30.0).isApprox(Eigen::Vector2d(1.75, 1.0)));  // one-shot stops
  crossing.loop = true;  // back along the closing segment, then round again
  EXPECT_TRUE(crossing.center_at(15.0).isApprox(Eigen::Vector2d(1.75, 0.0)));
  EXPECT_TRUE(crossing.center_at(22.5).isApprox(Eigen::Vector2d(1.75, -0.5)));
}

TEST(MovingObstacle, StandsAtItsFirstWaypointUntilItsStartTime) {
  const MovingObstacle late{.shape = Shape::circle({0.0, 0.0}, 0.15),
                            .waypoints = {{1.75, -1.0}, {1.75, 1.0}},
                            .speed_mps = 0.2,
                            .loop = false,
                            .start_s = 4.0};
  EXPECT_TRUE(late.center_at(0.0).isApprox(Eigen::Vector2d(1.75, -1.0)));
  EXPECT_TRUE(late.center_at(4.0).isApprox(Eigen::Vector2d(1.75, -1.0)));
  EXPECT_TRUE(late.center_at(9.0).isApprox(Eigen::Vector2d(1.75, 0.0)));
}

TEST(MovingObstacle, ContactsAreSplitIntoRunningIntoItAndBeingRunInto) {
  // A person walks through where the robot stands: a contact at rest. Then the robot drives into a wall: moving.
  const MovingObstacle person{.shape = Shape::circle({0.0, 0.0}, 0.25),
                              .waypoints = {{0.0, -3.0}, {0.0, 3.0}},
                              .speed_mps = 1.0,
                              .loop = false};
  const ShapeWorld world({Shape::box({4.0, 0.0}, 0.2, 4.0, 0.0)}, {person});
  SimulatedRobot robot(world, bearcat(), {0.0, 0.0, 0.0});
  for (int i = 0; i < 800; ++i) robot.step();  // 8 s standing: the person passes through at t 3 s
  EXPECT_EQ(robot.collisions_at_rest(), 1u);
  EXPECT_EQ(robot.collisions_moving(), 0u);
  for (int i = 0; i < 800; ++i) {
    if (i % 40 == 0) robot.command({.left_mps = 0.5, .right_mps = 0.5});
    robot.step();
  }
  EXPECT_EQ(robot.collisions_moving(), 1u);
  EXPECT_EQ(robot.collisions_at_rest(), 1u);
  EXPECT_EQ(robot.collisions(), 2u);
}

TEST(MovingObstacle, AWalkerCatchingUpWithARobotDrivingAwayRanIntoIt) {
  // The robot backs away at 0.1 m/s from a person walking at it at 1 m/s: the person comes into the footprint where
  // the robot stands, so the contact is theirs, not the robot's, though its wheels turn.
  const MovingObstacle walker{.shape = Shape::circle({0.0, 0.0}, 0.25),
                              .waypoints = {{3.0, 0.0}, {-3.0, 0.0}},
                              .speed_mps = 1.0,
                              .loop = false};
  const ShapeWorld world({}, {walker});
  SimulatedRobot robot(world, bearcat(), {0.0, 0.0, 0.0});
  for (int i = 0; i < 300; ++i) {
    if (i % 40 == 0) robot.command({.left_mps = -0.1, .right_mps = -0.1});
    robot.step();
  }
  EXPECT_EQ(robot.collisions_hit_moving(), 1u);
  EXPECT_EQ(robot.collisions_moving(), 0u);
  EXPECT_EQ(robot.collisions_at_rest(), 0u);
  ASSERT_EQ(robot.collision_events().size(), 1u);
  EXPECT_TRUE(robot.collision_events()[0].moving);
  EXPECT_TRUE(robot.collision_events()[0].ran_into_robot);
  EXPECT_NE(robot.collision_events()[0].obstacle.find(" at t = "), std::string::npos);  // the walker, where and when

  // Driving at a person who stands still (a walker that has arrived) is the robot's contact.
  const MovingObstacle arrived{
      .shape = Shape::circle({0.0, 0.0}, 0.25), .waypoints = {{1.5, 0.0}, {1.5, 0.0}}, .speed_mps = 1.0, .loop = false};
  const ShapeWorld still({}, {arrived});
  SimulatedRobot driving(still, bearcat(), {0.0, 0.0, 0.0});
  for (int i = 0; i < 400; ++i) {
    if (i % 40 == 0) driving.command({.left_mps = 0.5, .right_mps = 0.5});
    driving.step();
  }
  EXPECT_EQ(driving.collisions_moving(), 1u);
  EXPECT_EQ(driving.collisions_hit_moving(), 0u);
  ASSERT_EQ(driving.collision_events().size(), 1u);
  EXPECT_FALSE(driving.collision_events()[0].ran_into_robot);
}

TEST(MovingObstacle, SuccessiveScansSeeTheApproachingObstacleCloser) {
  RobotPreset preset = bearcat();
  preset.laser()->range_noise_sigma_m = 0.0;
  Simulation simulation(load_sim_world(kWorlds / "ptem_approaching.yaml"), preset, {0.0, 0.0, 0.0}, 1);
  const int ahead = static_cast<int>(std::lround(-preset.laser()->angle_min_rad / preset.laser()->angle_increment_rad));
  std::vector<double> ranges;
  while (ranges.size() < 20) {
    if (simulation.batch_due()) {
      const SensorBatch batch = simulation.take_batch();
      const v1::LaserScan& laser = *batch.laser_scan();
      ranges.push_back(laser.ranges(ahead));
      // Obstacle surface at 3.3 - 0.1 t - 0.15, laser at x = 0.45.
      EXPECT_NEAR(ranges.back(), 3.3 - 0.1 * laser.stamp_s() - 0.15 - 0.45, 1e-5);
    }
    simulation.step();
  }
  for (std::size_t i = 1; i < ranges.size(); ++i) {
    EXPECT_NEAR(ranges[i - 1] - ranges[i], 0.1 * 0.1, 1e-5) << "scan " << i;
  }
}

// The UGV preset's URG-04LX (seed 004 §3.2.1) sees the approaching obstacle of seed 004 §6 at its new position in
// every scan. No URG beam points straight ahead (682 beams over 240°): the two middle ones are ±0.176° off the axis,
// so the expected range is the exact ray-circle distance for beam 340.
TEST(MovingObstacle, UgvUrgSeesTheApproachingObstacleAtItsNewPositionEachScan) {
  RobotPreset preset = *find_robot_preset("ugv");
  LaserPreset& urg = *preset.laser();
  urg.range_noise_sigma_m = 0.0;
  Simulation simulation(load_sim_world(kWorlds / "ptem_approaching.yaml"), preset, {0.0, 0.0, 0.0}, 1);
  constexpr int kBeam = 340;
  const double angle_rad = urg.angle_min_rad + kBeam * urg.angle_increment_rad;
  ASSERT_NEAR(angle_rad, -0.5 * urg.angle_increment_rad, 1e-12);
  std::vector<double> ranges;
  for (int step = 0; step < 3000 && ranges.size() < 20; ++step) {
    if (simulation.batch_due()) {
      const SensorBatch batch = simulation.take_batch();
      const v1::LaserScan* scan = batch.laser_scan();
      ASSERT_NE(scan, nullptr);
      EXPECT_EQ(scan->sensor(), "urg_04lx");
      ASSERT_EQ(scan->ranges_size(), 682);
      ranges.push_back(scan->ranges(kBeam));
      // Centre at 3.3 - 0.1 t on the x axis, radius 0.15; the laser at x = 0.3.
      const double centre_ahead_m = 3.3 - 0.1 * scan->stamp_s() - urg.X_BS.x;
      const double along_m = centre_ahead_m * std::cos(angle_rad);
      const double across_m = centre_ahead_m * std::sin(angle_rad);
      EXPECT_NEAR(ranges.back(), along_m - std::sqrt(0.15 * 0.15 - across_m * across_m), 1e-5);
    }
    simulation.step();
  }
  ASSERT_EQ(ranges.size(), 20U);
  for (std::size_t i = 1; i < ranges.size(); ++i) {
    EXPECT_NEAR(ranges[i - 1] - ranges[i], 0.1 * 0.1, 1e-4) << "scan " << i << ": 0.1 m/s for one 0.1 s period";
  }
}

TEST(MovingObstacle, RunningIntoAStandingRobotIsOneCollision) {
  Simulation simulation(load_sim_world(kWorlds / "ptem_approaching.yaml"), bearcat(), {0.0, 0.0, 0.0}, 1);
  // The front is at x = 0.5, so contact starts when the centre passes 0.65: t = 26.5 s.
  while (simulation.robot().time_s() < 26.4) simulation.step();
  EXPECT_EQ(simulation.robot().collisions(), 0u);
  while (simulation.robot().time_s() < 40.0) simulation.step();
  EXPECT_EQ(simulation.robot().collisions(), 1u);
}

TEST(SimWorldLoad, EveryShippedWorldLoadsAndTheStartIsClear) {
  int loaded = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kWorlds)) {
    if (entry.path().extension() != ".yaml") continue;
    SCOPED_TRACE(entry.path().string());
    const std::unique_ptr<SimWorld> world = load_sim_world(entry.path());
    ASSERT_TRUE(world);
    for (const RobotPreset& preset : robot_presets()) {
      EXPECT_FALSE(world->find_collision(preset.footprint, {0.0, 0.0, 0.0}, 0.0)) << preset.name;
    }
    ++loaded;
  }
  EXPECT_EQ(loaded, 16) << "a world was added or removed: update this count and clients/sim/worlds/README.md";
  EXPECT_TRUE(dynamic_cast<const PixelWorld*>(load_sim_world(kWorlds / "corridor.yaml").get()));
  EXPECT_TRUE(dynamic_cast<const ShapeWorld*>(load_sim_world(kWorlds / "ptem_thin.yaml").get()));
}

TEST(SimWorldLoad, ShippedPtemWorldsPutTheObstacleAt175) {
  for (const char* name : {"ptem_thin.yaml", "ptem_cone.yaml"}) {
    const auto world = load_sim_world(kWorlds / name);
    const auto hit = world->cast({0.45, 0.0}, {1.0, 0.0}, 8.0, 0.0, kLaserHeight_m);
    ASSERT_TRUE(hit) << name;
    EXPECT_NEAR(hit->distance_m, 1.75 - (std::string(name) == "ptem_thin.yaml" ? 0.055 : 0.15) - 0.45, 1e-12);
  }
}

TEST(SimWorldLoad, UnrecognisedFilesAreErrorsNamingTheFile) {
  const std::filesystem::path path = std::filesystem::temp_directory_path() / "occgeo_sim_neither_world.yaml";
  std::ofstream(path) << "resolution: 0.1\n";
  try {
    (void)load_sim_world(path);
    FAIL() << "no error";
  } catch (const WorldError& error) {
    EXPECT_TRUE(contains(error.what(), path.string())) << error.what();
    EXPECT_TRUE(contains(error.what(), "neither")) << error.what();
  }
  std::filesystem::remove(path);
  EXPECT_THROW((void)load_sim_world(kWorlds / "no_such_world.yaml"), WorldError);
}

}  // namespace
}  // namespace occgeo::sim
