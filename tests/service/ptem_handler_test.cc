// The PTEM in the server: laser scans feed each world's model on its strand and PtemQuery reads the
// published snapshot. Against a fake session and a real ServerCore (no sockets).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "fake_session.h"
#include "occgeo/mapping/ptem.h"
#include "test_robots.h"

namespace occgeo::service {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A URG-04LX-like laser on base_link's origin: 241 beams over 240°, 0.02–4 m.
constexpr int kBeams = 241;
constexpr double kFov_rad = 240.0 * M_PI / 180.0;
constexpr double kAngleMin_rad = -kFov_rad / 2.0;
constexpr double kIncrement_rad = kFov_rad / (kBeams - 1);
constexpr double kRangeMax_m = 4.0;

// The thin obstacle of seed 004 §5.1.1: a circle of radius 0.055 m at (1.75, 0).
const Eigen::Vector2d kObstacle(1.75, 0.0);
constexpr double kObstacleRadius_m = 0.055;

v1::RobotSpec laser_robot_spec() {
  return testing::laser_probe_spec({.model = "ptem-probe",
                                    .height_m = 0.4,
                                    .beam_count = kBeams,
                                    .angle_min_rad = kAngleMin_rad,
                                    .angle_increment_rad = kIncrement_rad,
                                    .range_min_m = 0.02,
                                    .range_max_m = kRangeMax_m});
}

// Exact ranges from a sensor at the origin facing +x to the obstacle's circle; max range elsewhere.
std::vector<float> circle_ranges() {
  std::vector<float> ranges;
  for (int i = 0; i < kBeams; ++i) {
    const double a = kAngleMin_rad + kIncrement_rad * i;
    const Eigen::Vector2d u(std::cos(a), std::sin(a));
    const double b = u.dot(kObstacle);
    const double disc = b * b - (kObstacle.squaredNorm() - kObstacleRadius_m * kObstacleRadius_m);
    ranges.push_back(disc >= 0.0 ? static_cast<float>(b - std::sqrt(disc)) : static_cast<float>(kRangeMax_m));
  }
  return ranges;
}

// The same scan as the library sees it when given the returns directly: what the server must reproduce.
std::shared_ptr<const mapping::PtemSnapshot> library_snapshot(const std::vector<float>& ranges,
                                                              mapping::PtemConstruction construction) {
  std::vector<Eigen::Vector2d> points;
  for (int i = 0; i < kBeams; ++i) {
    const auto r = static_cast<double>(ranges[static_cast<std::size_t>(i)]);
    if (r >= kRangeMax_m) continue;
    const double a = kAngleMin_rad + kIncrement_rad * i;
    points.emplace_back(r * std::cos(a), r * std::sin(a));
  }
  mapping::PtemParams params;
  params.construction = construction;
  mapping::PtemModel model(params);
  mapping::PtemScan scan;
  scan.stamp_s = 0.1;
  scan.field_of_view_rad = kFov_rad + kIncrement_rad;
  scan.max_range_m = kRangeMax_m;
  scan.points_W = points;
  model.insert_scan(scan);
  return model.snapshot();
}

v1::Point2D point(double x, double y) {
  v1::Point2D p;
  p.set_x(x);
  p.set_y(y);
  return p;
}

ServerConfig config_with_cumulative_world() {
  ServerConfig config;
  config.ptem.worlds["cumulative_world"].construction = mapping::PtemConstruction::kCumulative;
  config.limits.max_ptem_query_points = 1000;
  return config;
}

class PtemHandler : public ::testing::Test {
 protected:
  PtemHandler() : core_(config_with_cumulative_world()) {}

  // A driver in `world` at the origin that has sent one scan of the thin obstacle, acknowledged.
  std::shared_ptr<FakeSession> scan_circle(const std::string& robot_id, const std::string& world) {
    auto session = testing::driver_session(core_, robot_id, laser_robot_spec(), world);
    v1::Odometry odometry;
    odometry.set_stamp_s(0.0);
    odometry.mutable_pose();
    handle_odometry(session, odometry);
    v1::LaserScan scan;
    scan.set_sensor("laser");
    scan.set_seq(1);
    scan.set_stamp_s(0.1);
    for (const float r : circle_ranges()) scan.add_ranges(r);
    handle_laser_scan(session, scan);
    const auto ack = session->next_of(v1::ServerMessage::kScanAck);
    EXPECT_TRUE(ack) << "no ScanAck";
    return session;
  }

  std::shared_ptr<FakeSession> query_session() {
    auto session = std::make_shared<FakeSession>(core_);
    handle_hello(session, testing::hello_message(v1::ROLE_QUERY));
    EXPECT_TRUE(session->next_of(v1::ServerMessage::kWelcome));
    return session;
  }

