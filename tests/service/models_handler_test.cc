// The three live models of a world (HIMM grid with its distance field, OctoMap, PTEM) in the
// server: every sensor kind reaches the OctoMap from its 6-DoF pose, the distance field follows the
// grid, collision and clearance queries choose models, and the octree exports as .bt. Against a
// fake session and a real ServerCore (no sockets).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <random>
#include <set>
#include <thread>
#include <vector>

#include "fake_session.h"
#include "model_geometry.h"
#include "occgeo/geometry/collision.h"
#include "occgeo/proto/protocol.h"
#include "sensor_robot_spec.h"
#include "test_robots.h"

namespace occgeo::service {
namespace {

using R = testing::SensorRobot;

// A level laser 0.3 m up on base_link's origin, 181 beams over 180°, 0.05–8 m; mount pitch optional.
v1::RobotSpec laser_spec(double pitch_rad = 0.0) { return testing::laser_probe_spec({.pitch_rad = pitch_rad}); }

using testing::odometry;

v1::LaserScan scan(std::uint64_t seq, double stamp, const std::vector<float>& ranges) {
  v1::LaserScan message;
  message.set_sensor("laser");
  message.set_seq(seq);
  message.set_stamp_s(stamp);
  for (const float r : ranges) message.add_ranges(r);
  return message;
}

// Ranges of the level laser at the origin to a wall x = 2 m (beams beyond ±60° see nothing: max range).
std::vector<float> wall_ranges() {
  std::vector<float> ranges;
  for (int i = 0; i < 181; ++i) {
    const double a = -M_PI / 2 + i * M_PI / 180;
    ranges.push_back(std::abs(a) < M_PI / 3 ? static_cast<float>(2.0 / std::cos(a)) : 8.0F);
  }
  return ranges;
}

ServerConfig test_config() {
  ServerConfig config;
  config.octomap.min_publish_interval_s = 0.0;  // every message publishes the octree: tests read it at once
  config.octomap.outlier_filter_enabled = false;
  return config;
}

class ModelsHandlers : public ::testing::Test {
 protected:
  explicit ModelsHandlers(ServerConfig config = test_config()) : core_(std::move(config)) {}

  std::shared_ptr<FakeSession> driver(const std::string& robot_id, const v1::RobotSpec& spec) {
    auto session = testing::driver_session(core_, robot_id, spec);
    EXPECT_NE(core_.find_robot(robot_id), nullptr) << "the spec was refused";
    return session;
  }

  std::shared_ptr<FakeSession> querier() {
    auto session = std::make_shared<FakeSession>(core_);
    v1::Hello hello;
    hello.set_protocol_version(proto::kProtocolVersion);
    hello.set_role(v1::ROLE_QUERY);
    handle_hello(session, hello);
    EXPECT_TRUE(session->next_of(v1::ServerMessage::kWelcome));
    return session;
  }

  static void expect_ack(FakeSession& session, std::uint64_t seq) {
    const auto reply = session.next_of(v1::ServerMessage::kScanAck);
    ASSERT_TRUE(reply) << "no ack of seq " << seq;
    EXPECT_EQ(reply->scan_ack().seq(), seq);
  }

  [[nodiscard]] WorldSnapshot world() { return core_.world("default")->snapshots(); }
  [[nodiscard]] bool voxel(double x, double y, double z) { return world().octomap->occupied({x, y, z}); }

  v1::CollisionReply collide(const std::shared_ptr<FakeSession>& session, double x, double y,
                             const std::vector<v1::Model>& models, std::optional<double> height = std::nullopt) {
    v1::CollisionQuery query;
    query.set_robot_id("r1");
    query.mutable_pose()->set_x(x);
    query.mutable_pose()->set_y(y);
    for (const auto m : models) query.add_models(m);
    if (height) {
      auto* box = query.mutable_footprint()->mutable_box();
      box->set_length_m(0.6);
      box->set_width_m(0.5);
      box->set_height_m(*height);
    }
    handle_collision_query(session, ++request_id_, query);
    const auto reply = session->next();
    EXPECT_TRUE(reply && reply->has_collision()) << (reply ? reply->DebugString() : "no reply");
    return reply && reply->has_collision() ? reply->collision() : v1::CollisionReply{};
  }

