// The pipelined client API against the real server: answers equal the sequential ones, the in-flight bound holds,
// each error reaches the request it answers, and a lost connection completes every outstanding request.
#include <google/protobuf/util/message_differencer.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <thread>

#include "../integration/test_clients.h"
#include "../support/process.h"
#include "occgeo/client/pipeline.h"
#include "occgeo/mapfile/map_file.h"
#include "occgeo/proto/protocol.h"

namespace occgeo::testing {
namespace {

v1::Hello query_hello() {
  v1::Hello hello;
  hello.set_protocol_version(proto::kProtocolVersion);
  hello.set_role(v1::ROLE_QUERY);
  hello.set_client_name("pipeline-test");
  return hello;
}

v1::ClientMessage collision_at(const std::string& robot, double x, double y, double theta) {
  v1::ClientMessage message;
  message.mutable_collision()->set_robot_id(robot);
  message.mutable_collision()->mutable_pose()->set_x(x);
  message.mutable_collision()->mutable_pose()->set_y(y);
  message.mutable_collision()->mutable_pose()->set_theta(theta);
  return message;
}

v1::ClientMessage clearance_at(const std::string& robot, double x, double y, double theta) {
  v1::ClientMessage message;
  message.mutable_clearance()->set_robot_id(robot);
  message.mutable_clearance()->mutable_pose()->set_x(x);
  message.mutable_clearance()->mutable_pose()->set_y(y);
  message.mutable_clearance()->mutable_pose()->set_theta(theta);
  message.mutable_clearance()->set_max_distance_m(3.0);
  return message;
}

class PipelinedConnectionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // The open-field world restored as the default world's grid, and a robot whose footprint the queries use.
    const auto world_dir = dir_.path() / "worlds" / "default";
    std::filesystem::create_directories(world_dir);
    mapfile::write_map(world_dir / "grid", mapfile::read_map_yaml(source("clients/sim/worlds/open_field.yaml")));
    server_ = std::make_unique<ServerProcess>(dir_.path());
    endpoint_ = client::Endpoint::parse(server_->address());
    driver_ = std::make_unique<client::Connection>(open_driver_session(server_->address(), "probe"));
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

  // 1000 collision and clearance queries around the world's obstacles (half of each kind).
  static std::vector<v1::ClientMessage> queries_near_obstacles() {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> coordinate(-29.0, 29.0);
    std::uniform_real_distribution<double> heading(-std::numbers::pi, std::numbers::pi);
    std::vector<v1::ClientMessage> requests;
    for (int i = 0; i < 1000; ++i) {
      const double x = coordinate(rng), y = coordinate(rng), theta = heading(rng);
      requests.push_back(i % 2 == 0 ? collision_at("probe", x, y, theta) : clearance_at("probe", x, y, theta));
    }
    return requests;
  }

  TempDir dir_;
  std::unique_ptr<ServerProcess> server_;
  client::Endpoint endpoint_;
  std::unique_ptr<client::Connection> driver_;
};

TEST_F(PipelinedConnectionTest, PipelinedAnswersEqualSequentialAnswers) {
  const std::vector<v1::ClientMessage> requests = queries_near_obstacles();
  auto sequential = open_query_session(server_->address());
  std::vector<v1::ServerMessage> expected;
  for (std::size_t i = 0; i < requests.size(); ++i) {
    v1::ClientMessage request = requests[i];
    ASSERT_TRUE(client::set_request_id(request, i + 1));
    expected.push_back(sequential.call(request, i + 1));
  }

  auto pipelined = client::PipelinedConnection::open(endpoint_, query_hello(), 32);
  const std::vector<client::Reply> replies = pipelined->run_batch(requests);
  ASSERT_EQ(replies.size(), requests.size());
  int hits = 0;
  for (std::size_t i = 0; i < replies.size(); ++i) {
    ASSERT_TRUE(replies[i].ok()) << i << ": " << replies[i].error_text();
    // A fresh connection numbers its requests 1, 2, 3 ..., as the sequential loop did: the replies must be equal
    // field for field, request_id included.
    EXPECT_EQ(replies[i].request_id, i + 1);
    EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(replies[i].message, expected[i]))
        << "request " << i << "\npipelined: " << replies[i].message.ShortDebugString()
        << "\nsequential: " << expected[i].ShortDebugString();
    if (replies[i].message.has_collision() && replies[i].message.collision().hit()) ++hits;
  }
  // Both answers must occur, or the comparison proves little.
  EXPECT_GT(hits, 10);
  EXPECT_LT(hits, 490);
}

