// Each protocol handler against a fake session and a real ServerCore (no sockets).
#include <gtest/gtest.h>

#include <cmath>
#include <future>

#include "fake_session.h"
#include "handlers/robot_control.h"
#include "occgeo/proto/labels.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/presets.h"
#include "test_robots.h"

namespace occgeo::service {
namespace {

// The Bearcat as the simulator describes it: 1.0 x 0.8 m box, LMS200 0.45 m ahead of base_link.
v1::RobotSpec bearcat_spec() { return sim::make_robot_spec(*sim::find_robot_preset("bearcat")); }

using testing::odometry;

class Handlers : public ::testing::Test {
 protected:
  Handlers() : core_(ServerConfig{}) {}

  std::shared_ptr<FakeSession> driver(const std::string& robot_id) {
    return testing::driver_session(core_, robot_id, bearcat_spec());
  }

  // A Bearcat driver at the origin whose one scan (every beam 3 m) has been mapped and answered.
  std::shared_ptr<FakeSession> driver_that_mapped_an_arc(const std::string& robot_id) {
    auto session = driver(robot_id);
    handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
    handle_laser_scan(session, scan(1, 0.1, 3.0F));
    EXPECT_TRUE(session->take_first_of(v1::ServerMessage::kMotionCommand));
    // The ack, not the command, says the scan is in the published models: the command leaves before the publication.
    EXPECT_TRUE(session->take_first_of(v1::ServerMessage::kScanAck));
    return session;
  }

  // A welcomed query client.
  std::shared_ptr<FakeSession> query_client() {
    auto session = std::make_shared<FakeSession>(core_);
    handle_hello(session, testing::hello_message(v1::ROLE_QUERY));
    EXPECT_TRUE(session->next_of(v1::ServerMessage::kWelcome));
    return session;
  }

  static v1::LaserScan scan(std::uint64_t seq, double stamp, float range) {
    v1::LaserScan message;
    message.set_sensor("front_laser");
    message.set_seq(seq);
    message.set_stamp_s(stamp);
    for (int i = 0; i < 181; ++i) message.add_ranges(range);
    return message;
  }

