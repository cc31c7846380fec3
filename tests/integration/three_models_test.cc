// Three live models per world against the real occgeod: seed 000 Fig 5.2 (a short obstacle and an
// overhang that the Bearcat's planar laser misses, clients/sim/worlds/short_and_overhang.yaml) seen
// by a depth camera into the OctoMap; the `occgeo` CLI's .bt export (read back with OctoMap's own
// reader), .pcd insertion, PTEM query; and the octree surviving a restart through the data dir.
#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "occgeo/client/pipeline.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/proto/protocol.h"
#include "process.h"
#include "temp_dir.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

using namespace std::chrono_literals;

// The shapes of short_and_overhang.yaml (boxes, yaw 0): x range, y half-width, z range.
struct Box {
  double x0, x1, half_width, z0, z1;
};
constexpr Box kShort{1.8, 2.2, 0.5, 0.0, 0.3};
constexpr Box kOverhang{3.8, 4.2, 0.75, 0.9, 2.0};
// A depth camera on the probe, 0.5 m up at the world origin looking along +x: between the short box's top and the
// overhang's underside, so it sees the short box's front and top and the overhang's front and underside.
constexpr double kCameraZ_m = 0.5;
constexpr double kStep_m = 0.025;

// Points of a synthetic depth image of the two boxes and the floor before them, in the camera's frame.
std::vector<float> depth_cloud() {
  std::vector<float> xyz;
  const auto add = [&](double x, double y, double z) {
    xyz.push_back(static_cast<float>(x));
    xyz.push_back(static_cast<float>(y));
    xyz.push_back(static_cast<float>(z - kCameraZ_m));
  };
  const auto face_x = [&](const Box& b, double z0, double z1) {  // the front face x = b.x0
    for (double y = -b.half_width; y <= b.half_width + 1e-9; y += kStep_m) {
      for (double z = z0; z <= z1 + 1e-9; z += kStep_m) add(b.x0, y, z);
    }
  };
  const auto face_z = [&](const Box& b, double z) {  // a horizontal face
    for (double x = b.x0; x <= b.x1 + 1e-9; x += kStep_m) {
      for (double y = -b.half_width; y <= b.half_width + 1e-9; y += kStep_m) add(x, y, z);
    }
  };
  face_x(kShort, 0.0, kShort.z1);
  face_z(kShort, kShort.z1);
  face_x(kOverhang, kOverhang.z0, kOverhang.z1);
  face_z(kOverhang, kOverhang.z0);
  for (double x = 0.6; x <= 1.7 + 1e-9; x += kStep_m) {  // the floor (z = 0): must not count as an obstacle
    for (double y = -0.5; y <= 0.5 + 1e-9; y += kStep_m) add(x, y, 0.0);
  }
  return xyz;
}

v1::ServerMessage wait_for(client::Connection& connection, v1::ServerMessage::BodyCase kind) {
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (std::chrono::steady_clock::now() < deadline) {
    auto message = connection.receive(1000ms);
    if (!message) continue;
    if (message->has_error()) ADD_FAILURE() << message->error().DebugString();
    if (message->body_case() == kind) return *message;
  }
  ADD_FAILURE() << "timed out waiting for message kind " << kind;
  return {};
}

v1::CollisionReply collide(client::Connection& query, std::uint64_t id, double x, v1::Model model) {
  v1::ClientMessage request;
  auto* collision = request.mutable_collision();
  request.set_request_id(id);
  collision->set_robot_id("bearcat");
  collision->mutable_pose()->set_x(x);
  collision->add_models(model);
  return query.call(request, id).collision();
}

v1::WorldStatus world_status(const std::string& address, const std::string& name) {
  auto query = open_query_session(address);
  v1::ClientMessage request;
  request.mutable_status();
  request.set_request_id(1);
  const v1::ServerMessage reply = query.call(request, 1);
  for (const auto& world : reply.status().worlds()) {
    if (world.name() == name) return world;
  }
  ADD_FAILURE() << "no world " << name;
  return {};
}

// The octree config of the scenario: publish every message so the query right after the ack sees the cloud.
std::filesystem::path write_config(const std::filesystem::path& dir) {
  const auto path = dir / "occgeod.yaml";
  std::ofstream(path) << "octomap: {min_publish_interval_s: 0.0}\n";
  return path;
}

