// The batch forms of the queries answer exactly like the single forms, entry by entry, on a world mapped by a real
// ServerCore from laser scans (all three models live); bad entries are refused naming the field; and a client that
// follows the grid with GridWindowRequest.since_version ends with the same window as a fresh fetch while scans
// stream in.
#include <google/protobuf/util/message_differencer.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "fake_session.h"
#include "occgeo/proto/protocol.h"
#include "test_robots.h"

namespace occgeo::service {
namespace {

ServerConfig test_config() {
  ServerConfig config;
  config.octomap.min_publish_interval_s = 0.0;
  config.octomap.outlier_filter_enabled = false;
  return config;
}

v1::LaserScan scan(std::uint64_t seq, double stamp, std::mt19937& rng) {
  v1::LaserScan message;
  message.set_sensor("laser");
  message.set_seq(seq);
  message.set_stamp_s(stamp);
  std::uniform_real_distribution<float> range(0.8F, 4.0F);
  float r = range(rng);
  for (int i = 0; i < 181; ++i) {
    if (i % 15 == 0) r = range(rng);  // flat stretches: walls
    message.add_ranges(r);
  }
  return message;
}

v1::Pose2D pose2d(double x, double y, double theta) {
  v1::Pose2D p;
  p.set_x(x);
  p.set_y(y);
  p.set_theta(theta);
  return p;
}

class QueriesBatch : public ::testing::Test {
 protected:
  QueriesBatch() : core_(test_config()) {}

  void SetUp() override {
    driver_ = testing::driver_session(core_, "r1", testing::laser_probe_spec());
    ASSERT_NE(core_.find_robot("r1"), nullptr);
    querier_ = std::make_shared<FakeSession>(core_);
    v1::Hello hello;
    hello.set_protocol_version(proto::kProtocolVersion);
    hello.set_role(v1::ROLE_QUERY);
    handle_hello(querier_, hello);
    ASSERT_TRUE(querier_->next_of(v1::ServerMessage::kWelcome));
  }

  // One scan from pose (x, y, theta), waiting for its ack.
  void map_from(double x, double y, double theta) {
    ++seq_;
    handle_odometry(driver_, testing::odometry(x, y, theta, 0.1 * static_cast<double>(seq_)));
    handle_laser_scan(driver_, scan(seq_, 0.1 * static_cast<double>(seq_) + 0.05, rng_));
    // Acks of scans sent without waiting come first, in order.
    for (int i = 0; i < 10; ++i) {
      const auto ack = driver_->next_of(v1::ServerMessage::kScanAck);
      ASSERT_TRUE(ack) << "no ack of scan " << seq_;
      if (ack->scan_ack().seq() == seq_) return;
    }
    FAIL() << "no ack of scan " << seq_;
  }

  void map_world() {
    for (int i = 0; i < 8; ++i) map_from(0.3 * i, 0.2 * i, i * 0.8);
  }

  // Sends one client message and returns the reply.
  v1::ServerMessage ask(v1::ClientMessage message) {
    dispatch(querier_, std::move(message));
    const auto reply = querier_->next();
    EXPECT_TRUE(reply.has_value()) << "no reply";
    return reply.value_or(v1::ServerMessage{});
  }

  std::vector<v1::Pose2D> random_poses(int n) {
    std::uniform_real_distribution<double> xy(-4.0, 4.0), theta(-M_PI, M_PI);
    std::vector<v1::Pose2D> poses;
    for (int i = 0; i < n; ++i) poses.push_back(pose2d(xy(rng_), xy(rng_), theta(rng_)));
    return poses;
  }

  // A single reply and the batch entry for the same pose are equal, field for field.
  static void expect_same(const google::protobuf::Message& single, const google::protobuf::Message& batch, int index) {
    EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(single, batch))
        << "entry " << index << "\nsingle: " << single.ShortDebugString() << "\nbatch:  " << batch.ShortDebugString();
  }