  ServerCore core_;
};

TEST_F(Handlers, HelloChecksVersionRoleAndRobotName) {
  auto session = std::make_shared<FakeSession>(core_);
  auto wrong = testing::hello_message(v1::ROLE_QUERY);
  wrong.set_protocol_version(1);
  handle_hello(session, wrong);
  auto reply = session->next();
  ASSERT_TRUE(reply && reply->has_error());
  EXPECT_EQ(reply->error().field(), "hello.protocol_version");

  handle_hello(session, testing::hello_message(v1::ROLE_DRIVER, "no spaces allowed"));
  reply = session->next();
  ASSERT_TRUE(reply && reply->has_error());
  EXPECT_EQ(reply->error().field(), "hello.robot_id");

  handle_hello(session, testing::hello_message(v1::ROLE_UNSPECIFIED));
  reply = session->next();
  ASSERT_TRUE(reply && reply->has_error());
  EXPECT_EQ(reply->error().code(), v1::ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(reply->error().field(), "hello.role");

  handle_hello(session, testing::hello_message(v1::ROLE_QUERY));
  reply = session->next();
  ASSERT_TRUE(reply && reply->has_welcome());
  EXPECT_EQ(reply->welcome().protocol_version(), proto::kProtocolVersion);
  EXPECT_TRUE(session->info().greeted);
}

// A version 1 client (request_id inside each body) is refused at hello and told why, before it sends a request whose
// id the server would not see.
TEST_F(Handlers, HelloOfProtocolVersionOneIsRefusedNamingTheEnvelope) {
  auto session = std::make_shared<FakeSession>(core_);
  auto old = testing::hello_message(v1::ROLE_QUERY);
  old.set_protocol_version(1);
  handle_hello(session, old);
  const auto reply = session->next();
  ASSERT_TRUE(reply && reply->has_error());
  EXPECT_EQ(reply->error().code(), v1::ERROR_PROTOCOL_VERSION);
  EXPECT_EQ(reply->error().field(), "hello.protocol_version");
  EXPECT_NE(reply->error().message().find("version 2"), std::string::npos) << reply->error().message();
  EXPECT_NE(reply->error().message().find("request_id"), std::string::npos) << reply->error().message();
  EXPECT_EQ(reply->request_id(), 0U) << "a hello is no request";
  EXPECT_FALSE(session->info().greeted);
}

TEST_F(Handlers, DispatchRequiresHelloFirstAndDriverRoleForRobotData) {
  auto session = std::make_shared<FakeSession>(core_);
  v1::ClientMessage status;
  status.mutable_status();
  status.set_request_id(1);
  dispatch(session, status);
  auto reply = session->next();
  ASSERT_TRUE(reply && reply->has_error());
  EXPECT_EQ(reply->error().code(), v1::ERROR_OUT_OF_ORDER);

  handle_hello(session, testing::hello_message(v1::ROLE_QUERY));
  ASSERT_TRUE(session->next_of(v1::ServerMessage::kWelcome));
  v1::ClientMessage data;
  *data.mutable_laser_scan() = scan(1, 0.0, 1.0F);
  dispatch(session, data);
  reply = session->next();
  ASSERT_TRUE(reply && reply->has_error());
  EXPECT_EQ(reply->error().code(), v1::ERROR_NOT_ALLOWED);
  EXPECT_EQ(reply->error().field(), "laser_scan");
}

TEST_F(Handlers, RobotSpecErrorsNameTheField) {
  auto session = std::make_shared<FakeSession>(core_);
  handle_hello(session, testing::hello_message(v1::ROLE_DRIVER, "r1"));
  ASSERT_TRUE(session->next_of(v1::ServerMessage::kWelcome));
  struct Case {
    std::function<void(v1::RobotSpec&)> damage;
    std::string field;
  };
  const std::vector<Case> cases = {
      {[](v1::RobotSpec& s) { s.mutable_footprint()->mutable_box()->set_width_m(-1); },
       "robot_spec.footprint.box.width_m"},
      {[](v1::RobotSpec& s) { s.clear_sensors(); }, "robot_spec.sensors"},
      {[](v1::RobotSpec& s) { s.mutable_sensors(0)->mutable_laser()->set_beam_count(0); },
       "robot_spec.sensors[0].laser.beam_count"},
      {[](v1::RobotSpec& s) { s.mutable_sensors(0)->mutable_laser()->set_range_max_m(NAN); },
       "robot_spec.sensors[0].laser.range_max_m"},
      {[](v1::RobotSpec& s) { s.mutable_kinematics()->clear_differential(); }, "robot_spec.kinematics"},
      // A kilometre-long beam would sweep (and allocate) far more map than any sensor sees.
      {[](v1::RobotSpec& s) { s.mutable_sensors(0)->mutable_laser()->set_range_max_m(1000.0); },
       "robot_spec.sensors[0].laser.range_max_m"},
  };
  for (const auto& c : cases) {
    auto spec = bearcat_spec();
    c.damage(spec);
    handle_robot_spec(session, spec);
    const auto reply = session->next();
    ASSERT_TRUE(reply && reply->has_error()) << c.field;
    EXPECT_EQ(reply->error().field(), c.field);
  }
  EXPECT_EQ(core_.find_robot("r1"), nullptr) << "a rejected spec registers nothing";
}

TEST_F(Handlers, ScanBeforeOdometryIsRejectedAndLeavesTheMapAlone) {
  auto session = driver("r1");
  handle_laser_scan(session, scan(1, 0.0, 2.0F));
  const auto reply = session->next_of(v1::ServerMessage::kError);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->error().code(), v1::ERROR_OUT_OF_ORDER);
  core_.drain();
  EXPECT_EQ(core_.world("default")->snapshot()->version(), 0U);
}

// A scan's ack is registered after its publication, off the world strand; the rejection of the next message (seq not
// increased) is decided on the strand at once, and must still reach the driver after that ack.
TEST_F(Handlers, ARejectionNeverOvertakesTheAckOfTheScanBeforeIt) {
  auto session = driver("r1");
  handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
  for (std::uint64_t seq = 1; seq <= 20; ++seq) {
    handle_laser_scan(session, scan(seq, 0.1 * static_cast<double>(seq), 2.0F + 0.05F * static_cast<float>(seq)));
    handle_laser_scan(session, scan(seq, 0.1 * static_cast<double>(seq) + 0.01, 1.5F));  // same seq, other ranges
    std::vector<v1::ServerMessage::BodyCase> replies;
    for (int i = 0; i < 3 && replies.size() < 2; ++i) {
      const auto reply = session->next();
      ASSERT_TRUE(reply) << "scan " << seq;
      if (reply->has_scan_ack() || reply->has_error()) replies.push_back(reply->body_case());
    }
    ASSERT_EQ(replies.size(), 2U) << "scan " << seq;
    EXPECT_EQ(replies[0], v1::ServerMessage::kScanAck) << "scan " << seq;
    EXPECT_EQ(replies[1], v1::ServerMessage::kError) << "scan " << seq;
  }
}

// A publish lane that falls behind (here held up on purpose) publishes the scans it missed in one publication, whose
// distance field is the one the published grid has, and still acks each scan, in order, after it.
TEST_F(Handlers, ScansAPublishLaneFellBehindOnArePublishedTogetherAndEachIsAckedAfterIt) {
  auto session = driver("r1");
  handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
  const auto world = core_.world("default");
  const auto wait_on = [](auto post) {
    std::promise<void> done;
    post([&done] { done.set_value(); });
    done.get_future().wait();
  };
  // Everything the odometry started has run: on the strand, then on the publish lane.
  wait_on([&world](auto job) { asio::post(world->strand(), std::move(job)); });
  wait_on([&world](auto job) { world->after_publications_on_strand(std::move(job)); });

  std::promise<void> lane_blocked;
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  world->after_publications_on_strand([&lane_blocked, released] {
    lane_blocked.set_value();
    released.wait();
  });
  lane_blocked.get_future().wait();
  const std::uint64_t publications_before = world->publications();
  const std::uint64_t merged_before = world->merged_publications();
  constexpr std::uint64_t kScans = 6;
  for (std::uint64_t seq = 1; seq <= kScans; ++seq) {
    // Each scan's arc is half a metre beyond the previous one: its cells become occupied and the previous arc's free.
    handle_laser_scan(session, scan(seq, 0.1 * static_cast<double>(seq), 0.5F + 0.5F * static_cast<float>(seq)));
  }
  // Commands do not wait for the publication; the last one says every scan but the last was staged.
  for (std::uint64_t seq = 1; seq <= kScans; ++seq) {
    const auto command = session->take_first_of(v1::ServerMessage::kMotionCommand);
    ASSERT_TRUE(command) << "scan " << seq;
    EXPECT_EQ(command->motion_command().answers_scan_seq(), seq);
  }
  release.set_value();
  for (std::uint64_t seq = 1; seq <= kScans; ++seq) {
    const auto ack = session->take_first_of(v1::ServerMessage::kScanAck);
    ASSERT_TRUE(ack) << "scan " << seq;
    EXPECT_EQ(ack->scan_ack().seq(), seq);
  }
  const std::uint64_t publications = world->publications() - publications_before;
  const std::uint64_t merged = world->merged_publications() - merged_before;
  EXPECT_EQ(publications + merged, kScans);
  EXPECT_LE(publications, 2U) << "the scans staged while the lane was held go out in one publication";

  const WorldSnapshot models = world->snapshots();
  EXPECT_EQ(models.distance->version(), models.grid->version());
  mapping::DistanceField fresh(core_.config().distance_field);
  static_cast<void>(fresh.update(models.grid));
  const auto bounds = models.distance->bounds();
  ASSERT_TRUE(bounds);
  std::size_t differing = 0;
  for (std::int32_t y = bounds->min.iy; y <= bounds->max.iy; ++y) {
    for (std::int32_t x = bounds->min.ix; x <= bounds->max.ix; ++x) {
      if (models.distance->distance({x, y}) != fresh.snapshot()->distance({x, y})) ++differing;
    }
  }
  EXPECT_EQ(differing, 0U) << "cells whose published distance is not the published grid's";
}

TEST_F(Handlers, ScanIsMappedFromTheSensorMountAndAnsweredByACommand) {
  auto session = driver("r1");
  // Robot at (1, 2) facing +y; the laser sits 0.45 m ahead of base_link, at (1, 2.45).
  handle_odometry(session, odometry(1.0, 2.0, M_PI / 2, 0.0));
  handle_laser_scan(session, scan(7, 0.1, 2.5F));
  const auto ack = session->take_first_of(v1::ServerMessage::kScanAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->scan_ack().seq(), 7U);
  const auto command = session->take_first_of(v1::ServerMessage::kMotionCommand);
  ASSERT_TRUE(command);
  EXPECT_EQ(command->motion_command().answers_scan_seq(), 7U);
  EXPECT_EQ(command->motion_command().behaviour(), v1::BEHAVIOUR_BEARCAT);
  // A ring of returns at 2.5 m lies outside the frontal rectangle (its far corners are 2.135 m
  // from the sensor), so the robot drives on.
  EXPECT_FALSE(command->motion_command().stop());
  EXPECT_GT(command->motion_command().linear_mps(), 0.0);
  EXPECT_NEAR(command->motion_command().expires_after_s(), 0.6, 1e-12);

  const auto snapshot = core_.world("default")->snapshot();
  const geometry::GridGeometry grid(snapshot->cell_size());
  // The straight-ahead beam ends 2.5 m beyond the sensor, at (1, 4.95): marked occupied there.
  EXPECT_TRUE(snapshot->occupied(grid.cell_of({1.0, 4.95})));
  // Had the beam been traced from the robot centre it would end at (1, 4.5), which stays free.
  EXPECT_FALSE(snapshot->occupied(grid.cell_of({1.0, 4.5})));
  EXPECT_TRUE(snapshot->observed(grid.cell_of({1.0, 4.5})));
}

// The default Bearcat does not park in a deadlock (seed 000 §5.2): with nothing on the map to plan by yet, it turns on
// the spot to see more instead of stopping.
TEST_F(Handlers, WallAcrossTheFrontIsADeadlockTheDefaultBearcatDoesNotStopIn) {
  auto session = driver("r1");
  handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
  handle_laser_scan(session, scan(1, 0.1, 1.0F));
  const auto command = session->next_of(v1::ServerMessage::kMotionCommand);
  ASSERT_TRUE(command);
  EXPECT_FALSE(command->motion_command().stop());
  const std::string state = proto::behaviour_state_label(command->motion_command().state());
  EXPECT_EQ(state.rfind("escape_", 0), 0U) << state;
  EXPECT_NE(command->motion_command().left_wheel_mps(), command->motion_command().right_wheel_mps());
  core_.drain();
  EXPECT_EQ(core_.find_robot("r1")->state().behaviour_state, command->motion_command().state());
}

// A driver that reconnects with a new footprint changes what the very next query on the same thread measures: the
// network threads keep the robot they looked up last and must look again after every registration.
TEST_F(Handlers, QueriesUseTheFootprintOfTheRobotsLatestRegistration) {
  auto robot_session = driver_that_mapped_an_arc("r1");
  auto query = query_client();
  v1::ClearanceQuery clearance;
  clearance.set_robot_id("r1");
  clearance.add_models(v1::MODEL_GRID);
  const auto clearance_now = [&](std::uint64_t request_id) {
    handle_clearance_query(query, request_id, clearance);
    const auto reply = query->next_of(v1::ServerMessage::kClearance);
    EXPECT_TRUE(reply && reply->clearance().found());
    return reply ? reply->clearance().clearance_m() : -1.0;
  };
  // The nearest returns start at |y| = 2.9 (CollisionAndClearanceQueriesReadThePublishedMap): 2.5 m from the 0.8 m
  // wide box's sides.
  EXPECT_NEAR(clearance_now(1), 2.5, 0.1);

  handle_disconnect(core_, robot_session->info());
  v1::RobotSpec wider = bearcat_spec();
  wider.mutable_footprint()->mutable_box()->set_width_m(2.0);
  const auto reconnected = testing::driver_session(core_, "r1", wider);
  ASSERT_NE(core_.find_robot("r1"), nullptr);
  EXPECT_NEAR(clearance_now(2), 1.9, 0.1) << "the 2.0 m wide box's sides are at |y| = 1.0";
}

TEST_F(Handlers, CollisionAndClearanceQueriesReadThePublishedMap) {
  auto robot_session = driver_that_mapped_an_arc("r1");
  auto query = query_client();
  v1::CollisionQuery collision;
  collision.set_robot_id("r1");
  collision.mutable_pose()->set_x(3.45);  // on the arc of returns 3 m ahead of the sensor
  handle_collision_query(query, 3, collision);
  auto reply = query->next_of(v1::ServerMessage::kCollision);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->request_id(), 3U);
  EXPECT_TRUE(reply->collision().hit());