TEST(ThreeModels, ShortObstacleAndOverhangAreInTheOctreeButNotTheGrid) {
  TempDir dir;
  std::filesystem::create_directories(dir.path() / "data");
  ServerProcess server(dir.path() / "data", {"--config", write_config(dir.path()).string()});

  // The Bearcat at the origin: its laser plane at 0.6 m passes over the short box and under the overhang, so every
  // beam of its scan is a "no return" (range_max).
  auto bearcat = open_driver_session(server.address(), "bearcat");
  v1::ClientMessage odometry;
  odometry.mutable_odometry()->set_stamp_s(0.0);
  odometry.mutable_odometry()->mutable_pose();
  bearcat.send(odometry);
  const v1::RobotSpec spec = bearcat_spec();
  const auto& laser = spec.sensors(0).laser();
  v1::ClientMessage scan;
  scan.mutable_laser_scan()->set_sensor(spec.sensors(0).name());
  scan.mutable_laser_scan()->set_seq(1);
  scan.mutable_laser_scan()->set_stamp_s(0.1);
  for (std::uint32_t i = 0; i < laser.beam_count(); ++i) {
    scan.mutable_laser_scan()->add_ranges(static_cast<float>(laser.range_max_m()));
  }
  bearcat.send(scan);
  wait_for(bearcat, v1::ServerMessage::kScanAck);

  // A depth-camera probe: a sensor cart 4 cm tall, so that none of its points fall in its own 2D-grid band
  // (0.05 m up to its height) and the grid stays the Bearcat laser's alone.
  auto probe = client::Connection::open(client::Endpoint::parse(server.address()));
  v1::Hello hello;
  hello.set_protocol_version(proto::kProtocolVersion);
  hello.set_role(v1::ROLE_DRIVER);
  hello.set_robot_id("depth-probe");
  probe.hello(hello);
  v1::ClientMessage probe_spec;
  auto* ps = probe_spec.mutable_robot_spec();
  ps->set_model("depth-probe");
  ps->mutable_kinematics()->mutable_differential()->set_wheel_separation_m(0.2);
  ps->mutable_kinematics()->mutable_differential()->set_wheel_radius_m(0.03);
  ps->mutable_kinematics()->mutable_differential()->set_max_wheel_speed_mps(0.1);
  ps->mutable_footprint()->mutable_cylinder()->set_radius_m(0.1);
  ps->mutable_footprint()->mutable_cylinder()->set_height_m(0.04);
  ps->set_command_timeout_s(1.0);
  auto* camera = ps->add_sensors();
  camera->set_name("depth");
  camera->mutable_mount()->mutable_position()->set_z(kCameraZ_m);
  camera->mutable_point_cloud()->set_range_max_m(6.0);
  camera->mutable_point_cloud()->set_max_points(20000);
  probe.send(probe_spec);
  probe.send(odometry);
  v1::ClientMessage cloud;
  cloud.mutable_point_cloud()->set_sensor("depth");
  cloud.mutable_point_cloud()->set_seq(1);
  cloud.mutable_point_cloud()->set_stamp_s(0.1);
  for (const float v : depth_cloud()) cloud.mutable_point_cloud()->add_xyz(v);
  std::printf("depth cloud: %d points\n", cloud.point_cloud().xyz_size() / 3);
  probe.send(cloud);
  wait_for(probe, v1::ServerMessage::kScanAck);

  auto query = open_query_session(server.address());
  std::uint64_t id = 0;
  // The Bearcat's 1.0 x 0.8 x 1.2 m body at x = 1.5 reaches the short box (x 1.8..2.2), at x = 4 the overhang.
  for (const double x : {1.5, 4.0}) {
    const auto grid = collide(query, ++id, x, v1::MODEL_GRID);
    const auto octomap = collide(query, ++id, x, v1::MODEL_OCTOMAP);
    std::printf("bearcat at x = %.1f: grid %s, octomap %s at (%.3f, %.3f, %.3f)\n", x, grid.hit() ? "hit" : "clear",
                octomap.hit() ? "hit" : "clear", octomap.contact().x(), octomap.contact().y(), octomap.contact().z());
    EXPECT_FALSE(grid.hit()) << "the planar laser missed it";
    EXPECT_TRUE(octomap.hit()) << "the depth camera saw it";
    EXPECT_EQ(octomap.model(), v1::MODEL_OCTOMAP);
  }
  const auto overhang = collide(query, ++id, 4.0, v1::MODEL_OCTOMAP);
  EXPECT_GE(overhang.contact().z(), kOverhang.z0 - 0.1);
  EXPECT_LE(overhang.contact().z(), 1.2 + 0.1);
  // Before the short box, on the floor the camera saw: clear in both (the floor band is not an obstacle).
  EXPECT_FALSE(collide(query, ++id, 0.7, v1::MODEL_OCTOMAP).hit());
  EXPECT_FALSE(collide(query, ++id, 0.7, v1::MODEL_GRID).hit());
  // All models at once: the grid is clear, the octree answers.
  v1::ClientMessage all;
  all.set_request_id(++id);
  all.mutable_collision()->set_robot_id("bearcat");
  all.mutable_collision()->mutable_pose()->set_x(4.0);
  const auto reply = query.call(all, id).collision();
  EXPECT_TRUE(reply.hit());
  EXPECT_EQ(reply.model(), v1::MODEL_OCTOMAP);
  EXPECT_EQ(world_status(server.address(), "default").occupied_cells(), 0U);
}