TEST_F(PipelinedConnectionTest, InFlightNeverExceedsTheBound) {
  constexpr std::size_t kDepth = 4;
  auto connection = client::PipelinedConnection::open(endpoint_, query_hello(), kDepth);
  for (std::size_t i = 0; i < kDepth; ++i) connection->submit(collision_at("probe", 0.0, 0.0, 0.0));
  EXPECT_EQ(connection->in_flight(), kDepth);
  EXPECT_FALSE(connection->can_submit());
  EXPECT_THROW(connection->async_submit(collision_at("probe", 0.0, 0.0, 0.0), [](client::Reply&&) {}),
               client::ClientError);
  EXPECT_EQ(connection->wait_all().size(), kDepth);

  // A long batch: at every completion at most kDepth requests were outstanding (this one included).
  std::size_t most_in_flight = 0;
  std::size_t answered = 0;
  std::size_t submitted = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (answered < 500 && std::chrono::steady_clock::now() < deadline) {
    while (submitted < 500 && connection->can_submit()) {
      connection->async_submit(clearance_at("probe", 0.1 * static_cast<double>(submitted % 50), 0.0, 0.0),
                               [&](client::Reply&& reply) {
                                 EXPECT_TRUE(reply.ok()) << reply.error_text();
                                 most_in_flight = std::max(most_in_flight, connection->in_flight() + 1);
                                 ++answered;
                               });
      ++submitted;
      most_in_flight = std::max(most_in_flight, connection->in_flight());
    }
    connection->next(std::chrono::milliseconds(10));  // runs the io_context; the handlers above take the replies
  }
  EXPECT_EQ(answered, 500u);
  EXPECT_EQ(most_in_flight, kDepth);
}