  v1::ClearanceQuery clearance;
  clearance.set_robot_id("r1");
  // The grid only first; then every model (no `models`), which answers against matter too: the PTEM's clusters are
  // the returns they gathered, not a restricted region covering the robot.
  clearance.add_models(v1::MODEL_GRID);
  handle_clearance_query(query, 4, clearance);
  reply = query->next_of(v1::ServerMessage::kClearance);
  ASSERT_TRUE(reply);
  EXPECT_TRUE(reply->clearance().found());
  // The nearest returns are the ±90° beams ending at (0.45, ±3.0); their cells start at |y| = 2.9,
  // 2.5 m from the box's sides at |y| = 0.4. One cell of tolerance for where the endpoint falls.
  EXPECT_NEAR(reply->clearance().clearance_m(), 2.5, 0.1);
  EXPECT_EQ(reply->clearance().model(), v1::MODEL_GRID);
  v1::ClearanceQuery every = clearance;
  every.clear_models();
  handle_clearance_query(query, 5, every);
  reply = query->next_of(v1::ServerMessage::kClearance);
  ASSERT_TRUE(reply);
  EXPECT_NEAR(reply->clearance().clearance_m(), 2.5, 0.1);
  EXPECT_GT(reply->clearance().clearance_m(), 0.0);

