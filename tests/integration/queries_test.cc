// Collision and clearance queries over the protocol against the true geometry of a world whose
// map the server restored from its data directory.
#include <gtest/gtest.h>

#include <random>
#include <thread>

#include "../support/json_fields.h"
#include "../support/process.h"
#include "../support/world_truth.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

constexpr double kBearcatLength = 1.0;
constexpr double kBearcatWidth = 0.8;

class QueriesOnKnownWorld : public ::testing::Test {
 protected:
  void SetUp() override {
    // A data directory holding the open-field world as the default world's grid: the server
    // restores it at start, so its occupied cells are exactly the world's obstacles.
    const auto world_dir = dir_.path() / "worlds" / "default";
    std::filesystem::create_directories(world_dir);
    auto yaml = mapfile::read_map_yaml(source("clients/sim/worlds/open_field.yaml"));
    mapfile::write_map(world_dir / "grid", yaml);
    server_ = std::make_unique<ServerProcess>(dir_.path());
    driver_ = std::make_unique<client::Connection>(open_driver_session(server_->address(), "probe"));
    truth_ = std::make_unique<WorldTruth>(yaml);
    // The spec is processed asynchronously to the hello; wait (bounded) until the robot is known.
    auto query = open_query_session(server_->address());
    for (int attempt = 0; attempt < 100; ++attempt) {
      v1::ClientMessage request;
      request.mutable_status();
      request.set_request_id(1);
      if (query.call(request, 1).status().robots_size() == 1) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    FAIL() << "robot 'probe' was not registered";
  }

  TempDir dir_;
  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<client::Connection> driver_;
  std::unique_ptr<WorldTruth> truth_;
};

TEST_F(QueriesOnKnownWorld, ClearanceWithinOneCellOfTrueDistanceOverThousandRandomPoses) {
  auto query = open_query_session(server_->address());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(-29.0, 29.0);
  std::uniform_real_distribution<double> heading(-M_PI, M_PI);
  constexpr int kPoses = 1000;
  constexpr double kMaxDistance = 5.0;
  int checked = 0;
  double worst_error = 0.0;
  for (int i = 0; i < kPoses; ++i) {
    const double x = coordinate(rng), y = coordinate(rng), theta = heading(rng);
    v1::ClientMessage request;
    request.set_request_id(static_cast<std::uint64_t>(i + 1));
    auto* clearance = request.mutable_clearance();
    clearance->set_robot_id("probe");
    clearance->mutable_pose()->set_x(x);
    clearance->mutable_pose()->set_y(y);
    clearance->mutable_pose()->set_theta(theta);
    clearance->set_max_distance_m(kMaxDistance);
    const v1::ClearanceReply reply = query.call(request, static_cast<std::uint64_t>(i + 1)).clearance();
    const double truth = std::min(kMaxDistance, truth_->box_distance(x, y, theta, kBearcatLength, kBearcatWidth, 0.0));
    worst_error = std::max(worst_error, std::abs(reply.clearance_m() - truth));
    EXPECT_NEAR(reply.clearance_m(), truth, truth_->cell_size()) << "pose " << x << ", " << y << ", " << theta;
    EXPECT_EQ(reply.found(), truth < kMaxDistance) << "pose " << x << ", " << y << ", " << theta;
    ++checked;
  }
  std::cout << checked << " clearance queries, worst error " << worst_error << " m\n";
}

TEST_F(QueriesOnKnownWorld, CollisionAgreesWithTrueGeometryOverThousandRandomPoses) {
  auto query = open_query_session(server_->address());
  std::mt19937 rng(11);
  // Poses near obstacles are the interesting ones: pick them around random obstacle cells.
  const std::vector<std::pair<int, int>> obstacles(truth_->obstacles().begin(), truth_->obstacles().end());
  std::uniform_int_distribution<std::size_t> pick(0, obstacles.size() - 1);
  std::uniform_real_distribution<double> offset(-1.2, 1.2);
  std::uniform_real_distribution<double> heading(-M_PI, M_PI);
  int hits = 0;
  for (int i = 0; i < 1000; ++i) {
    const auto [ix, iy] = obstacles[pick(rng)];
    const double x = (ix + 0.5) * truth_->cell_size() + offset(rng);
    const double y = (iy + 0.5) * truth_->cell_size() + offset(rng);
    const double theta = heading(rng);
    const double distance = truth_->box_distance(x, y, theta, kBearcatLength, kBearcatWidth, 0.0);
    if (distance > 0.0 && distance < 1e-9) continue;  // touching within rounding: either answer is right
    v1::ClientMessage request;
    request.set_request_id(static_cast<std::uint64_t>(i + 1));
    auto* collision = request.mutable_collision();
    collision->set_robot_id("probe");
    collision->mutable_pose()->set_x(x);
    collision->mutable_pose()->set_y(y);
    collision->mutable_pose()->set_theta(theta);
    const v1::CollisionReply reply = query.call(request, static_cast<std::uint64_t>(i + 1)).collision();
    EXPECT_EQ(reply.hit(), distance == 0.0) << "pose " << x << ", " << y << ", " << theta;
    if (reply.hit()) {
      ++hits;
      EXPECT_TRUE(truth_->obstacles().contains({reply.cell().ix(), reply.cell().iy()}))
          << "the reported cell must be an obstacle";
    }
  }
  std::cout << hits << " of 1000 poses in collision\n";
  EXPECT_GT(hits, 100);
  EXPECT_LT(hits, 900);
}

TEST_F(QueriesOnKnownWorld, CliAnswersCollisionAndClearanceAsJson) {
  const auto cli = [&](const std::vector<std::string>& args) {
    std::vector<std::string> argv = {binary("clients/occgeo").string()};
    argv.insert(argv.end(), args.begin(), args.end());
    argv.insert(argv.end(), {"--server", server_->address(), "--json"});
    return run_process(argv, std::chrono::seconds(30));
  };
  // The fence runs along x = -30..-29.7; a robot centred on it collides, one at the origin does not.
  const ProcessResult on_fence = cli({"query", "collision", "--robot", "probe", "--x", "-29.85", "--y", "0"});
  ASSERT_EQ(on_fence.exit_code, 0) << on_fence.err;
  EXPECT_TRUE(json_bool(on_fence.out, "hit")) << on_fence.out;
  const ProcessResult at_origin = cli({"query", "collision", "--robot", "probe", "--x", "0", "--y", "0"});
  ASSERT_EQ(at_origin.exit_code, 0) << at_origin.err;
  EXPECT_FALSE(json_bool(at_origin.out, "hit")) << at_origin.out;

  const double x = -27.0, y = 0.0;
  const ProcessResult clearance = cli({"query", "clearance", "--robot", "probe", "--x", "-27", "--y", "0"});
  ASSERT_EQ(clearance.exit_code, 0) << clearance.err;
  const double clearance_m = json_number(clearance.out, "clearance_m");
  EXPECT_NEAR(clearance_m, truth_->box_distance(x, y, 0.0, kBearcatLength, kBearcatWidth, 0.0), truth_->cell_size());

  const ProcessResult unknown = cli({"query", "collision", "--robot", "nobody", "--x", "0", "--y", "0"});
  EXPECT_EQ(unknown.exit_code, 1);
  EXPECT_NE(unknown.err.find("ERROR_UNKNOWN_ROBOT"), std::string::npos) << unknown.err;
  EXPECT_NE(unknown.err.find("nobody"), std::string::npos) << unknown.err;

  const ProcessResult status = cli({"status"});
  ASSERT_EQ(status.exit_code, 0) << status.err;
  EXPECT_NE(status.out.find("\"id\":\"probe\""), std::string::npos) << status.out;

  // The common options may also come before the command, as git, kubectl and redis-cli users type them.
  const std::string occgeo = binary("clients/occgeo").string();
  const ProcessResult options_first =
      run_process({occgeo, "--server", server_->address(), "status", "--json"}, std::chrono::seconds(30));
  ASSERT_EQ(options_first.exit_code, 0) << options_first.err;
  EXPECT_NE(options_first.out.find("\"id\":\"probe\""), std::string::npos) << options_first.out;
  const ProcessResult all_first = run_process({occgeo, "--json", "--server=" + server_->address(), "query", "collision",
                                               "--robot", "probe", "--x", "0", "--y", "0"},
                                              std::chrono::seconds(30));
  ASSERT_EQ(all_first.exit_code, 0) << all_first.err;
  EXPECT_FALSE(json_bool(all_first.out, "hit")) << all_first.out;
  // Split around the command, with the command's own flag among them.
  const ProcessResult split = run_process({occgeo, "--json", "status", "--detailed", "--server=" + server_->address()},
                                          std::chrono::seconds(30));
  ASSERT_EQ(split.exit_code, 0) << split.err;
  EXPECT_NE(split.out.find("\"id\":\"probe\""), std::string::npos) << split.out;
  // A bad number is refused before anything is sent, naming the option.
  const ProcessResult bad_number = run_process(
      {occgeo, "--server", server_->address(), "query", "collision", "--robot", "probe", "--x", "abc", "--y", "0"},
      std::chrono::seconds(30));
  EXPECT_EQ(bad_number.exit_code, 2);
  EXPECT_NE(bad_number.err.find("option '--x' needs a number, got 'abc'"), std::string::npos) << bad_number.err;
  // A mistake names itself, wherever the options stand.
  const ProcessResult bad =
      run_process({occgeo, "--server", server_->address(), "status", "--bogus", "1"}, std::chrono::seconds(30));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("unknown option '--bogus'"), std::string::npos) << bad.err;
  const ProcessResult dangling = run_process({occgeo, "--server"}, std::chrono::seconds(30));
  EXPECT_EQ(dangling.exit_code, 2);
  EXPECT_NE(dangling.err.find("'--server' needs a value"), std::string::npos) << dangling.err;
}

