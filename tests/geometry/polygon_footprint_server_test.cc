// A robot whose spec declares a convex polygon footprint, on a server that restored a known world: single and batch
// collision and clearance queries over loopback agree with the true geometry and with each other, and the CLI's
// --footprint polygon:... override reaches the server (and a bad outline comes back naming the vertex).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <thread>

#include "../integration/test_clients.h"
#include "../support/json_fields.h"
#include "../support/process.h"
#include "../support/world_truth.h"
#include "occgeo/geometry/convex_polygon.h"
#include "occgeo/proto/protocol.h"

namespace occgeo::testing {
namespace {

// An arrow-shaped pentagon in base_link (metres, counter-clockwise), its tip 0.6 m ahead.
const std::vector<Eigen::Vector2d> kArrow = {{-0.3, -0.35}, {0.2, -0.35}, {0.6, 0.0}, {0.2, 0.35}, {-0.3, 0.35}};
constexpr double kArrowHeight = 0.5;

v1::Footprint arrow_message() {
  v1::Footprint footprint;
  footprint.mutable_polygon()->set_height_m(kArrowHeight);
  for (const Eigen::Vector2d& v : kArrow) {
    auto* vertex = footprint.mutable_polygon()->add_vertices();
    vertex->set_x(v.x());
    vertex->set_y(v.y());
  }
  return footprint;
}

class PolygonRobotOnKnownWorld : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto world_dir = dir_.path() / "worlds" / "default";
    std::filesystem::create_directories(world_dir);
    auto yaml = mapfile::read_map_yaml(source("clients/sim/worlds/open_field.yaml"));
    mapfile::write_map(world_dir / "grid", yaml);
    server_ = std::make_unique<ServerProcess>(dir_.path());
    truth_ = std::make_unique<WorldTruth>(yaml);

    driver_ =
        std::make_unique<client::Connection>(client::Connection::open(client::Endpoint::parse(server_->address())));
    v1::Hello hello;
    hello.set_protocol_version(proto::kProtocolVersion);
    hello.set_role(v1::ROLE_DRIVER);
    hello.set_robot_id("arrow");
    hello.set_client_name("polygon-footprint-test");
    driver_->hello(hello);
    v1::ClientMessage spec;
    *spec.mutable_robot_spec() = bearcat_spec();
    *spec.mutable_robot_spec()->mutable_footprint() = arrow_message();
    driver_->send(spec);
    auto query = open_query_session(server_->address());
    for (int attempt = 0; attempt < 100; ++attempt) {
      v1::ClientMessage request;
      request.mutable_status();
      request.set_request_id(1);
      if (query.call(request, 1).status().robots_size() == 1) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    FAIL() << "robot 'arrow' was not registered";
  }

  // Exact distance from the footprint at (x, y, theta) to the nearest obstacle cell, by brute force; 0 on overlap.
  [[nodiscard]] double true_distance(const std::vector<Eigen::Vector2d>& outline_B, double x, double y,
                                     double theta) const {
    std::vector<Eigen::Vector2d> outline_W;
    const geometry::Pose2 X_WB{x, y, theta};
    for (const Eigen::Vector2d& v : outline_B) outline_W.push_back(X_WB.transform(v));
    const double s = truth_->cell_size();
    double best = 1e300;
    for (const auto& [ix, iy] : truth_->obstacles()) {
      const Eigen::Vector2d center((ix + 0.5) * s, (iy + 0.5) * s);
      if ((center - X_WB.position()).norm() > best + 1.0) continue;
      best = std::min(best, geometry::convex_polygon_square_distance(outline_W, center, s / 2).distance_m);
    }
    return best;
  }