  clearance.set_max_distance_m(1.0e9);
  handle_clearance_query(query, 4, clearance);
  reply = query->next_of(v1::ServerMessage::kError);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->error().field(), "clearance.max_distance_m");
  EXPECT_EQ(reply->request_id(), 4U);

  collision.set_robot_id("nobody");
  handle_collision_query(query, 3, collision);
  reply = query->next_of(v1::ServerMessage::kError);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->error().code(), v1::ERROR_UNKNOWN_ROBOT);
  EXPECT_EQ(reply->error().field(), "collision.robot_id");
}

// The wire numbers the behaviours' states as the control library does, name for name: a state added to one and not the
// other fails here instead of reaching a robot's commands and logs under another name.
TEST(BehaviourVocabulary, WireStatesAreTheBehavioursStatesByNumberAndName) {
  for (std::size_t i = 1; i < control::kBehaviourStateCount; ++i) {
    const auto state = static_cast<control::BehaviourState>(i);
    EXPECT_EQ(proto::behaviour_state_label(to_wire(state)), control::name(state)) << "state " << i;
  }
  // Every label names its value back, and only the lower-case label of a set value names one.
  const google::protobuf::EnumDescriptor& states = *v1::BehaviourState_descriptor();
  for (int i = 1; i < states.value_count(); ++i) {
    const auto value = static_cast<v1::BehaviourState>(states.value(i)->number());
    EXPECT_EQ(proto::behaviour_state_from_label(proto::behaviour_state_label(value)), value) << states.value(i)->name();
  }
  EXPECT_EQ(proto::behaviour_from_label("goto"), v1::BEHAVIOUR_GOTO);
  EXPECT_EQ(proto::behaviour_from_label("bearcat_seed"), v1::BEHAVIOUR_BEARCAT_SEED);
  EXPECT_FALSE(proto::behaviour_from_label("GOTO"));
  EXPECT_FALSE(proto::behaviour_from_label("unspecified"));
  EXPECT_FALSE(proto::behaviour_from_label(""));
  EXPECT_FALSE(proto::behaviour_from_label("dance"));
  EXPECT_EQ(proto::behaviour_label(v1::BEHAVIOUR_UNSPECIFIED), "");
  EXPECT_EQ(proto::behaviour_labels(), "bearcat, bearcat_seed, stop, teleop, wander, goto, waypoints");
}