  // Sends the query as request `request_id` and returns the reply or error.
  static v1::ServerMessage ask(const std::shared_ptr<FakeSession>& session, const v1::PtemQuery& query,
                               std::uint64_t request_id = 0) {
    v1::ClientMessage message;
    message.set_request_id(request_id);
    *message.mutable_ptem() = query;
    dispatch(session, message);
    auto reply = session->next();
    EXPECT_TRUE(reply) << "no reply";
    return reply ? *reply : v1::ServerMessage{};
  }

  ServerCore core_;
};

void expect_matches_library(const v1::PtemReply& reply, const v1::PtemQuery& query,
                            const mapping::PtemSnapshot& expected) {
  ASSERT_EQ(reply.samples_size(), query.points_size());
  ASSERT_EQ(reply.clusters_size(), static_cast<int>(expected.clusters().size()));
  for (int i = 0; i < reply.clusters_size(); ++i) {
    const auto& got = reply.clusters(i);
    const mapping::PtemCluster& want = expected.clusters()[static_cast<std::size_t>(i)];
    EXPECT_NEAR(got.center().x(), want.centre_W.x(), 1e-12);
    EXPECT_NEAR(got.center().y(), want.centre_W.y(), 1e-12);
    EXPECT_NEAR(got.radius_m(), want.radius_m, 1e-12);
    EXPECT_NEAR(got.sigma_m(), want.sigma_m, 1e-12);
    EXPECT_EQ(got.age_scans(), 0U);
    EXPECT_EQ(got.age_s(), 0.0);
    EXPECT_EQ(got.threshold_reachable(), want.threshold_reachable);
  }
  for (int i = 0; i < query.points_size(); ++i) {
    const Eigen::Vector2d p(query.points(i).x(), query.points(i).y());
    const mapping::PtemThreat want = expected.threat_and_gradient(p);
    const auto& got = reply.samples(i);
    const double scale = std::max(1.0, std::abs(want.value));
    EXPECT_NEAR(got.threat(), want.value, 1e-9 * scale) << "point " << i;
    EXPECT_NEAR(got.gradient().x(), want.gradient_W.x(), 1e-9 * std::max(1.0, want.gradient_W.norm())) << i;
    EXPECT_NEAR(got.gradient().y(), want.gradient_W.y(), 1e-9 * std::max(1.0, want.gradient_W.norm())) << i;
    EXPECT_EQ(got.restricted(), expected.restricted(p)) << "point " << i;
  }
}

TEST_F(PtemHandler, ScanOfACircleMakesOneClusterAndQueriesAgreeWithTheLibrary) {
  for (const auto& [world, construction] :
       {std::pair{std::string("default"), mapping::PtemConstruction::kSingleScan},
        std::pair{std::string("cumulative_world"), mapping::PtemConstruction::kCumulative}}) {
    SCOPED_TRACE(world);
    auto driver = scan_circle("probe-" + world, world);
    auto session = query_session();
    v1::PtemQuery query;
    query.set_world(world == "default" ? "" : world);  // empty: the default world
    query.set_include_clusters(true);
    *query.add_points() = point(1.75, 0.0);          // the obstacle's centre
    *query.add_points() = point(1.75 - 0.055, 0.0);  // its near side, where the returns are
    *query.add_points() = point(1.75, 0.3);          // beside it
    *query.add_points() = point(0.0, 0.0);           // the robot
    *query.add_points() = point(-3.0, 2.0);          // far away
    *query.add_points() = point(1.70, 0.02);         // off-axis, for the gradient's y
    const v1::ServerMessage reply = ask(session, query, 42);
    ASSERT_TRUE(reply.has_ptem()) << reply.DebugString();
    const v1::PtemReply& ptem = reply.ptem();
    EXPECT_EQ(reply.request_id(), 42U);
    EXPECT_EQ(ptem.world(), world);
    EXPECT_EQ(ptem.construction(), world == "default" ? "single_scan" : "cumulative");
    EXPECT_EQ(ptem.cluster_count(), 1U);
    EXPECT_EQ(ptem.scans(), 1U);
    EXPECT_DOUBLE_EQ(ptem.latest_stamp_s(), 0.1);
    EXPECT_DOUBLE_EQ(ptem.threshold_f_r(), 0.04);
    EXPECT_GE(ptem.version(), 1U);
    ASSERT_EQ(ptem.clusters_size(), 1);
    // The cluster is centred on the obstacle: it starts at a return on its surface and the others fall inside.
    EXPECT_LE((Eigen::Vector2d(ptem.clusters(0).center().x(), ptem.clusters(0).center().y()) - kObstacle).norm(),
              kObstacleRadius_m + 1e-6);
    expect_matches_library(ptem, query, *library_snapshot(circle_ranges(), construction));
    EXPECT_TRUE(ptem.samples(1).restricted()) << "the returns themselves are restricted";
    EXPECT_FALSE(ptem.samples(3).restricted());
    EXPECT_FALSE(ptem.samples(4).restricted());
    EXPECT_EQ(ptem.samples(4).threat(), 0.0);
    // The threat rises towards the cluster's centre: on its near side the gradient points ahead (+x).
    EXPECT_GT(ptem.samples(1).gradient().x(), 0.0);
  }
}

TEST_F(PtemHandler, WithoutIncludeClustersOnlyTheCountAndSamplesComeBack) {
  auto driver = scan_circle("probe", "default");
  auto session = query_session();
  v1::PtemQuery query;
  const v1::ServerMessage reply = ask(session, query, 3);
  ASSERT_TRUE(reply.has_ptem());
  EXPECT_EQ(reply.ptem().cluster_count(), 1U);
  EXPECT_EQ(reply.ptem().clusters_size(), 0);
  EXPECT_EQ(reply.ptem().samples_size(), 0);
}

TEST_F(PtemHandler, StatusListsEachWorldsClusters) {
  auto driver = scan_circle("probe", "cumulative_world");
  auto session = query_session();
  v1::ClientMessage message;
  message.mutable_status();
  message.set_request_id(1);
  dispatch(session, message);
  const auto reply = session->next_of(v1::ServerMessage::kStatus);
  ASSERT_TRUE(reply);
  ASSERT_EQ(reply->status().worlds_size(), 1);
  const v1::WorldStatus& world = reply->status().worlds(0);
  EXPECT_EQ(world.name(), "cumulative_world");
  EXPECT_EQ(world.ptem_construction(), "cumulative");
  EXPECT_EQ(world.ptem_clusters(), 1U);
  EXPECT_EQ(world.ptem_scans(), 1U);
}

TEST_F(PtemHandler, ValidationErrorsNameTheField) {
  auto driver = scan_circle("probe", "default");
  auto session = query_session();
  struct Case {
    std::function<void(v1::PtemQuery&)> damage;
    v1::ErrorCode code;
    std::string field;
  };
  const std::vector<Case> cases = {
      {[](v1::PtemQuery& q) { q.set_world("nowhere"); }, v1::ERROR_UNKNOWN_WORLD, "ptem.world"},
      {[](v1::PtemQuery& q) { *q.add_points() = point(kNaN, 0.0); }, v1::ERROR_INVALID_ARGUMENT, "ptem.points[1].x"},
      {[](v1::PtemQuery& q) { *q.add_points() = point(0.0, kInf); }, v1::ERROR_INVALID_ARGUMENT, "ptem.points[1].y"},
      {[](v1::PtemQuery& q) { *q.add_points() = point(2.0e5, 0.0); }, v1::ERROR_INVALID_ARGUMENT, "ptem.points[1].x"},
      {[](v1::PtemQuery& q) {
         for (int i = 0; i < 1000; ++i) *q.add_points() = point(0.0, 0.0);
       },
       v1::ERROR_INVALID_ARGUMENT, "ptem.points"},
  };
  std::uint64_t request_id = 100;
  for (const Case& c : cases) {
    v1::PtemQuery query;
    *query.add_points() = point(1.0, 1.0);
    c.damage(query);
    const v1::ServerMessage reply = ask(session, query, ++request_id);
    ASSERT_TRUE(reply.has_error()) << c.field;
    EXPECT_EQ(reply.error().code(), c.code) << c.field;
    EXPECT_EQ(reply.error().field(), c.field);
    EXPECT_EQ(reply.request_id(), request_id);
  }
  // Exactly the limit is fine.
  v1::PtemQuery query;
  for (int i = 0; i < 1000; ++i) *query.add_points() = point(0.0, 0.0);
  const v1::ServerMessage reply = ask(session, query, 7);
  ASSERT_TRUE(reply.has_ptem());
  EXPECT_EQ(reply.ptem().samples_size(), 1000);
}

TEST_F(PtemHandler, ASecondScanWithoutTheObstacleClearsSingleScanButNotCumulative) {
  for (const std::string world : {"default", "cumulative_world"}) {
    SCOPED_TRACE(world);
    auto driver = scan_circle("probe-" + world, world);
    v1::LaserScan empty;
    empty.set_sensor("laser");
    empty.set_seq(2);
    empty.set_stamp_s(0.2);
    for (int i = 0; i < kBeams; ++i) empty.add_ranges(static_cast<float>(kRangeMax_m));
    handle_laser_scan(driver, empty);
    ASSERT_TRUE(driver->next_of(v1::ServerMessage::kScanAck));
    auto session = query_session();
    v1::PtemQuery query;
    query.set_world(world == "default" ? "" : world);
    query.set_include_clusters(true);
    const v1::ServerMessage reply = ask(session, query);
    ASSERT_TRUE(reply.has_ptem());
    EXPECT_EQ(reply.ptem().scans(), 2U);
    if (world == "default") {
      EXPECT_EQ(reply.ptem().cluster_count(), 0U) << "the scanned sector no longer holds the obstacle";
    } else {
      ASSERT_EQ(reply.ptem().clusters_size(), 1);
      EXPECT_EQ(reply.ptem().clusters(0).age_scans(), 1U);
      EXPECT_NEAR(reply.ptem().clusters(0).age_s(), 0.1, 1e-12);
    }
  }
}

}  // namespace
}  // namespace occgeo::service
