// The simulated depth sensor: 3-D ray casts against each shape kind (heights, yaw, non-solid and moving shapes), the
// ground and pixel worlds; the frame's points in the sensor frame; the bearcat_3d preset's RobotSpec and its clouds
// of the short and the overhanging obstacle (seed 000 Fig 5.2).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "occgeo/geometry/pose.h"
#include "occgeo/sim/depth_sensor.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/shape_world.h"
#include "occgeo/sim/sim_world.h"
#include "occgeo/sim/simulation.h"

namespace occgeo::sim {
namespace {

const std::filesystem::path kWorlds = std::filesystem::path(OCCGEO_SOURCE_DIR) / "clients" / "sim" / "worlds";

Shape with_heights(Shape shape, double base_m, double top_m) {
  shape.base_height_m = base_m;
  shape.top_height_m = top_m;
  return shape;
}

TEST(DepthRayCast, BoxIsEnteredThroughItsSideItsTopOrItsUnderside) {
  // A 1 m cube of material from x = 2 to 3, y = -0.5 to 0.5, z = 0.5 to 1.5.
  const Shape box = with_heights(Shape::box({2.5, 0.0}, 1.0, 1.0, 0.0), 0.5, 1.5);
  // Level at 1 m: enters the near face.
  EXPECT_NEAR(*ray_entry_3d(box, {0.0, 0.0, 1.0}, {1.0, 0.0, 0.0}), 2.0, 1e-12);
  // Level below the base or above the top: passes.
  EXPECT_FALSE(ray_entry_3d(box, {0.0, 0.0, 0.4}, {1.0, 0.0, 0.0}));
  EXPECT_FALSE(ray_entry_3d(box, {0.0, 0.0, 1.6}, {1.0, 0.0, 0.0}));
  // Down from above onto the top face at (2.5, 0, 1.5).
  const Eigen::Vector3d down = Eigen::Vector3d(1.0, 0.0, -1.0).normalized();
  EXPECT_NEAR(*ray_entry_3d(box, {1.0, 0.0, 3.0}, down), std::sqrt(2.0) * 1.5, 1e-12);
  // Up from below onto the underside at (2.2, 0, 0.5).
  const Eigen::Vector3d up = Eigen::Vector3d(2.2, 0.0, 0.4).normalized();
  EXPECT_NEAR(*ray_entry_3d(box, {0.0, 0.0, 0.1}, up), Eigen::Vector3d(2.2, 0.0, 0.4).norm(), 1e-12);
  // Straight down onto the top, and from inside.
  EXPECT_NEAR(*ray_entry_3d(box, {2.5, 0.0, 2.0}, {0.0, 0.0, -1.0}), 0.5, 1e-12);
  EXPECT_EQ(*ray_entry_3d(box, {2.5, 0.0, 1.0}, {1.0, 0.0, 0.0}), 0.0);
  // Pointing away.
  EXPECT_FALSE(ray_entry_3d(box, {0.0, 0.0, 1.0}, {-1.0, 0.0, 0.0}));
}

TEST(DepthRayCast, YawedBoxAndCylinderAreEnteredWhereTheirOutlinesAre) {
  // A box turned 45°: its corner points at the ray, 1/sqrt(2) from its centre.
  const Shape diamond = with_heights(Shape::box({3.0, 0.0}, 1.0, 1.0, std::numbers::pi / 4.0), 0.0, 0.3);
  EXPECT_NEAR(*ray_entry_3d(diamond, {0.0, 0.0, 0.2}, {1.0, 0.0, 0.0}), 3.0 - std::sqrt(0.5), 1e-12);
  // A kerb-height cylinder of radius 0.5 at x = 3: a ray sloping down from 1 m enters its top or its side.
  const Shape post = with_heights(Shape::circle({3.0, 0.0}, 0.5), 0.0, 0.3);
  const Eigen::Vector3d to_side = Eigen::Vector3d(2.5, 0.0, 0.1 - 1.0).normalized();
  EXPECT_NEAR(*ray_entry_3d(post, {0.0, 0.0, 1.0}, to_side), Eigen::Vector3d(2.5, 0.0, -0.9).norm(), 1e-12);
  const Eigen::Vector3d to_top = Eigen::Vector3d(3.0, 0.0, 0.3 - 1.0).normalized();
  EXPECT_NEAR(*ray_entry_3d(post, {0.0, 0.0, 1.0}, to_top), Eigen::Vector3d(3.0, 0.0, -0.7).norm(), 1e-12);
  // Over it and beside it.
  EXPECT_FALSE(ray_entry_3d(post, {0.0, 0.0, 1.0}, Eigen::Vector3d(1.0, 0.0, 0.05).normalized()));
  EXPECT_FALSE(ray_entry_3d(post, {0.0, 0.6, 0.2}, {1.0, 0.0, 0.0}));
  // Straight down into it and just beside it.
  EXPECT_NEAR(*ray_entry_3d(post, {3.2, 0.0, 1.0}, {0.0, 0.0, -1.0}), 0.7, 1e-12);
  EXPECT_FALSE(ray_entry_3d(post, {3.6, 0.0, 1.0}, {0.0, 0.0, -1.0}));
}

TEST(DepthRayCast, ConvexPolygonIsEnteredThroughItsSlantedEdge) {
  Shape wedge = with_heights(Shape::polygon({{2.0, -1.0}, {3.0, -1.0}, {3.0, 1.0}, {2.0, 0.0}}), 0.0, 1.0);
  // Along y = 0.5 the slanted edge from (2, 0) to (3, 1) is at x = 2.5.
  EXPECT_NEAR(*ray_entry_3d(wedge, {0.0, 0.5, 0.5}, {1.0, 0.0, 0.0}), 2.5, 1e-12);
  EXPECT_NEAR(*ray_entry_3d(wedge, {0.0, -0.5, 0.5}, {1.0, 0.0, 0.0}), 2.0, 1e-12);
}

TEST(DepthRayCast, RampIsEnteredThroughItsSlopedSurface) {
  // The shipped ramp: x 3..7 rising 0.2 m per metre, 2.8 m wide; the platform beyond it.
  const auto world = load_sim_world(kWorlds / "ramp.yaml");
  const auto& shapes = dynamic_cast<const ShapeWorld&>(*world).shapes();
  const Shape& ramp = shapes[3];
  EXPECT_FALSE(ramp.solid);
  EXPECT_NEAR(ramp.slope_rise, 0.2, 1e-12);
  // Straight down at x = 4.5: the surface is 0.3 m high.
  EXPECT_NEAR(*ray_entry_3d(ramp, {4.5, 0.0, 1.0}, {0.0, 0.0, -1.0}), 0.7, 1e-12);
  // Level at 0.6 m: enters where the slope reaches 0.6 m, x = 6, however far in y (within the width).
  EXPECT_NEAR(*ray_entry_3d(ramp, {0.0, 1.0, 0.6}, {1.0, 0.0, 0.0}), 6.0, 1e-12);
  // Sloping down from a camera 1.1 m up at x = 0: z = 1.1 - 0.25 x meets z = 0.2 (x - 3) at x = 1.7 / 0.45.
  const Eigen::Vector3d down = Eigen::Vector3d(1.0, 0.0, -0.25).normalized();
  EXPECT_NEAR(*ray_entry_3d(ramp, {0.0, 0.0, 1.1}, down), 1.7 / 0.45 * Eigen::Vector3d(1.0, 0.0, -0.25).norm(), 1e-9);
  // Running parallel to the slope just above it: no entry.
  EXPECT_FALSE(ray_entry_3d(ramp, {3.0, 0.0, 0.01}, Eigen::Vector3d(1.0, 0.0, 0.2).normalized()));
  // The laser at 0.6 m sees the slope at x = 6 (a wall to one laser plane), at 0.2 m already at x = 4.
  EXPECT_NEAR(world->cast({0.0, 0.0}, {1.0, 0.0}, 20.0, 0.0, 0.6)->distance_m, 6.0, 1e-12);
  EXPECT_NEAR(world->cast({0.0, 0.0}, {1.0, 0.0}, 20.0, 0.0, 0.2)->distance_m, 4.0, 1e-12);
  // The robot drives up it: no ground-truth collision on the slope or the platform.
  const geometry::BoxFootprint bearcat = find_robot_preset("bearcat")->footprint;
  EXPECT_FALSE(world->find_collision(bearcat, {5.0, 0.0, 0.0}, 0.0));
  EXPECT_FALSE(world->find_collision(bearcat, {9.0, 0.0, 0.0}, 0.0));
}

TEST(DepthRayCast, RampKeysAreChecked) {
  const ShapeWorld world = ShapeWorld::parse(
      "shapes:\n  - ramp: {center: [0, 0], size: [2, 1], yaw: 1.5707963267948966, base_height: 0.1, top_height: "
      "0.5}\n",
      "test.yaml");
  ASSERT_EQ(world.shapes().size(), 1U);
  const Shape& ramp = world.shapes()[0];
  EXPECT_NEAR(ramp.slope_rise, 0.2, 1e-12);
  // Rising along +y: at y = 0.5 the surface is 0.1 + 0.2 * 1.5 = 0.4 m high.
  EXPECT_NEAR(*ray_entry_3d(ramp, {0.0, 0.5, 1.0}, {0.0, 0.0, -1.0}), 0.6, 1e-9);
  try {
    (void)ShapeWorld::parse("shapes:\n  - ramp: {center: [0, 0], size: [2, 1], slope: 3}\n", "test.yaml");
    ADD_FAILURE() << "an unknown key parsed";
  } catch (const WorldError& error) {
    EXPECT_NE(std::string(error.what()).find("shapes[0].ramp.slope: unknown key 'slope'"), std::string::npos)
        << error.what();
  }
}

TEST(DepthRayCast, WorldSeesNonSolidAndMovingShapesAndTheGround) {
  Shape strip = with_heights(Shape::box({2.0, 0.0}, 0.1, 2.0, 0.0), 0.5, 0.7);
  strip.solid = false;  // the laser sees it, the body drives through it: a depth sensor sees it too
  MovingObstacle mover{.shape = with_heights(Shape::circle({0.0, 0.0}, 0.25), 0.0, 2.0),
                       .waypoints = {{5.0, 5.0}, {5.0, -5.0}},
                       .speed_mps = 1.0,
                       .loop = false};
  const ShapeWorld world({strip}, {mover});
  EXPECT_NEAR(*cast_depth_ray(world, {0.0, 0.0, 0.6}, {1.0, 0.0, 0.0}, 10.0, 0.0), 1.95, 1e-12);
  // The mover crosses y = 0 at t = 5 s.
  EXPECT_FALSE(cast_depth_ray(world, {0.0, 0.0, 1.0}, {1.0, 0.0, 0.0}, 10.0, 0.0));
  EXPECT_NEAR(*cast_depth_ray(world, {0.0, 0.0, 1.0}, {1.0, 0.0, 0.0}, 10.0, 5.0), 4.75, 1e-12);
  // The ground: 1 m up, 45° down meets it at sqrt(2) m; beyond the range nothing.
  const Eigen::Vector3d down = Eigen::Vector3d(-1.0, 0.0, -1.0).normalized();
  EXPECT_NEAR(*cast_depth_ray(world, {0.0, 0.0, 1.0}, down, 10.0, 0.0), std::sqrt(2.0), 1e-12);
  EXPECT_FALSE(cast_depth_ray(world, {0.0, 0.0, 1.0}, down, 1.4, 0.0));
  // A shape in front of the ground point wins.
  const Eigen::Vector3d toward_strip = Eigen::Vector3d(2.0, 0.0, -0.4).normalized();
  EXPECT_NEAR(*cast_depth_ray(world, {0.0, 0.0, 1.0}, toward_strip, 10.0, 0.0),
              1.95 * Eigen::Vector3d(2.0, 0.0, -0.4).norm() / 2.0, 1e-9);
}

TEST(DepthRayCast, PixelWorldObstaclesAreInfinitelyTall) {
  const auto world = load_sim_world(kWorlds / "room.yaml");
  const Eigen::Vector3d level(1.0, 0.0, 0.0);
  const Eigen::Vector3d rising = Eigen::Vector3d(1.0, 0.0, 1.0).normalized();
  const auto flat = cast_depth_ray(*world, {0.0, 0.0, 0.5}, level, 20.0, 0.0);
  const auto steep = cast_depth_ray(*world, {0.0, 0.0, 0.5}, rising, 20.0, 0.0);
  ASSERT_TRUE(flat);
  ASSERT_TRUE(steep);
  EXPECT_NEAR(*steep, *flat * std::sqrt(2.0), 1e-9) << "the same wall, reached along the slant";
}

TEST(DepthSensor, DirectionsSpanTheFieldOfViewLeftToRightTopToBottom) {
  const DepthSensorPreset sensor{.name = "depth",
                                 .X_BS = {},
                                 .columns = 5,
                                 .rows = 3,
                                 .horizontal_fov_rad = 1.0,
                                 .vertical_fov_rad = 0.6,
                                 .range_min_m = 0.1,
                                 .range_max_m = 5.0,
                                 .period_s = 0.2,
                                 .range_noise_sigma_m = 0.0};
  const Eigen::Vector3d top_left = depth_ray_direction_S(sensor, 0, 0);
  EXPECT_NEAR(std::atan2(top_left.y(), top_left.x()), 0.5, 1e-12);
  EXPECT_NEAR(std::asin(top_left.z()), 0.3, 1e-12);
  const Eigen::Vector3d centre = depth_ray_direction_S(sensor, 1, 2);
  EXPECT_NEAR((centre - Eigen::Vector3d::UnitX()).norm(), 0.0, 1e-12);
  const Eigen::Vector3d bottom_right = depth_ray_direction_S(sensor, 2, 4);
  EXPECT_NEAR(std::atan2(bottom_right.y(), bottom_right.x()), -0.5, 1e-12);
  EXPECT_NEAR(std::asin(bottom_right.z()), -0.3, 1e-12);
}

// The points of one frame from base_link pose X_WB, in the world frame.
std::vector<Eigen::Vector3d> frame_in_world(DepthSensorSimulator& sensor, const SimWorld& world,
                                            const geometry::Pose2& X_WB) {
  const std::vector<float> xyz = sensor.capture(world, X_WB, 0.0);
  const geometry::Pose3 X_WS = geometry::Pose3::from_pose2(X_WB).compose(sensor.preset().X_BS);
  std::vector<Eigen::Vector3d> points;
  for (std::size_t i = 0; i + 2 < xyz.size(); i += 3) {
    points.push_back(X_WS.transform * Eigen::Vector3d(xyz[i], xyz[i + 1], xyz[i + 2]));
  }
  return points;
}

TEST(DepthSensor, Bearcat3dSeesTheKerbTheOverhangAndTheFloorFromTheStart) {
  const RobotPreset& preset = *find_robot_preset("bearcat_3d");
  ASSERT_EQ(preset.sensors.size(), 2u);
  DepthSensorPreset depth = std::get<DepthSensorPreset>(preset.sensors[1]);
  depth.range_noise_sigma_m = 0.0;
  DepthSensorSimulator sensor(depth, 1);
  const auto world = load_sim_world(kWorlds / "short_and_overhang.yaml");
  const std::vector<Eigen::Vector3d> points = frame_in_world(sensor, *world, {0.0, 0.0, 0.0});
  // The points went through float: a micrometre of slack.
  constexpr double kFloatSlack_m = 1e-5;
  int floor = 0, kerb = 0, overhang = 0;
  for (const Eigen::Vector3d& p : points) {
    const double range = (p - Eigen::Vector3d(0.45, 0.0, 1.1)).norm();
    EXPECT_GE(range, depth.range_min_m);
    EXPECT_LT(range, depth.range_max_m);
    if (std::abs(p.z()) < kFloatSlack_m) {
      ++floor;
    } else if (p.x() > 1.8 - kFloatSlack_m && p.x() < 2.2 + kFloatSlack_m && std::abs(p.y()) <= 0.5 + kFloatSlack_m &&
               p.z() <= 0.3 + kFloatSlack_m) {
      ++kerb;
    } else if (p.x() > 3.8 - kFloatSlack_m && p.x() < 4.2 + kFloatSlack_m && std::abs(p.y()) <= 0.75 + kFloatSlack_m &&
               p.z() >= 0.9 - kFloatSlack_m) {
      ++overhang;
    } else {
      ADD_FAILURE() << "a point on nothing: " << p.transpose();
    }
  }
  EXPECT_GT(floor, 200);
  EXPECT_GT(kerb, 10);
  EXPECT_GT(overhang, 10);
  // In the overhang's height band below the robot's top, where the body would hit it.
  int overhang_in_band = 0;
  for (const Eigen::Vector3d& p : points) overhang_in_band += p.x() > 3.7 && p.z() >= 0.9 && p.z() <= 1.2;
  EXPECT_GT(overhang_in_band, 3);
}

TEST(DepthSensor, NoiseIsSeededAndKeepsPointsWithinRange) {
  const RobotPreset& preset = *find_robot_preset("bearcat_3d");
  const DepthSensorPreset depth = std::get<DepthSensorPreset>(preset.sensors[1]);
  const auto world = load_sim_world(kWorlds / "short_and_overhang.yaml");
  DepthSensorSimulator a(depth, 7), b(depth, 7), c(depth, 8);
  const std::vector<float> first = a.capture(*world, {0.0, 0.0, 0.0}, 0.0);
  EXPECT_EQ(first, b.capture(*world, {0.0, 0.0, 0.0}, 0.0));
  EXPECT_NE(first, c.capture(*world, {0.0, 0.0, 0.0}, 0.0));
  for (std::size_t i = 0; i + 2 < first.size(); i += 3) {
    const double range = Eigen::Vector3d(first[i], first[i + 1], first[i + 2]).norm();
    EXPECT_LT(range, depth.range_max_m);
  }
}

TEST(DepthSensor, RobotSpecDeclaresThePointCloudSensorWithItsMount) {
  const RobotPreset& preset = *find_robot_preset("bearcat_3d");
  const v1::RobotSpec spec = make_robot_spec(preset);
  ASSERT_EQ(spec.sensors_size(), 2);
  const v1::SensorSpec& sensor = spec.sensors(1);
  EXPECT_EQ(sensor.name(), "front_depth");
  ASSERT_TRUE(sensor.has_point_cloud());
  EXPECT_DOUBLE_EQ(sensor.point_cloud().range_max_m(), 6.0);
  EXPECT_EQ(sensor.point_cloud().max_points(), 40u * 30u);
  EXPECT_NEAR(sensor.mount().position().x(), 0.45, 1e-12);
  EXPECT_NEAR(sensor.mount().position().z(), 1.1, 1e-12);
  EXPECT_NEAR(sensor.mount().pitch(), 20.0 * std::numbers::pi / 180.0, 1e-12);
  EXPECT_NEAR(sensor.mount().roll(), 0.0, 1e-12);
  EXPECT_NEAR(sensor.mount().yaw(), 0.0, 1e-12);
  // The mount round-trips through the server's composition (yaw, pitch, roll).
  const geometry::Pose3 X_BS = geometry::Pose3::from_xyz_rpy(
      sensor.mount().position().x(), sensor.mount().position().y(), sensor.mount().position().z(),
      sensor.mount().roll(), sensor.mount().pitch(), sensor.mount().yaw());
  EXPECT_TRUE(X_BS.transform.isApprox(std::get<DepthSensorPreset>(preset.sensors[1]).X_BS.transform, 1e-12));
}

TEST(DepthSensor, SimulationSendsAPointCloudEveryFifthOfASecond) {
  Simulation simulation(load_sim_world(kWorlds / "short_and_overhang.yaml"), *find_robot_preset("bearcat_3d"),
                        {0.0, 0.0, 0.0}, 1);
  int clouds = 0;
  for (int step = 0; step < 1000 && simulation.robot().time_s() < 1.0 - 1e-9; ++step) {
    if (simulation.batch_due()) {
      const SensorBatch batch = simulation.take_batch();
      for (const v1::ClientMessage& message : batch.messages) {
        if (!message.has_point_cloud()) continue;
        ++clouds;
        EXPECT_EQ(message.point_cloud().sensor(), "front_depth");
        EXPECT_EQ(message.point_cloud().xyz_size() % 3, 0);
        EXPECT_GT(message.point_cloud().xyz_size(), 0);
        EXPECT_EQ(message.point_cloud().seq(), batch.last_sensor_seq) << "the cloud closes its batch";
      }
    }
    simulation.step();
  }
  EXPECT_EQ(clouds, 5);
  EXPECT_EQ(simulation.message_counts().at("point_cloud"), 5u);
}

}  // namespace
}  // namespace occgeo::sim