// A driver's acks are answered by the journal's sync thread, which keeps the callbacks it ran until the next append;
// they hold the session, its robot and their world. A core shutting down lets go of them: otherwise the world outlives
// its core, with its journal's thread and its strands on thread pools that are gone (the heap corruption this once
// caused showed up when the next core started its pools). Which thread answers the last ack varies from run to run,
// hence twenty cores.
TEST(ServerCoreLifetime, AWorldDoesNotOutliveItsCore) {
  for (int run = 0; run < 20; ++run) {
    std::weak_ptr<World> world;
    {
      ServerCore core{ServerConfig{}};
      world = core.world("default");
      auto session = testing::driver_session(core, "r1", bearcat_spec());
      handle_odometry(session, odometry(0.0, 0.0, 0.0, 0.0));
      for (std::uint64_t seq = 1; seq <= 5; ++seq) {
        v1::LaserScan scan;
        scan.set_sensor("front_laser");
        scan.set_seq(seq);
        scan.set_stamp_s(0.1 * static_cast<double>(seq));
        for (int i = 0; i < 181; ++i) scan.add_ranges(2.0F + 0.01F * static_cast<float>(seq));
        handle_laser_scan(session, scan);
        ASSERT_TRUE(session->take_first_of(v1::ServerMessage::kScanAck)) << "run " << run << ", scan " << seq;
      }
    }
    EXPECT_TRUE(world.expired()) << "run " << run;
  }
}

}  // namespace
}  // namespace occgeo::service