  TempDir dir_;
  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<client::Connection> driver_;
  std::unique_ptr<WorldTruth> truth_;
};

TEST_F(PolygonRobotOnKnownWorld, SingleAndBatchQueriesAgreeWithTheTrueGeometryAndEachOther) {
  auto query = open_query_session(server_->address());
  std::mt19937 rng(17);
  const std::vector<std::pair<int, int>> obstacles(truth_->obstacles().begin(), truth_->obstacles().end());
  std::uniform_int_distribution<std::size_t> pick(0, obstacles.size() - 1);
  std::uniform_real_distribution<double> offset(-1.0, 1.0), heading(-M_PI, M_PI);
  constexpr int kPoses = 500;
  constexpr double kMaxDistance = 2.0;
  v1::ClientMessage collision_batch;
  collision_batch.set_request_id(9000);
  collision_batch.mutable_collision_batch()->set_robot_id("arrow");
  v1::ClientMessage clearance_batch;
  clearance_batch.set_request_id(9001);
  clearance_batch.mutable_clearance_batch()->set_robot_id("arrow");
  clearance_batch.mutable_clearance_batch()->set_max_distance_m(kMaxDistance);
  std::vector<double> distances;
  while (static_cast<int>(distances.size()) < kPoses) {
    const auto [ix, iy] = obstacles[pick(rng)];
    const double x = (ix + 0.5) * truth_->cell_size() + offset(rng);
    const double y = (iy + 0.5) * truth_->cell_size() + offset(rng);
    const double theta = heading(rng);
    const double distance = true_distance(kArrow, x, y, theta);
    if (distance > 0.0 && distance < 1e-9) continue;  // touching within rounding: either answer is right
    distances.push_back(distance);
    for (auto* poses : {collision_batch.mutable_collision_batch()->add_poses(),
                        clearance_batch.mutable_clearance_batch()->add_poses()}) {
      poses->set_x(x);
      poses->set_y(y);
      poses->set_theta(theta);
    }
  }
  const v1::CollisionBatchReply collisions = query.call(collision_batch, 9000).collision_batch();
  const v1::ClearanceBatchReply clearances = query.call(clearance_batch, 9001).clearance_batch();
  ASSERT_EQ(collisions.results_size(), kPoses);
  ASSERT_EQ(clearances.results_size(), kPoses);
  int hits = 0;
  for (int i = 0; i < kPoses; ++i) {
    const double distance = distances[static_cast<std::size_t>(i)];
    const v1::Pose2D& pose = collision_batch.collision_batch().poses(i);
    EXPECT_EQ(collisions.results(i).hit(), distance == 0.0) << "pose " << i;
    hits += collisions.results(i).hit() ? 1 : 0;
    if (distance < kMaxDistance - truth_->cell_size()) {
      EXPECT_TRUE(clearances.results(i).found()) << "pose " << i;
      EXPECT_NEAR(clearances.results(i).clearance_m(), distance, truth_->cell_size()) << "pose " << i;
    }
    if (i % 5 != 0) continue;
    // Every 5th pose again as single queries: the same answers, field for field.
    v1::ClientMessage single;
    single.set_request_id(static_cast<std::uint64_t>(i + 1));
    single.mutable_collision()->set_robot_id("arrow");
    *single.mutable_collision()->mutable_pose() = pose;
    const v1::CollisionReply one = query.call(single, static_cast<std::uint64_t>(i + 1)).collision();
    EXPECT_EQ(one.SerializeAsString(), collisions.results(i).SerializeAsString()) << "pose " << i;
    v1::ClientMessage single_clearance;
    single_clearance.set_request_id(static_cast<std::uint64_t>(i + 1));
    single_clearance.mutable_clearance()->set_robot_id("arrow");
    single_clearance.mutable_clearance()->set_max_distance_m(kMaxDistance);
    *single_clearance.mutable_clearance()->mutable_pose() = pose;
    const v1::ClearanceReply clear = query.call(single_clearance, static_cast<std::uint64_t>(i + 1)).clearance();
    EXPECT_EQ(clear.SerializeAsString(), clearances.results(i).SerializeAsString()) << "pose " << i;
  }
  std::cout << hits << " of " << kPoses << " poses of the polygon robot in collision\n";
  EXPECT_GT(hits, kPoses / 10);
  EXPECT_LT(hits, kPoses * 9 / 10);
}

TEST_F(PolygonRobotOnKnownWorld, CliPolygonOverrideReachesTheServer) {
  const auto cli = [&](const std::vector<std::string>& args) {
    std::vector<std::string> argv = {binary("clients/occgeo").string()};
    argv.insert(argv.end(), args.begin(), args.end());
    argv.insert(argv.end(), {"--server", server_->address(), "--json"});
    return run_process(argv, std::chrono::seconds(30));
  };
  // The fence runs along x = -30..-29.7. A triangle pointing at it from x = -29.2 reaches into it with its tip 0.55 m
  // ahead; 0.45 m stays 5 cm clear.
  const std::string reaching = "polygon:0.5:0.55,0:-0.2,0.2:-0.2,-0.2";
  const std::string short_of = "polygon:0.5:0.45,0:-0.2,0.2:-0.2,-0.2";
  const auto ask = [&](const std::string& footprint) {
    return cli({"query", "collision", "--robot", "arrow", "--x", "-29.2", "--y", "0.05", "--theta", "3.14159265358979",
                "--footprint", footprint});
  };
  const ProcessResult hit = ask(reaching);
  ASSERT_EQ(hit.exit_code, 0) << hit.err;
  EXPECT_TRUE(json_bool(hit.out, "hit")) << hit.out;
  const ProcessResult free = ask(short_of);
  ASSERT_EQ(free.exit_code, 0) << free.err;
  EXPECT_FALSE(json_bool(free.out, "hit")) << free.out;

  const ProcessResult clearance = cli({"query", "clearance", "--robot", "arrow", "--x", "-29.2", "--y", "0.05",
                                       "--theta", "3.14159265358979", "--footprint", short_of});
  ASSERT_EQ(clearance.exit_code, 0) << clearance.err;
  const double clearance_m = json_number(clearance.out, "clearance_m");
  EXPECT_NEAR(clearance_m, 0.05, 1e-6);

  // Driving at 0.5 m/s towards the fence, the 5 cm gap closes after 0.1 s: the swept check reports contact (within
  // 0.005 m, so from 0.09 s) no later than that.
  const ProcessResult swept =
      cli({"query", "swept", "--robot", "arrow", "--x", "-29.2", "--y", "0.05", "--theta", "3.14159265358979", "--v",
           "0.5", "--w", "0", "--duration", "2", "--footprint", short_of});
  ASSERT_EQ(swept.exit_code, 0) << swept.err;
  EXPECT_TRUE(json_bool(swept.out, "hit")) << swept.out;
  const double time_s = json_number(swept.out, "time_s");
  EXPECT_GE(time_s, 0.09 - 1e-6);
  EXPECT_LE(time_s, 0.1 + 1e-6);

  // Vertex 2 dents the outline: refused, naming it.
  const ProcessResult dented = ask("polygon:0.5:0.5,0:-0.2,0.2:0,0:-0.2,-0.2");
  EXPECT_EQ(dented.exit_code, 1);
  EXPECT_NE(dented.err.find("collision.footprint.polygon.vertices[2]"), std::string::npos) << dented.err;
  const ProcessResult malformed = ask("polygon:0.5:0.5,0:oops");
  EXPECT_NE(malformed.exit_code, 0);
  EXPECT_NE(malformed.err.find("--footprint"), std::string::npos) << malformed.err;
}

}  // namespace
}  // namespace occgeo::testing