TEST_F(QueriesOnKnownWorld, BatchOverLoopbackAnswersLikeSingleQueriesAndTheTrueGeometry) {
  auto query = open_query_session(server_->address());
  std::mt19937 rng(13);
  const std::vector<std::pair<int, int>> obstacles(truth_->obstacles().begin(), truth_->obstacles().end());
  std::uniform_int_distribution<std::size_t> pick(0, obstacles.size() - 1);
  std::uniform_real_distribution<double> offset(-1.5, 1.5);
  std::uniform_real_distribution<double> heading(-M_PI, M_PI);
  v1::ClientMessage batch;
  batch.set_request_id(5000);
  auto* poses = batch.mutable_collision_batch();
  poses->set_robot_id("probe");
  std::vector<double> distances;
  while (poses->poses_size() < 2000) {
    const auto [ix, iy] = obstacles[pick(rng)];
    const double x = (ix + 0.5) * truth_->cell_size() + offset(rng);
    const double y = (iy + 0.5) * truth_->cell_size() + offset(rng);
    const double theta = heading(rng);
    const double distance = truth_->box_distance(x, y, theta, kBearcatLength, kBearcatWidth, 0.0);
    if (distance > 0.0 && distance < 1e-9) continue;  // touching within rounding: either answer is right
    auto* pose = poses->add_poses();
    pose->set_x(x);
    pose->set_y(y);
    pose->set_theta(theta);
    distances.push_back(distance);
  }
  const v1::CollisionBatchReply reply = query.call(batch, 5000).collision_batch();
  ASSERT_EQ(reply.results_size(), 2000);
  std::uint32_t hits = 0;
  for (int i = 0; i < reply.results_size(); ++i) {
    EXPECT_EQ(reply.results(i).hit(), distances[static_cast<std::size_t>(i)] == 0.0) << "pose " << i;
    hits += reply.results(i).hit() ? 1 : 0;
  }
  EXPECT_EQ(reply.hits(), hits);
  // Every 50th pose again as a single query, pipelined on the same connection: the same answer.
  for (int i = 0; i < 2000; i += 50) {
    v1::ClientMessage single;
    single.set_request_id(static_cast<std::uint64_t>(i + 1));
    single.mutable_collision()->set_robot_id("probe");
    *single.mutable_collision()->mutable_pose() = poses->poses(i);
    const v1::CollisionReply one = query.call(single, static_cast<std::uint64_t>(i + 1)).collision();
    EXPECT_EQ(one.SerializeAsString(), reply.results(i).SerializeAsString()) << "pose " << i;
  }
  std::cout << hits << " of 2000 batched poses in collision\n";
  EXPECT_GT(hits, 200U);
}

}  // namespace
}  // namespace occgeo::testing