  ServerCore core_;
  std::shared_ptr<FakeSession> driver_;
  std::shared_ptr<FakeSession> querier_;
  std::mt19937 rng_{7};
  std::uint64_t seq_ = 0;
};

TEST_F(QueriesBatch, CollisionAndClearanceBatchesAnswerLikeSingleQueries) {
  map_world();
  const auto poses = random_poses(150);
  v1::ClientMessage collision_batch;
  collision_batch.set_request_id(1000);
  auto* cb = collision_batch.mutable_collision_batch();
  cb->set_robot_id("r1");
  v1::ClientMessage clearance_batch;
  clearance_batch.set_request_id(1001);
  auto* kb = clearance_batch.mutable_clearance_batch();
  kb->set_robot_id("r1");
  kb->set_max_distance_m(1.5);
  for (const auto& p : poses) {
    *cb->add_poses() = p;
    *kb->add_poses() = p;
  }
  const v1::ServerMessage collisions = ask(collision_batch);
  ASSERT_TRUE(collisions.has_collision_batch()) << collisions.ShortDebugString();
  ASSERT_EQ(collisions.request_id(), 1000U);
  ASSERT_EQ(collisions.collision_batch().results_size(), 150);
  const v1::ServerMessage clearances = ask(clearance_batch);
  ASSERT_TRUE(clearances.has_clearance_batch()) << clearances.ShortDebugString();
  ASSERT_EQ(clearances.clearance_batch().results_size(), 150);
  int hits = 0;
  for (int i = 0; i < 150; ++i) {
    v1::ClientMessage single;
    single.set_request_id(static_cast<std::uint64_t>(i + 1));
    single.mutable_collision()->set_robot_id("r1");
    *single.mutable_collision()->mutable_pose() = poses[static_cast<std::size_t>(i)];
    v1::ServerMessage reply = ask(single);
    ASSERT_TRUE(reply.has_collision());
    hits += reply.collision().hit() ? 1 : 0;
    expect_same(reply.collision(), collisions.collision_batch().results(i), i);

    v1::ClientMessage clearance;
    clearance.set_request_id(static_cast<std::uint64_t>(i + 1));
    clearance.mutable_clearance()->set_robot_id("r1");
    clearance.mutable_clearance()->set_max_distance_m(1.5);
    *clearance.mutable_clearance()->mutable_pose() = poses[static_cast<std::size_t>(i)];
    reply = ask(clearance);
    ASSERT_TRUE(reply.has_clearance());
    expect_same(reply.clearance(), clearances.clearance_batch().results(i), i);
  }
  EXPECT_EQ(collisions.collision_batch().hits(), static_cast<std::uint32_t>(hits));
  EXPECT_GT(hits, 0);
  EXPECT_LT(hits, 150);
}

TEST_F(QueriesBatch, RaycastOccupancyAndSweptListsAnswerLikeOneEntryEach) {
  map_world();
  const auto poses = random_poses(60);
  v1::ClientMessage rays;
  rays.set_request_id(1);
  rays.mutable_raycast()->set_max_range_m(6.0);
  v1::ClientMessage points;
  points.set_request_id(2);
  v1::ClientMessage motions;
  motions.set_request_id(3);
  motions.mutable_swept()->set_robot_id("r1");
  for (const auto& p : poses) {
    *rays.mutable_raycast()->add_rays() = p;
    auto* point = points.mutable_occupancy()->add_points();
    point->set_x(p.x());
    point->set_y(p.y());
    point->set_z(0.3);
    auto* motion = motions.mutable_swept()->add_motions();
    *motion->mutable_start() = p;
    motion->set_linear_mps(0.4);
    motion->set_angular_radps(0.3);
    motion->set_duration_s(2.0);
  }
  const v1::ServerMessage all_rays = ask(rays);
  const v1::ServerMessage all_points = ask(points);
  const v1::ServerMessage all_motions = ask(motions);
  ASSERT_EQ(all_rays.raycast().results_size(), 60) << all_rays.ShortDebugString();
  ASSERT_EQ(all_points.occupancy().samples_size(), 60) << all_points.ShortDebugString();
  ASSERT_EQ(all_motions.swept().results_size(), 60) << all_motions.ShortDebugString();
  int ray_hits = 0, swept_hits = 0;
  for (int i = 0; i < 60; ++i) {
    v1::ClientMessage one = rays;
    one.mutable_raycast()->clear_rays();
    *one.mutable_raycast()->add_rays() = poses[static_cast<std::size_t>(i)];
    v1::ServerMessage reply = ask(one);
    ASSERT_EQ(reply.raycast().results_size(), 1);
    expect_same(reply.raycast().results(0), all_rays.raycast().results(i), i);
    ray_hits += reply.raycast().results(0).hit() ? 1 : 0;
    ASSERT_EQ(reply.raycast().results(0).per_model_size(), 3) << "all three models by default";

    one = points;
    one.mutable_occupancy()->clear_points();
    *one.mutable_occupancy()->add_points() = points.occupancy().points(i);
    reply = ask(one);
    ASSERT_EQ(reply.occupancy().samples_size(), 1);
    expect_same(reply.occupancy().samples(0), all_points.occupancy().samples(i), i);

    one = motions;
    one.mutable_swept()->clear_motions();
    *one.mutable_swept()->add_motions() = motions.swept().motions(i);
    reply = ask(one);
    ASSERT_EQ(reply.swept().results_size(), 1);
    expect_same(reply.swept().results(0), all_motions.swept().results(i), i);
    swept_hits += reply.swept().results(0).hit() ? 1 : 0;
  }
  EXPECT_GT(ray_hits, 0);
  EXPECT_GT(swept_hits, 0);
}

TEST_F(QueriesBatch, BadEntriesAreRefusedNamingTheField) {
  map_world();
  v1::ClientMessage message;
  message.set_request_id(5);
  auto* batch = message.mutable_collision_batch();
  batch->set_robot_id("r1");
  *batch->add_poses() = pose2d(0, 0, 0);
  *batch->add_poses() = pose2d(std::nan(""), 0, 0);
  v1::ServerMessage reply = ask(message);
  ASSERT_TRUE(reply.has_error());
  EXPECT_EQ(reply.error().code(), v1::ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(reply.error().field().rfind("collision_batch.poses[1]", 0), 0U) << reply.error().field();
  EXPECT_EQ(reply.request_id(), 5U);

  message.Clear();
  message.set_request_id(6);
  *message.mutable_raycast()->add_rays() = pose2d(0, 0, 0);
  reply = ask(message);
  ASSERT_TRUE(reply.has_error());
  EXPECT_EQ(reply.error().field(), "raycast.max_range_m");

  message.Clear();
  message.set_request_id(7);
  message.mutable_clearance_batch()->set_robot_id("r1");
  reply = ask(message);
  ASSERT_TRUE(reply.has_error());
  EXPECT_EQ(reply.error().field(), "clearance_batch.poses");

  message.Clear();
  message.set_request_id(8);
  auto* swept = message.mutable_swept();
  swept->set_robot_id("r1");
  swept->add_motions()->set_duration_s(-1.0);
  reply = ask(message);
  ASSERT_TRUE(reply.has_error());
  EXPECT_EQ(reply.error().field(), "swept.motions[0].duration_s");

  message.Clear();
  message.set_request_id(9);
  auto* window = message.mutable_grid_window();
  window->mutable_min_corner()->set_x(1.0);
  window->mutable_max_corner()->set_x(0.0);
  reply = ask(message);
  ASSERT_TRUE(reply.has_error());
  EXPECT_EQ(reply.error().field(), "grid_window.max_corner");
}

// Applies a GridWindowReply to a client's copy of the window.
void apply(const v1::GridWindowReply& reply, std::vector<std::uint8_t>& copy) {
  if (!reply.cells().empty()) {
    copy.assign(reply.cells().begin(), reply.cells().end());
    return;
  }
  for (const v1::GridBlock& block : reply.changed()) {
    for (std::uint32_t y = 0; y < block.height(); ++y) {
      const auto row = static_cast<std::size_t>(block.min_cell().iy() - reply.min_cell().iy()) + y;
      const auto column = static_cast<std::size_t>(block.min_cell().ix() - reply.min_cell().ix());
      std::copy_n(block.cells().begin() + static_cast<std::ptrdiff_t>(y * block.width()), block.width(),
                  copy.begin() + static_cast<std::ptrdiff_t>(row * reply.width() + column));
    }
  }
}

TEST_F(QueriesBatch, AFollowerPatchedWithChangesMatchesAFreshWindowWhileScansStream) {
  map_from(0.0, 0.0, 0.0);
  v1::ClientMessage request;
  request.set_request_id(1);
  auto* window = request.mutable_grid_window();
  window->mutable_min_corner()->set_x(-3.0);
  window->mutable_min_corner()->set_y(-2.5);
  window->mutable_max_corner()->set_x(9.0);
  window->mutable_max_corner()->set_y(4.0);
  v1::ServerMessage reply = ask(request);
  ASSERT_TRUE(reply.has_grid_window()) << reply.ShortDebugString();
  std::vector<std::uint8_t> copy;
  apply(reply.grid_window(), copy);
  ASSERT_EQ(copy.size(), static_cast<std::size_t>(reply.grid_window().width()) * reply.grid_window().height());
  std::uint64_t version = reply.grid_window().version();
  std::size_t blocks = 0;
  std::size_t cells_sent = 0;
  for (int round = 0; round < 30; ++round) {
    // Scans stream in between (and while) the follower catches up.
    map_from(0.2 * round, 0.1 * (round % 5), 0.4 * round);
    if (round % 3 == 0) {
      ++seq_;
      handle_laser_scan(driver_, scan(seq_, 0.1 * static_cast<double>(seq_) + 0.05, rng_));
    }
    window->set_since_version(version);
    reply = ask(request);
    ASSERT_TRUE(reply.has_grid_window()) << reply.ShortDebugString();
    ASSERT_TRUE(reply.grid_window().cells().empty()) << "a follower is sent changes only";
    apply(reply.grid_window(), copy);
    blocks += static_cast<std::size_t>(reply.grid_window().changed_size());
    for (const auto& block : reply.grid_window().changed()) cells_sent += block.cells().size();
    version = reply.grid_window().version();
    // A fresh fetch at the same version (nothing is ingested between the two requests unless a scan is queued).
    v1::ClientMessage fresh = request;
    fresh.mutable_grid_window()->set_since_version(0);
    const v1::ServerMessage full = ask(fresh);
    if (full.grid_window().version() == version) {
      ASSERT_EQ(copy, std::vector<std::uint8_t>(full.grid_window().cells().begin(), full.grid_window().cells().end()))
          << "round " << round;
    }
  }
  // Once every scan is in, compare at rest.
  map_from(1.0, 1.0, 1.0);
  window->set_since_version(version);
  reply = ask(request);
  apply(reply.grid_window(), copy);
  v1::ClientMessage fresh = request;
  fresh.mutable_grid_window()->set_since_version(0);
  const v1::ServerMessage full = ask(fresh);
  ASSERT_EQ(full.grid_window().version(), reply.grid_window().version());
  EXPECT_EQ(copy, std::vector<std::uint8_t>(full.grid_window().cells().begin(), full.grid_window().cells().end()));
  EXPECT_GT(blocks, 0U);
  EXPECT_LT(cells_sent, 30 * copy.size()) << "changes cost less than refetching";
}

TEST_F(QueriesBatch, OctreeWindowListsTheOccupiedVoxelsInTheBox) {
  map_world();
  v1::ClientMessage request;
  request.set_request_id(3);
  auto* window = request.mutable_octree_window();
  window->mutable_min_corner()->set_x(-5);
  window->mutable_min_corner()->set_y(-5);
  window->mutable_min_corner()->set_z(0);
  window->mutable_max_corner()->set_x(5);
  window->mutable_max_corner()->set_y(5);
  window->mutable_max_corner()->set_z(1);
  const v1::ServerMessage reply = ask(request);
  ASSERT_TRUE(reply.has_octree_window()) << reply.ShortDebugString();
  ASSERT_GT(reply.octree_window().voxels_size(), 0);
  const auto octomap = core_.world("default")->snapshots().octomap;
  for (const auto& voxel : reply.octree_window().voxels()) {
    EXPECT_TRUE(octomap->occupied({voxel.center().x(), voxel.center().y(), voxel.center().z()}));
    EXPECT_LE(std::abs(voxel.center().x()), 5.0 + voxel.size_m());
  }
}

// Every kind a session counts against limits.max_pending_requests is answered by exactly one message that the session
// counts as an answer, so a session can never stall with requests it believes unanswered; and every query kind,
// batch and window forms included, is counted (the ClientMessage and ServerMessage bodies share field numbers and
// names for a request and its reply). Leases, drive, e-stop and watch are control messages answered on the robot's
// strand and are not counted.
TEST_F(QueriesBatch, EveryQueryKindIsARequestAnsweredByExactlyOneAnswer) {
  map_world();
  const auto* client_body = v1::ClientMessage::descriptor()->FindOneofByName("body");
  const auto* server = v1::ServerMessage::descriptor();
  const std::set<std::string> control = {"lease", "drive", "estop", "watch"};
  int requests = 0;
  for (int i = 0; i < client_body->field_count(); ++i) {
    const auto* field = client_body->field(i);
    const auto kind = static_cast<v1::ClientMessage::BodyCase>(field->number());
    const auto* reply_field = server->FindFieldByNumber(field->number());
    const bool query =
        reply_field != nullptr && reply_field->name() == field->name() && !control.contains(field->name());
    EXPECT_EQ(is_request(kind), query) << field->name();
    if (!query) continue;
    ++requests;
    EXPECT_TRUE(is_answer(static_cast<v1::ServerMessage::BodyCase>(reply_field->number()))) << reply_field->name();

    // An empty request of this kind (refused or answered) gets exactly one answer, carrying its request_id on the
    // envelope.
    v1::ClientMessage message;
    message.GetReflection()->MutableMessage(&message, field);
    message.set_request_id(40 + static_cast<std::uint64_t>(i));
    dispatch(querier_, std::move(message));
    const auto answer = querier_->next();
    ASSERT_TRUE(answer) << field->name() << " got no answer";
    EXPECT_TRUE(is_answer(answer->body_case())) << answer->ShortDebugString();
    // A second answer to an earlier kind would arrive here first, with that kind's request_id.
    EXPECT_EQ(answer->request_id(), 40 + static_cast<std::uint64_t>(i))
        << field->name() << ": " << answer->ShortDebugString();
  }
  core_.drain();
  EXPECT_TRUE(querier_->take_all().empty()) << "the last kind got more than one answer";
  EXPECT_EQ(requests, 13);
  EXPECT_TRUE(is_answer(v1::ServerMessage::kError));
  for (const auto kind : {v1::ClientMessage::kHello, v1::ClientMessage::kLaserScan, v1::ClientMessage::kOdometry,
                          v1::ClientMessage::kPointCloud, v1::ClientMessage::kLease, v1::ClientMessage::kWatch}) {
    EXPECT_FALSE(is_request(kind)) << kind;
  }
  for (const auto kind : {v1::ServerMessage::kWelcome, v1::ServerMessage::kScanAck, v1::ServerMessage::kMotionCommand,
                          v1::ServerMessage::kWatchEvent}) {
    EXPECT_FALSE(is_answer(kind)) << kind;
  }
}

// Protocol version 2 carries request_id on the envelope: ClientMessage and ServerMessage each have request_id = 9
// outside their body, no body message has a request_id of its own, and every ClientMessage kind numbered 10 or more is
// a request answered by the ServerMessage kind of the same number and name (or an Error).
TEST(EnvelopeSchema, RequestIdIsOnTheEnvelopeAndEveryRequestKindHasItsReply) {
  for (const auto* envelope : {v1::ClientMessage::descriptor(), v1::ServerMessage::descriptor()}) {
    const auto* request_id = envelope->FindFieldByName("request_id");
    ASSERT_NE(request_id, nullptr) << envelope->full_name();
    EXPECT_EQ(request_id->number(), 9) << envelope->full_name();
    EXPECT_EQ(request_id->type(), google::protobuf::FieldDescriptor::TYPE_UINT64) << envelope->full_name();
    EXPECT_EQ(request_id->containing_oneof(), nullptr) << envelope->full_name();
    const auto* body = envelope->FindOneofByName("body");
    ASSERT_NE(body, nullptr) << envelope->full_name();
    for (int i = 0; i < body->field_count(); ++i) {
      const auto* field = body->field(i);
      ASSERT_NE(field->message_type(), nullptr) << field->full_name();
      EXPECT_EQ(field->message_type()->FindFieldByName("request_id"), nullptr)
          << field->full_name() << " (" << field->message_type()->full_name() << ") still has a request_id";
    }
  }

  const auto* client_body = v1::ClientMessage::descriptor()->FindOneofByName("body");
  const auto* server_body = v1::ServerMessage::descriptor()->FindOneofByName("body");
  int requests = 0;
  for (int i = 0; i < client_body->field_count(); ++i) {
    const auto* field = client_body->field(i);
    if (field->number() < 10) continue;  // hello, robot_spec and sensor data: not requests
    ++requests;
    const auto* reply = v1::ServerMessage::descriptor()->FindFieldByNumber(field->number());
    ASSERT_NE(reply, nullptr) << field->name() << " (" << field->number() << ") has no reply kind";
    EXPECT_EQ(reply->name(), field->name()) << "field " << field->number();
    EXPECT_EQ(reply->containing_oneof(), server_body) << reply->full_name();
  }
  EXPECT_GT(requests, 0);
}

}  // namespace
}  // namespace occgeo::service