  v1::ClearanceReply clearance(const std::shared_ptr<FakeSession>& session, double x, double y, double theta,
                               const std::vector<v1::Model>& models, double max_distance = 0.0) {
    v1::ClearanceQuery query;
    query.set_robot_id("r1");
    query.mutable_pose()->set_x(x);
    query.mutable_pose()->set_y(y);
    query.mutable_pose()->set_theta(theta);
    query.set_max_distance_m(max_distance);
    for (const auto m : models) query.add_models(m);
    handle_clearance_query(session, ++request_id_, query);
    const auto reply = session->next();
    EXPECT_TRUE(reply && reply->has_clearance()) << (reply ? reply->DebugString() : "no reply");
    return reply && reply->has_clearance() ? reply->clearance() : v1::ClearanceReply{};
  }

  ServerCore core_;
  std::uint64_t request_id_ = 0;
};

TEST_F(ModelsHandlers, LaserScansReachTheOctreeFromTheMountsSixDofPose) {
  auto session = driver("r1", laser_spec());
  handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
  handle_laser_scan(session, scan(1, 0.1, wall_ranges()));
  expect_ack(*session, 1);
  EXPECT_TRUE(voxel(2.0, 0.0, 0.3)) << "the wall, at the laser's height";
  EXPECT_FALSE(voxel(2.0, 0.0, 0.1)) << "nothing below the plane was seen";
  EXPECT_TRUE(world().octomap->occupancy({1.0, 0.0, 0.3}).has_value()) << "the beam cleared its way";
  EXPECT_FALSE(voxel(1.0, 0.0, 0.3));
  EXPECT_EQ(world().octomap->version(), 1U);

  // Pitched 0.1 rad down (R = Ry(0.1) tilts x towards -z), the same ranges end 2 sin(0.1) m lower.
  auto pitched = driver("r2", laser_spec(0.1));
  handle_odometry(pitched, odometry(0.0, 3.0, 0.0, 0.0));
  std::vector<float> ranges(181, 8.0F);
  ranges[90] = 2.0F;
  handle_laser_scan(pitched, scan(1, 0.1, ranges));
  expect_ack(*pitched, 1);
  const double z = 0.3 - 2.0 * std::sin(0.1);
  std::printf("pitched beam end at z = %.4f m\n", z);
  EXPECT_TRUE(voxel(2.0 * std::cos(0.1), 3.0, z));
  EXPECT_FALSE(voxel(2.0, 3.0, 0.3));
}

TEST_F(ModelsHandlers, SonarServoAndCloudReachTheOctreeAndTheDistanceFieldFollowsTheGrid) {
  auto session = driver("r1", testing::sensor_robot_spec());
  handle_odometry(session, odometry(0.05, 0.05, 0.0, 0.0));
  // Servo on base_link's origin 0.3 m up, turned to +90°: a return 1 m to the left.
  v1::ServoRange servo;
  servo.set_sensor("lidar_lite");
  servo.set_seq(1);
  servo.set_stamp_s(0.1);
  servo.set_servo_angle_rad(M_PI / 2);
  servo.set_range_m(1.0F);
  handle_servo_range(session, servo);
  expect_ack(*session, 1);
  EXPECT_TRUE(voxel(0.05, 1.05, 0.3));
  // Sonar element 0 faces ahead from (0.1 + 0.25, 0) at 0.2 m up: a return 1 m ahead of it.
  v1::RangeArray sonar;
  sonar.set_sensor("sonar");
  sonar.set_seq(2);
  sonar.set_stamp_s(0.2);
  for (int k = 0; k < R::kSonarElements; ++k) sonar.add_ranges(k == 0 ? 1.0F : 0.0F);
  handle_range_array(session, sonar);
  expect_ack(*session, 2);
  EXPECT_TRUE(voxel(0.05 + R::kSonarMountX_m + R::kSonarRingRadius_m + 1.0, 0.05, 0.2));

  const WorldSnapshot snapshot = world();
  ASSERT_TRUE(snapshot.distance);
  EXPECT_EQ(snapshot.distance->version(), snapshot.grid->version()) << "the field matches the published grid";
  const geometry::CellIndex servo_cell = geometry::GridGeometry(snapshot.grid->cell_size()).cell_of({0.05, 1.05});
  EXPECT_TRUE(snapshot.grid->occupied(servo_cell));
  EXPECT_EQ(snapshot.distance->distance(servo_cell), 0.0);
}

// An overhang (z 0.9–1.0 m) above the 0.5 m robot, seen by the depth camera: only the octree holds it,
// and only a footprint taller than 0.9 m collides with it.
TEST_F(ModelsHandlers, CollisionChoosesModelsAndTheOctreeSeesAnOverhangTheGridCannot) {
  auto session = driver("r1", testing::sensor_robot_spec());
  handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
  v1::PointCloud cloud;
  cloud.set_sensor("depth");
  cloud.set_seq(1);
  cloud.set_stamp_s(0.1);
  // The camera is at (0.2, 0, 0.3); the overhang's underside: x 1.3..1.7, y -0.3..0.3, z 0.9 (sensor z 0.6).
  for (double x = 1.3; x <= 1.7001; x += 0.025) {
    for (double y = -0.3; y <= 0.3001; y += 0.025) {
      cloud.add_xyz(static_cast<float>(x - R::kDepthMountX_m));
      cloud.add_xyz(static_cast<float>(y));
      cloud.add_xyz(static_cast<float>(0.92 - R::kDepthMountZ_m));
    }
  }
  ASSERT_LE(cloud.xyz_size() / 3, static_cast<int>(R::kDepthMaxPoints));
  handle_point_cloud(session, cloud);
  expect_ack(*session, 1);
  EXPECT_TRUE(voxel(1.5, 0.0, 0.92));
  EXPECT_EQ(world().grid->occupied_cell_count(), 0U) << "above the robot: not in the 2D grid";

  auto q = querier();
  const auto grid_only = collide(q, 1.5, 0.0, {v1::MODEL_GRID}, 1.2);
  EXPECT_FALSE(grid_only.hit());
  EXPECT_EQ(grid_only.model(), v1::MODEL_UNSPECIFIED);
  const auto octomap = collide(q, 1.5, 0.0, {v1::MODEL_OCTOMAP}, 1.2);
  ASSERT_TRUE(octomap.hit());
  EXPECT_EQ(octomap.model(), v1::MODEL_OCTOMAP);
  std::printf("octomap contact (%.3f, %.3f, %.3f)\n", octomap.contact().x(), octomap.contact().y(),
              octomap.contact().z());
  EXPECT_NEAR(octomap.contact().z(), 0.925, 0.1);
  EXPECT_NEAR(octomap.contact().x(), 1.5, 0.5);
  const auto all = collide(q, 1.5, 0.0, {}, 1.2);
  EXPECT_TRUE(all.hit());
  EXPECT_EQ(all.model(), v1::MODEL_OCTOMAP) << "empty models: grid (clear), then octomap";
  EXPECT_FALSE(collide(q, 1.5, 0.0, {v1::MODEL_OCTOMAP}).hit()) << "the robot's own 0.5 m passes under";
  EXPECT_FALSE(collide(q, 3.0, 0.0, {v1::MODEL_OCTOMAP}, 1.2).hit()) << "beyond the overhang";

  // Clearance on the octree's columns in the robot's band: 1.2 m tall, 1 m before the overhang's edge at x 1.3.
  q = querier();
  v1::ClearanceQuery query;
  query.set_robot_id("r1");
  query.mutable_pose()->set_x(0.0);
  query.add_models(v1::MODEL_OCTOMAP);
  auto* box = query.mutable_footprint()->mutable_box();
  box->set_length_m(0.6);
  box->set_width_m(0.5);
  box->set_height_m(1.2);
  handle_clearance_query(q, 7, query);
  const auto reply = q->next();
  ASSERT_TRUE(reply && reply->has_clearance()) << (reply ? reply->DebugString() : "no reply");
  std::printf("octomap clearance %.4f m (model %d)\n", reply->clearance().clearance_m(), reply->clearance().model());
  EXPECT_TRUE(reply->clearance().found());
  EXPECT_EQ(reply->clearance().model(), v1::MODEL_OCTOMAP);
  EXPECT_NEAR(reply->clearance().clearance_m(), 1.0, 0.05 + 1e-9);
}

TEST_F(ModelsHandlers, GridClearanceComesFromTheDistanceFieldWithinOneCellOfExact) {
  auto session = driver("r1", laser_spec());
  handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
  handle_laser_scan(session, scan(1, 0.1, wall_ranges()));
  expect_ack(*session, 1);
  auto q = querier();
  const WorldSnapshot snapshot = world();
  const geometry::Footprint footprint = geometry::BoxFootprint{0.6, 0.4, 0.5, 0.0};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> x(-0.5, 1.4), y(-1.5, 1.5), theta(-M_PI, M_PI);
  double worst = 0.0;
  for (int i = 0; i < 200; ++i) {
    const geometry::Pose2 pose{x(rng), y(rng), theta(rng)};
    const auto reply = clearance(q, pose.x, pose.y, pose.theta, {v1::MODEL_GRID}, 3.0);
    const auto exact = geometry::compute_clearance({footprint, pose, 3.0}, *snapshot.grid);
    ASSERT_EQ(reply.found(), exact.found) << i;
    if (!exact.found) continue;
    EXPECT_EQ(reply.model(), v1::MODEL_GRID);
    EXPECT_GE(reply.clearance_m(), exact.clearance_m - 1e-9) << i;
    EXPECT_LE(reply.clearance_m(), exact.clearance_m + snapshot.grid->cell_size() + 1e-9) << i;
    worst = std::max(worst, reply.clearance_m() - exact.clearance_m);
  }
  std::printf("distance-field clearance: largest excess over exact %.4f m over 200 poses\n", worst);
}

// The thin obstacle of seed 004 §5.1.1 as a PTEM cluster: a footprint holding one of its returns collides with the
// PTEM, clearance measures to the returns, and the circle around them (which reaches into free floor) is keep-out.
TEST_F(ModelsHandlers, PtemClusterReturnsAreObstaclesForModelPtemAndItsCircleIsKeepOut) {
  auto session = driver("r1", laser_spec());
  handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
  const Eigen::Vector2d obstacle(1.75, 0.0);
  std::vector<float> ranges;
  for (int i = 0; i < 181; ++i) {
    const double a = -M_PI / 2 + i * M_PI / 180;
    const Eigen::Vector2d u(std::cos(a), std::sin(a));
    const double b = u.dot(obstacle);
    const double c = obstacle.squaredNorm() - 0.055 * 0.055;
    const double disc = b * b - c;
    ranges.push_back(disc >= 0 ? static_cast<float>(b - std::sqrt(disc)) : 8.0F);
  }
  handle_laser_scan(session, scan(1, 0.1, ranges));
  expect_ack(*session, 1);
  const auto ptem = world().ptem;
  ASSERT_EQ(ptem->clusters().size(), 1U);
  const mapping::PtemCluster& cluster = ptem->clusters().front();
  ASSERT_FALSE(cluster.extent_W.empty());
  // The return nearest the robot: the obstacle's front, 1.695 m out.
  const Eigen::Vector2d front =
      *std::min_element(cluster.extent_W.begin(), cluster.extent_W.end(),
                        [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() < b.x(); });
  EXPECT_NEAR(front.x(), 1.695, 0.002);
  std::printf("cluster at (%.3f, %.3f), radius %.4f m, %zu returns, front at %.4f m\n", cluster.centre_W.x(),
              cluster.centre_W.y(), cluster.radius_m, cluster.extent_W.size(), front.x());
  auto q = querier();
  // The 0.6 m box centred 0.29 m before the front holds it; 0.31 m before, it does not, but is inside the circle.
  const auto hit = collide(q, front.x() - 0.29, 0.0, {v1::MODEL_PTEM});
  EXPECT_TRUE(hit.hit());
  EXPECT_EQ(hit.model(), v1::MODEL_PTEM);
  const auto short_of = collide(q, front.x() - 0.31, 0.0, {v1::MODEL_PTEM});
  EXPECT_FALSE(short_of.hit());
  EXPECT_TRUE(short_of.keep_out());
  const double gap = 0.5;
  const auto far = clearance(q, front.x() - 0.3 - gap, 0.0, 0.0, {v1::MODEL_PTEM});
  EXPECT_TRUE(far.found());
  EXPECT_EQ(far.model(), v1::MODEL_PTEM);
  EXPECT_NEAR(far.clearance_m(), gap, 1e-3);
  EXPECT_LT(far.restricted_clearance_m(), gap - 0.1);
}

// Ranges of the level laser at (0, 0) heading theta among posts 0.11 m across, some in pairs, and a 6 m wall x = 3.5
// (max range where a beam meets nothing).
std::vector<float> posts_ranges(double theta) {
  const std::vector<Eigen::Vector2d> posts = {{2.0, 0.3},  {2.0, -0.3}, {-1.5, 1.2}, {-1.5, 1.75},
                                              {0.5, -2.5}, {3.0, 2.5},  {-2.5, -1.5}};
  std::vector<float> ranges;
  for (int i = 0; i < 181; ++i) {
    const double a = theta - M_PI / 2 + i * M_PI / 180;
    const Eigen::Vector2d u(std::cos(a), std::sin(a));
    double t = 8.0;
    for (const auto& post : posts) {
      const double b = u.dot(post);
      const double disc = b * b - (post.squaredNorm() - 0.055 * 0.055);
      if (disc >= 0 && b - std::sqrt(disc) > 0.05) t = std::min(t, b - std::sqrt(disc));
    }
    if (u.x() > 1e-9 && std::abs(3.5 / u.x() * u.y()) <= 3.0) t = std::min(t, 3.5 / u.x());
    ranges.push_back(static_cast<float>(t));
  }
  return ranges;
}

TEST_F(ModelsHandlers, DefaultCollisionAndClearanceAnswerAgainstMatterAndReportTheKeepOutBeside) {
  auto session = driver("r1", laser_spec());
  std::uint64_t seq = 0;
  for (int turn = 0; turn < 8; ++turn) {
    const double theta = turn * M_PI / 4;
    const double stamp = 0.1 * (turn + 1);
    handle_odometry(session, odometry(0.0, 0.0, theta, stamp));
    handle_laser_scan(session, scan(++seq, stamp, posts_ranges(theta)));
    expect_ack(*session, seq);
  }
  const WorldSnapshot snapshot = world();
  ASSERT_GT(snapshot.grid->occupied_cell_count(), 0U);
  ASSERT_FALSE(snapshot.ptem->clusters().empty());
  ASSERT_TRUE(snapshot.ptem->restricted_threshold().has_value());
  std::vector<Eigen::Vector2d> cell_centres;
  const double cell = snapshot.grid->cell_size();
  snapshot.grid->for_each_occupied({-1000, -1000}, {1000, 1000}, [&](const geometry::CellIndex& c) {
    cell_centres.emplace_back((c.ix + 0.5) * cell, (c.iy + 0.5) * cell);
    return true;
  });
  // The footprint: a 0.6 m by 0.5 m box, bounding radius ≈ 0.39 m.
  v1::Footprint footprint;
  footprint.mutable_box()->set_length_m(0.6);
  footprint.mutable_box()->set_width_m(0.5);
  footprint.mutable_box()->set_height_m(0.4);
  const double radius = std::hypot(0.3, 0.25);
  auto q = querier();
  std::mt19937 rng(19);
  std::uniform_real_distribution<double> x_of(-3.5, 4.0), y_of(-3.5, 3.5), theta_of(-M_PI, M_PI);
  int tested = 0, keep_out = 0;
  for (int k = 0; k < 400; ++k) {
    const Eigen::Vector2d p(x_of(rng), y_of(rng));
    const double theta = theta_of(rng);
    // Distance from the pose to matter: occupied cells (their corners) and the returns the clusters gathered (their
    // circles reach into the free floor in front of the wall, and are keep-out, not matter).
    double matter_m = std::numeric_limits<double>::infinity();
    for (const auto& c : cell_centres) matter_m = std::min(matter_m, (c - p).norm() - cell * M_SQRT1_2);
    for (const auto& cluster : snapshot.ptem->clusters()) {
      for (const auto& r : cluster.extent_W) matter_m = std::min(matter_m, (r - p).norm());
    }
    // Free and at least one footprint radius clear: the footprint's bounding circle is a radius from everything.
    if (matter_m < 2.0 * radius) continue;
    ++tested;
    v1::CollisionQuery collision;
    collision.set_robot_id("r1");
    collision.mutable_pose()->set_x(p.x());
    collision.mutable_pose()->set_y(p.y());
    collision.mutable_pose()->set_theta(theta);
    *collision.mutable_footprint() = footprint;
    handle_collision_query(q, ++request_id_, collision);
    const auto hit = q->next();
    ASSERT_TRUE(hit && hit->has_collision());
    EXPECT_FALSE(hit->collision().hit()) << "at (" << p.x() << ", " << p.y() << ", " << theta << "), " << matter_m
                                         << " m from matter: " << hit->collision().DebugString();
    v1::ClearanceQuery clearance;
    clearance.set_robot_id("r1");
    *clearance.mutable_pose() = collision.pose();
    *clearance.mutable_footprint() = footprint;
    handle_clearance_query(q, ++request_id_, clearance);
    const auto room = q->next();
    ASSERT_TRUE(room && room->has_clearance());
    // The footprint's points lie within radius of the pose, so matter is at least matter_m - radius away.
    EXPECT_GE(room->clearance().clearance_m(), matter_m - radius - 1e-6)
        << "at (" << p.x() << ", " << p.y() << "): " << room->clearance().DebugString();
    EXPECT_GT(room->clearance().clearance_m(), 0.0);
    EXPECT_TRUE(room->clearance().has_restricted_clearance_m());
    EXPECT_EQ(room->clearance().keep_out(), hit->collision().keep_out());
    if (room->clearance().keep_out()) ++keep_out;
  }
  std::printf("%d free poses tested, %d of them inside the keep-out\n", tested, keep_out);
  EXPECT_GE(tested, 60);
}

TEST_F(ModelsHandlers, UnknownModelsAreRefusedNamingTheField) {
  auto session = driver("r1", laser_spec());
  auto q = querier();
  v1::CollisionQuery collision;
  collision.set_robot_id("r1");
  collision.add_models(v1::MODEL_GRID);
  collision.add_models(static_cast<v1::Model>(9));
  handle_collision_query(q, 3, collision);
  auto reply = q->next();
  ASSERT_TRUE(reply && reply->has_error());
  EXPECT_EQ(reply->error().code(), v1::ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(reply->error().field(), "collision.models[1]");
  EXPECT_EQ(reply->request_id(), 3U);
  v1::ClearanceQuery clearance_query;
  clearance_query.set_robot_id("r1");
  clearance_query.add_models(v1::MODEL_UNSPECIFIED);
  handle_clearance_query(q, 4, clearance_query);
  reply = q->next();
  ASSERT_TRUE(reply && reply->has_error());
  EXPECT_EQ(reply->error().field(), "clearance.models[0]");
}

TEST_F(ModelsHandlers, OctreeRequestExportsTheTreeAsBt) {
  auto session = driver("r1", laser_spec());
  handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
  handle_laser_scan(session, scan(1, 0.1, wall_ranges()));
  expect_ack(*session, 1);
  auto q = querier();
  v1::OctreeRequest request;
  handle_octree_request(q, 5, request);
  const auto reply = q->next();
  ASSERT_TRUE(reply && reply->has_octree()) << (reply ? reply->DebugString() : "no reply");
  const v1::OctreeReply& octree = reply->octree();
  std::printf("exported %zu bytes, %llu nodes, %llu leaves\n", octree.bt().size(),
              static_cast<unsigned long long>(octree.node_count()),
              static_cast<unsigned long long>(octree.leaf_count()));
  EXPECT_EQ(reply->request_id(), 5U);
  EXPECT_EQ(octree.world(), "default");
  EXPECT_EQ(octree.version(), 1U);
  EXPECT_DOUBLE_EQ(octree.resolution_m(), 0.05);
  const auto path = std::filesystem::temp_directory_path() / "models_handler_test.bt";
  std::ofstream(path, std::ios::binary).write(octree.bt().data(), static_cast<std::streamsize>(octree.bt().size()));
  mapping::OctoMapModel loaded(mapping::OctoMapParams{});
  loaded.load_bt(path);
  EXPECT_EQ(loaded.publish()->node_count(), octree.node_count());
  EXPECT_TRUE(loaded.snapshot()->occupied({2.0, 0.0, 0.3}));
  std::filesystem::remove(path);

  request.set_world("nowhere");
  handle_octree_request(q, 5, request);
  const auto error = q->next();
  ASSERT_TRUE(error && error->has_error());
  EXPECT_EQ(error->error().code(), v1::ERROR_UNKNOWN_WORLD);
  EXPECT_EQ(error->error().field(), "octree.world");
}

class SmallOctreeLimit : public ModelsHandlers {
 protected:
  static ServerConfig config() {
    ServerConfig c = test_config();
    c.limits.max_octree_reply_bytes = 64;
    c.octomap.min_publish_interval_s = 0.3;
    return c;
  }
  SmallOctreeLimit() : ModelsHandlers(config()) {}
};

TEST_F(SmallOctreeLimit, OversizedExportIsRefusedAndALaggingOctreeIsPublishedByTheTimer) {
  auto session = driver("r1", laser_spec());
  handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
  handle_laser_scan(session, scan(1, 0.1, wall_ranges()));
  expect_ack(*session, 1);
  handle_laser_scan(session, scan(2, 0.2, wall_ranges()));
  expect_ack(*session, 2);
  // The second scan came within 0.3 s of the first publication: the timer publishes it within the interval.
  const auto start = std::chrono::steady_clock::now();
  while (world().octomap->version() < 2 && std::chrono::steady_clock::now() - start < std::chrono::seconds(3)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const double lag_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("octree snapshot caught up after %.3f s\n", lag_s);
  EXPECT_EQ(world().octomap->version(), 2U);
  EXPECT_LT(lag_s, 1.0);

  auto q = querier();
  v1::OctreeRequest request;
  handle_octree_request(q, 6, request);
  const auto reply = q->next();
  ASSERT_TRUE(reply && reply->has_error()) << (reply ? reply->DebugString() : "no reply");
  EXPECT_EQ(reply->error().field(), "octree.world");
  EXPECT_NE(reply->error().message().find("limits.max_octree_reply_bytes"), std::string::npos);
}

// What the models cost per laser scan on the ingest strand (printed, loosely bounded): 181 beams of 8 m
// in a corridor, the robot advancing 5 cm per scan, with the octree published at every scan (interval 0) or at most
// every 0.2 s (the default).
void measure_ingest(double interval_s) {
  ServerConfig config = test_config();
  config.octomap.min_publish_interval_s = interval_s;
  ServerCore core(config);
  auto session = std::make_shared<FakeSession>(core);
  v1::Hello hello;
  hello.set_protocol_version(proto::kProtocolVersion);
  hello.set_role(v1::ROLE_DRIVER);
  hello.set_robot_id("r1");
  handle_hello(session, hello);
  handle_robot_spec(session, laser_spec());
  ASSERT_TRUE(session->next_of(v1::ServerMessage::kWelcome));
  constexpr int kScans = 200;
  const auto start = std::chrono::steady_clock::now();
  for (int k = 0; k < kScans; ++k) {
    const double x = 0.05 * k;
    handle_odometry(session, odometry(x, 0.0, 0.0, 0.1 * k));
    std::vector<float> ranges;
    for (int i = 0; i < 181; ++i) {  // walls at y = +-1.5 m
      const double a = -M_PI / 2 + i * M_PI / 180;
      const double s = std::abs(std::sin(a));
      ranges.push_back(s > 1.5 / 8.0 ? static_cast<float>(1.5 / s) : 8.0F);
    }
    handle_laser_scan(session, scan(static_cast<std::uint64_t>(k + 1), 0.1 * k + 0.05, ranges));
    ASSERT_TRUE(session->next_of(v1::ServerMessage::kScanAck)) << k;
  }
  const double per_scan_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count() / kScans;
  const auto world = core.world("default")->snapshots();
  std::printf(
      "min_publish_interval_s %.1f: %.3f ms per scan (grid + distance field + octree + PTEM + behaviour), "
      "octree %zu nodes\n",
      interval_s, per_scan_ms, world.octomap->node_count());
  EXPECT_LT(per_scan_ms, 100.0);
}

TEST(ModelsCost, IngestPerScanWithAndWithoutTheOctreeRateLimit) {
  measure_ingest(0.0);
  measure_ingest(0.2);
}

TEST(ModelsConfig, OctomapAndDistanceFieldSectionsAreReadAndChecked) {
  const auto path = std::filesystem::temp_directory_path() / "models_config_test.yaml";
  std::ofstream(path) << "octomap: {resolution_m: 0.1, outlier_mean_k: 8, min_publish_interval_s: 0.5}\n"
                         "distance_field: {max_distance_m: 2.0}\nlimits: {max_octree_reply_bytes: 1000}\n";
  const ServerConfig config = load_config(path);
  EXPECT_DOUBLE_EQ(config.octomap.resolution_m, 0.1);
  EXPECT_EQ(config.octomap.outlier_mean_k, 8);
  EXPECT_DOUBLE_EQ(config.octomap.min_publish_interval_s, 0.5);
  EXPECT_DOUBLE_EQ(config.distance_field.max_distance_m, 2.0);
  EXPECT_EQ(config.limits.max_octree_reply_bytes, 1000U);
  EXPECT_DOUBLE_EQ(ServerConfig{}.distance_field.max_distance_m, 5.0);

  const auto expect_error = [&](const std::string& yaml, const std::string& key) {
    std::ofstream(path) << yaml;
    try {
      load_config(path);
      ADD_FAILURE() << "accepted " << yaml;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  };
  expect_error("octomap: {resolutionm: 0.1}\n", "octomap.resolutionm");
  expect_error("octomap: {resolution_m: 0}\n", "resolution_m");
  expect_error("distance_field: {max_distance_m: -1}\n", "max_distance_m");
  expect_error("limits: {max_octree_reply_bytes: 0}\n", "limits.max_octree_reply_bytes");
  // A send queue smaller than the octree limit stays a valid configuration (the export limit is then half of it).
  std::ofstream(path) << "limits: {max_send_queue_bytes: 4194304}\n";
  EXPECT_NO_THROW(load_config(path));
  std::filesystem::remove(path);
}

// Consistency under load: two query threads read snapshots and ask collision queries while one driver streams 200
// scans. Every state a reader sees is one the driver saw published after a whole scan (grid version, distance-field
// version and PTEM scan count together), the distance field always matches its grid, and versions never go back.
TEST_F(ModelsHandlers, ReadersOnlyEverSeeWholeUpdatesWhileScansStream) {
  constexpr int kScans = 200;
  auto session = driver("r1", laser_spec());
  handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
  using State = std::tuple<std::uint64_t, std::uint64_t, std::uint64_t>;  // grid, distance field, PTEM scans
  const auto state_of = [](const WorldSnapshot& s) {
    return State{s.grid->version(), s.distance->version(), s.ptem->scan_count()};
  };
  std::set<State> published{state_of(world())};
  std::mutex published_mutex;
  std::atomic<bool> streaming{true};

  // Fills `seen`; a void lambda so that ASSERT_* can end it.
  const auto read = [&](int reader, std::vector<State>& seen) {
    auto querier_session = querier();
    std::uint64_t last_grid = 0;
    int collision_replies = 0;
    while (streaming.load() || seen.empty()) {
      const WorldSnapshot s = world();
      seen.push_back(state_of(s));
      EXPECT_GE(s.grid->version(), last_grid);
      last_grid = s.grid->version();
      // The field matches its grid: distance 0 exactly on the occupied cells of a window round the wall.
      for (int ix = 30; ix <= 50; ix += 2) {
        for (int iy = -20; iy <= 20; iy += 4) {
          const geometry::CellIndex cell{ix, iy};
          ASSERT_EQ(s.distance->distance(cell) == 0.0, s.grid->occupied(cell)) << ix << "," << iy;
        }
      }
      v1::CollisionQuery query;
      query.set_robot_id("r1");
      query.mutable_pose()->set_x(1.0);
      handle_collision_query(querier_session, static_cast<std::uint64_t>(reader * 1000000 + collision_replies), query);
      const auto reply = querier_session->next();
      ASSERT_TRUE(reply && reply->has_collision()) << (reply ? reply->DebugString() : "no reply");
      ++collision_replies;
    }
    std::printf("reader %d: %zu snapshots read, %d collision queries answered\n", reader, seen.size(),
                collision_replies);
  };
  std::vector<State> seen_a, seen_b;
  std::thread reader_a([&] { read(0, seen_a); });
  std::thread reader_b([&] { read(1, seen_b); });
  for (int k = 1; k <= kScans; ++k) {
    // A wall 2 m ahead that steps 1 cm closer per scan, so every scan changes the grid.
    std::vector<float> ranges = wall_ranges();
    for (float& r : ranges) r = r < 7.9F ? r * static_cast<float>(1.0 - 0.0025 * (k % 40)) : r;
    handle_laser_scan(session, scan(static_cast<std::uint64_t>(k), 0.1 * k, ranges));
    expect_ack(*session, static_cast<std::uint64_t>(k));
    const std::lock_guard lock(published_mutex);
    published.insert(state_of(world()));
  }
  streaming.store(false);
  reader_a.join();
  reader_b.join();
  EXPECT_EQ(std::get<2>(state_of(world())), static_cast<std::uint64_t>(kScans));
  EXPECT_GT(published.size(), static_cast<std::size_t>(kScans)) << "every scan changes the published state";
  std::set<State> distinct(seen_a.begin(), seen_a.end());
  distinct.insert(seen_b.begin(), seen_b.end());
  std::printf("%zu states published, %zu of them seen by the readers\n", published.size(), distinct.size());
  for (const auto* seen : {&seen_a, &seen_b}) {
    for (const State& state : *seen) {
      EXPECT_TRUE(published.contains(state))
          << "a reader saw grid " << std::get<0>(state) << ", field " << std::get<1>(state) << ", PTEM scans "
          << std::get<2>(state) << ": not a state published after a whole scan";
    }
  }
}

}  // namespace
}  // namespace occgeo::service