// occgeo map export --format bt, read back by OctoMap's own reader; occgeo cloud insert of a real scan; the octree
// saved in the data dir and restored by the next server.
TEST(ThreeModels, CliExportsTheOctreeAndInsertsAPcdWhichSurvivesARestart) {
  const std::filesystem::path pcd = source("../shared/datasets/pcl-scans/room_scan1.pcd");
  if (!std::filesystem::exists(pcd)) GTEST_SKIP() << "no " << pcd;
  TempDir dir;
  const auto data = dir.path() / "data";
  std::filesystem::create_directories(data);
  std::uint64_t nodes_before = 0;
  std::uint64_t high_nodes = 0;
  {
    ServerProcess server(data);
    const auto inserted = run_process({binary("clients/occgeo").string(), "cloud", "insert", pcd.string(), "--pose",
                                       "0,0,0,0,0,0", "--world", "room", "--server", server.address(), "--json"},
                                      120s);
    std::printf("cloud insert: %s%s", inserted.out.c_str(), inserted.err.c_str());
    ASSERT_EQ(inserted.exit_code, 0) << inserted.err;

    const auto prefix = dir.path() / "room";
    const auto exported = run_process({binary("clients/occgeo").string(), "map", "export", "--format", "bt", "--world",
                                       "room", "--out", prefix.string(), "--server", server.address(), "--json"},
                                      120s);
    std::printf("map export: %s%s", exported.out.c_str(), exported.err.c_str());
    ASSERT_EQ(exported.exit_code, 0) << exported.err;

    // OctoMap's own reader; the node count the server reports.
    octomap::OcTree tree((prefix.string() + ".bt"));
    const v1::WorldStatus status = world_status(server.address(), "room");
    std::printf("read back: %zu nodes, %zu leaves, resolution %.3f; server: %llu nodes\n", tree.size(),
                tree.getNumLeafNodes(), tree.getResolution(), static_cast<unsigned long long>(status.octomap_nodes()));
    EXPECT_GT(tree.size(), 1000U);
    EXPECT_EQ(tree.size(), status.octomap_nodes());
    EXPECT_NE(exported.out.find("\"nodes\":" + std::to_string(tree.size())), std::string::npos) << exported.out;
    nodes_before = tree.size();

    // Every point of the scan (sampled) has an occupied voxel within one voxel of it.
    const auto points = mapping::read_pcd_points(pcd);
    const double r = tree.getResolution();
    std::size_t tested = 0;
    std::size_t near = 0;
    std::size_t beyond_max_range = 0;
    for (std::size_t i = 0; i < points.size(); i += 97) {
      const Eigen::Vector3d p = points[i].cast<double>();
      if (!points[i].allFinite()) continue;
      // A point beyond octomap.max_range_m (10 m) only clears its beam: it cannot have a voxel.
      if (p.norm() > mapping::OctoMapParams{}.max_range_m) {
        ++beyond_max_range;
        continue;
      }
      ++tested;
      bool found = false;
      for (int dx = -1; dx <= 1 && !found; ++dx) {
        for (int dy = -1; dy <= 1 && !found; ++dy) {
          for (int dz = -1; dz <= 1 && !found; ++dz) {
            const octomap::OcTreeNode* node = tree.search(p.x() + dx * r, p.y() + dy * r, p.z() + dz * r);
            found = node != nullptr && tree.isNodeOccupied(node);
          }
        }
      }
      if (found) ++near;
    }
    const double fraction = static_cast<double>(near) / static_cast<double>(tested);
    std::printf(
        "%zu of %zu sampled scan points within 10 m (%.2f%%) have an occupied voxel within one voxel (%zu "
        "sampled beyond 10 m)\n",
        near, tested, 100.0 * fraction, beyond_max_range);
    EXPECT_GT(tested, 1000U);
    // The rest: points the statistical outlier filter (on by default) dropped, and voxels the free rays of the
    // second 100000-point message cleared again.
    EXPECT_GE(fraction, 0.93);

    // The PTEM query from the CLI (no laser in this world: no clusters, nothing restricted).
    const auto ptem = run_process({binary("clients/occgeo").string(), "query", "ptem", "--world", "room", "--x", "1",
                                   "--y", "0", "--server", server.address(), "--json"},
                                  60s);
    std::printf("query ptem: %s", ptem.out.c_str());
    EXPECT_EQ(ptem.exit_code, 0) << ptem.err;
    EXPECT_NE(ptem.out.find("\"restricted\":false"), std::string::npos);
    EXPECT_NE(ptem.out.find("\"world\":\"room\""), std::string::npos);
    // Bad input names the field and changes nothing.
    const auto bad = run_process({binary("clients/occgeo").string(), "cloud", "insert", pcd.string(), "--pose",
                                  "0,0,0,0,0", "--world", "room", "--server", server.address()},
                                 60s);
    EXPECT_EQ(bad.exit_code, 2);
    EXPECT_NE(bad.err.find("--pose"), std::string::npos) << bad.err;
    EXPECT_EQ(world_status(server.address(), "room").octomap_nodes(), nodes_before);

    // A cloud wholly above its robot's 2 m band (the bunny lifted to z = 3 m) reaches the octree but not the grid:
    // the world is saved and restored with its octree alone.
    const std::filesystem::path bunny = source("../shared/datasets/pcl-scans/bun0.pcd");
    if (std::filesystem::exists(bunny)) {
      const auto lifted = run_process({binary("clients/occgeo").string(), "cloud", "insert", bunny.string(), "--pose",
                                       "0,0,3,0,0,0", "--world", "high", "--server", server.address()},
                                      60s);
      EXPECT_EQ(lifted.exit_code, 0) << lifted.err;
      // The octree snapshot may lag by octomap.min_publish_interval_s (0.2 s by default): wait (bounded) for it.
      v1::WorldStatus high = world_status(server.address(), "high");
      for (int i = 0; i < 50 && high.octomap_nodes() == 0; ++i) {
        std::this_thread::sleep_for(100ms);
        high = world_status(server.address(), "high");
      }
      high_nodes = high.octomap_nodes();
      std::printf("bunny at 3 m: %llu octree nodes, %llu grid tiles\n", static_cast<unsigned long long>(high_nodes),
                  static_cast<unsigned long long>(high.tiles()));
      EXPECT_GT(high_nodes, 0U);
      EXPECT_EQ(high.tiles(), 0U);
    }
    ASSERT_EQ(server.stop(), 0);
  }
  ASSERT_TRUE(std::filesystem::exists(data / "worlds" / "room" / "octomap.bt"));
  ServerProcess restarted(data);
  const v1::WorldStatus status = world_status(restarted.address(), "room");
  std::printf("after restart: %llu nodes, %llu leaves\n", static_cast<unsigned long long>(status.octomap_nodes()),
              static_cast<unsigned long long>(status.octomap_leaves()));
  EXPECT_EQ(status.octomap_nodes(), nodes_before);
  if (high_nodes > 0) {
    EXPECT_FALSE(std::filesystem::exists(data / "worlds" / "high" / "grid.yaml"));
    EXPECT_EQ(world_status(restarted.address(), "high").octomap_nodes(), high_nodes);
  }
}

// The client numbers exactly the request kinds (every ClientMessage body from field 10 on, as the schema says): a
// request of each kind gets the id on its envelope, and the messages no reply answers (hello, spec, odometry, sensor
// data) are refused, since a caller waiting for their answer would wait forever.
TEST(ThreeModels, TheClientNumbersEveryRequestKindAndNothingElse) {
  const auto* body = v1::ClientMessage::descriptor()->FindOneofByName("body");
  ASSERT_NE(body, nullptr);
  for (int i = 0; i < body->field_count(); ++i) {
    const auto* field = body->field(i);
    v1::ClientMessage message;
    message.GetReflection()->MutableMessage(&message, field);
    const bool numbered = client::set_request_id(message, 40 + static_cast<std::uint64_t>(i));
    EXPECT_EQ(numbered, field->number() >= 10) << field->name();
    EXPECT_EQ(message.request_id(), numbered ? 40 + static_cast<std::uint64_t>(i) : 0U) << field->name();
  }
  v1::ClientMessage empty;
  EXPECT_FALSE(client::set_request_id(empty, 1));
}

}  // namespace
}  // namespace occgeo::testing