// Requests are filed by request_id in a table of slots twice the depth; a slow batch still unanswered when its slot
// comes round again must keep its own handler, and the fast requests after it theirs.
TEST_F(PipelinedConnectionTest, ASlowBatchOutlastingManyFastQueriesGetsItsOwnAnswer) {
  constexpr std::size_t kDepth = 4;
  constexpr int kPoses = 50000;
  auto connection = client::PipelinedConnection::open(endpoint_, query_hello(), kDepth);
  v1::ClientMessage batch;
  for (int i = 0; i < kPoses; ++i) {
    auto* pose = batch.mutable_collision_batch()->add_poses();
    pose->set_x(-20.0 + 40.0 * i / kPoses);
    pose->set_theta(0.01 * i);
  }
  batch.mutable_collision_batch()->set_robot_id("probe");
  int batch_answers = 0;
  const std::uint64_t batch_id = connection->async_submit(batch, [&](client::Reply&& reply) {
    ++batch_answers;
    ASSERT_TRUE(reply.ok()) << reply.error_text();
    ASSERT_TRUE(reply.message.has_collision_batch()) << reply.message.ShortDebugString();
    EXPECT_EQ(reply.message.collision_batch().results_size(), kPoses);
  });
  std::size_t fast_answers = 0;
  std::size_t submitted = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while ((fast_answers < 200 || batch_answers == 0) && std::chrono::steady_clock::now() < deadline) {
    while (submitted < 200 && connection->can_submit()) {
      const double x = 0.1 * static_cast<double>(submitted % 50);
      connection->async_submit(collision_at("probe", x, 0.0, 0.0), [&](client::Reply&& reply) {
        ASSERT_TRUE(reply.ok()) << reply.error_text();
        EXPECT_TRUE(reply.message.has_collision()) << reply.message.ShortDebugString();
        EXPECT_NE(reply.request_id, batch_id);
        ++fast_answers;
      });
      ++submitted;
    }
    connection->next(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(fast_answers, 200U);
  EXPECT_EQ(batch_answers, 1);
  EXPECT_EQ(connection->in_flight(), 0U);
}

TEST_F(PipelinedConnectionTest, EachErrorReachesTheRequestItAnswers) {
  auto connection = client::PipelinedConnection::open(endpoint_, query_hello(), 16);
  std::vector<v1::ClientMessage> requests;
  for (int i = 0; i < 30; ++i) {
    switch (i % 3) {
      case 0:
        requests.push_back(collision_at("probe", 0.0, 0.0, 0.0));
        break;
      case 1:
        requests.push_back(collision_at("nobody", 0.0, 0.0, 0.0));
        break;
      default:
        requests.push_back(clearance_at("probe", std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0));
        break;
    }
  }
  const std::vector<client::Reply> replies = connection->run_batch(requests);
  for (std::size_t i = 0; i < replies.size(); ++i) {
    const client::Reply& reply = replies[i];
    ASSERT_TRUE(reply.failure.empty()) << reply.failure;
    switch (i % 3) {
      case 0:
        EXPECT_TRUE(reply.ok()) << reply.error_text();
        EXPECT_TRUE(reply.message.has_collision());
        EXPECT_FALSE(reply.message.collision().hit());
        break;
      case 1:
        ASSERT_TRUE(reply.message.has_error()) << reply.message.ShortDebugString();
        EXPECT_EQ(reply.message.error().code(), v1::ERROR_UNKNOWN_ROBOT);
        EXPECT_EQ(reply.message.request_id(), reply.request_id);
        break;
      default:
        ASSERT_TRUE(reply.message.has_error()) << reply.message.ShortDebugString();
        EXPECT_EQ(reply.message.error().code(), v1::ERROR_INVALID_ARGUMENT);
        EXPECT_NE(reply.message.error().field().find("pose"), std::string::npos) << reply.error_text();
        break;
    }
  }
  // The blocking call turns the server's Error into an exception naming it, as Connection::call does.
  try {
    connection->call(collision_at("nobody", 0.0, 0.0, 0.0));
    ADD_FAILURE() << "no exception for an unknown robot";
  } catch (const client::ClientError& error) {
    EXPECT_NE(std::string(error.what()).find("ERROR_UNKNOWN_ROBOT"), std::string::npos) << error.what();
  }
}

TEST_F(PipelinedConnectionTest, LostConnectionCompletesEveryOutstandingRequest) {
  auto connection = client::PipelinedConnection::open(endpoint_, query_hello(), 64);
  ASSERT_TRUE(connection->call(collision_at("probe", 0.0, 0.0, 0.0)).has_collision());
  driver_.reset();
  ASSERT_TRUE(server_->stop().has_value());
  std::size_t failed = 0;
  std::size_t submitted = 0;
  for (int i = 0; i < 64 && connection->healthy(); ++i) {
    try {
      connection->async_submit(collision_at("probe", 0.0, 0.0, 0.0), [&](client::Reply&& reply) {
        EXPECT_FALSE(reply.failure.empty());
        ++failed;
      });
      ++submitted;
    } catch (const client::ClientError&) {
      break;  // the failure was noticed already
    }
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (failed < submitted && std::chrono::steady_clock::now() < deadline)
    connection->next(std::chrono::milliseconds(50));
  EXPECT_EQ(failed, submitted);
  EXPECT_FALSE(connection->healthy());
  EXPECT_THROW(connection->submit(collision_at("probe", 0.0, 0.0, 0.0)), client::ClientError);
}

}  // namespace
}  // namespace occgeo::testing
