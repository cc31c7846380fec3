// The pluggable behaviours as the server runs them: scans and poses in, velocities out.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "bearcat_shape.h"
#include "occgeo/service/control/behaviour.h"

namespace occgeo::service::control {
namespace {

constexpr double kPi = std::numbers::pi;

// A 181-beam, 1° laser over ±90° reading `range` everywhere, 8 m max.
struct OpenScan {
  std::vector<float> ranges = std::vector<float>(181, 8.0F);
  [[nodiscard]] ScanView view() const { return {-kPi / 2, kPi / 180, ranges, 8.0}; }
};

// Integrates a body velocity for dt (unicycle).
geometry::Pose2 step(const geometry::Pose2& pose, const BehaviourCommand& command, double dt) {
  const double theta = pose.theta + command.angular_radps * dt / 2.0;
  return {pose.x + command.linear_mps * dt * std::cos(theta), pose.y + command.linear_mps * dt * std::sin(theta),
          geometry::wrap_angle(pose.theta + command.angular_radps * dt)};
}

TEST(SweepFromScan, ReadsEveryWholeDegreeAndMarksNoReturnAsInfinite) {
  OpenScan scan;
  scan.ranges[90] = 0.5F;   // straight ahead
  scan.ranges[100] = 2.0F;  // 10° left
  const std::vector<SweepReading> sweep = sweep_from_scan(scan.view());
  ASSERT_EQ(sweep.size(), 181U);
  EXPECT_NEAR(sweep[90].angle_rad, 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(sweep[90].range_m, 0.5);
  EXPECT_DOUBLE_EQ(sweep[100].range_m, 2.0);
  EXPECT_TRUE(std::isinf(sweep[0].range_m)) << "a reading at range_max is no return";
}

TEST(PointBugParamsFor, KeepsTheSeedsValuesForTheActivityBotAndScalesForLargerRobots) {
  RobotShape activitybot;
  activitybot.footprint = geometry::BoxFootprint{.length = 0.15, .width = 0.13, .height = 0.12, .center_x = 0.0};
  const PointBugParams seed = pointbug_params_for(activitybot);
  EXPECT_DOUBLE_EQ(seed.obstacle_range_m, 0.30);
  EXPECT_DOUBLE_EQ(seed.angle_extension_deg, 15.0);
  EXPECT_DOUBLE_EQ(seed.distance_extension_m, 0.120);
  const PointBugParams big = pointbug_params_for(bearcat_shape());
  EXPECT_GT(big.obstacle_range_m, 0.8);
  EXPECT_GT(big.distance_extension_m, 0.4);
  EXPECT_GT(big.angle_extension_deg, 15.0);
  EXPECT_NO_THROW(big.validate());
}

TEST(GotoBehaviour, ReachesAGoalInOpenSpaceAndStops) {
  auto behaviour = make_goto(pointbug_params_for(bearcat_shape()), 3.0, 2.0, 0.1, 0.5);
  EXPECT_EQ(behaviour->name(), "goto");
  ASSERT_TRUE(behaviour->current_goal());
  const OpenScan scan;
  geometry::Pose2 pose;
  BehaviourCommand command;
  for (int i = 0; i < 2000 && !command.stop; ++i) {
    command = behaviour->decide({scan.view(), pose, 0.1 * i});
    pose = step(pose, command, 0.1);
  }
  EXPECT_EQ(command.state, BehaviourState::kReached);
  EXPECT_NEAR(pose.x, 3.0, 0.1);
  EXPECT_NEAR(pose.y, 2.0, 0.1);
}

TEST(GotoBehaviour, AnObstacleInTheBodysCorridorButOffTheCentreBeamStopsTheApproach) {
  // Returns 0.6 m ahead and 0.3 m to the left: inside a 0.5 m half-corridor, missed by the 0° beam.
  OpenScan scan;
  const int beam = 90 + static_cast<int>(std::lround(std::atan2(0.3, 0.6) * 180.0 / kPi));
  scan.ranges[static_cast<std::size_t>(beam)] = static_cast<float>(std::hypot(0.6, 0.3));
  auto with_corridor = make_goto(pointbug_params_for(bearcat_shape()), 5.0, 0.0, 0.1, 0.5);
  auto centre_beam_only = make_goto(pointbug_params_for(bearcat_shape()), 5.0, 0.0, 0.1, 0.0);
  const BehaviourCommand corridor = with_corridor->decide({scan.view(), geometry::Pose2{}, 0.0});
  const BehaviourCommand seed = centre_beam_only->decide({scan.view(), geometry::Pose2{}, 0.0});
  EXPECT_EQ(seed.state, BehaviourState::kStepToGoal);
  EXPECT_NE(corridor.state, BehaviourState::kStepToGoal);
}

TEST(WanderBehaviour, IsDeterministicAndTurnsAwayFromAFrontalObstacle) {
  OpenScan blocked;
  for (std::size_t i = 80; i <= 100; ++i) blocked.ranges[i] = 0.8F;
  auto avoiding = make_wander(WanderParams{}, bearcat_shape());
  const BehaviourCommand first = avoiding->decide({blocked.view(), geometry::Pose2{}, 0.0});
  EXPECT_EQ(first.state, BehaviourState::kAvoidTurn) << "1.5 robot widths of threshold see the obstacle 0.8 m ahead";
  EXPECT_EQ(first.linear_mps, 0.0);
  EXPECT_NE(first.angular_radps, 0.0);
  auto a = make_wander(WanderParams{}, bearcat_shape());
  auto b = make_wander(WanderParams{}, bearcat_shape());
  const OpenScan open;
  geometry::Pose2 pa;
  geometry::Pose2 pb;
  for (int i = 0; i < 200; ++i) {
    const BehaviourCommand ca = a->decide({open.view(), pa, 0.1 * i});
    const BehaviourCommand cb = b->decide({open.view(), pb, 0.1 * i});
    ASSERT_EQ(ca.linear_mps, cb.linear_mps) << i;
    ASSERT_EQ(ca.angular_radps, cb.angular_radps) << i;
    pa = step(pa, ca, 0.1);
    pb = step(pb, cb, 0.1);
  }
}

TEST(EscapeBehaviour, PassesAGoalBehavioursCommandsThroughWhileItProgresses) {
  const auto rebuild = [] { return make_goto(pointbug_params_for(bearcat_shape()), 3.0, 0.0, 0.1, 0.5); };
  auto escape = make_escape(rebuild, bearcat_shape(), GuardParams{});
  auto plain = rebuild();
  EXPECT_EQ(escape->name(), "goto");
  const OpenScan scan;
  geometry::Pose2 pose;
  for (int i = 0; i < 100; ++i) {
    const BehaviourCommand e = escape->decide({scan.view(), pose, 0.1 * i});
    const BehaviourCommand p = plain->decide({scan.view(), pose, 0.1 * i});
    ASSERT_EQ(e.state, p.state) << i;
    ASSERT_EQ(e.linear_mps, p.linear_mps) << i;
    pose = step(pose, e, 0.1);
  }
}

TEST(PlannedPath, GotoPlansFromWhereItIsToTheGoalUntilItArrives) {
  auto go = make_goto(pointbug_params_for(bearcat_shape()), 3.0, 0.0, 0.1, 0.5);
  EXPECT_TRUE(go->planned_path().empty()) << "no pose seen yet";
  const OpenScan scan;
  geometry::Pose2 pose;
  bool reached = false;
  for (int i = 0; i < 300 && !reached; ++i) {
    const BehaviourCommand command = go->decide({scan.view(), pose, 0.1 * i});
    reached = command.state == BehaviourState::kReached;
    const std::vector<Eigen::Vector2d> path = go->planned_path();
    if (reached) {
      EXPECT_TRUE(path.empty());
    } else {
      ASSERT_EQ(path.size(), 2U) << i;
      EXPECT_TRUE(path.front().isApprox(Eigen::Vector2d(pose.x, pose.y))) << i;
      EXPECT_TRUE(path.back().isApprox(Eigen::Vector2d(3.0, 0.0))) << i;
    }
    pose = step(pose, command, 0.1);
  }
  EXPECT_TRUE(reached);
}

TEST(PlannedPath, WaypointsPlanTheWaypointsStillAhead) {
  auto follow = make_waypoints(bearcat_shape(), {{1.0, 0.0}, {2.0, 1.0}, {3.0, 1.0}});
  const OpenScan scan;
  geometry::Pose2 pose;
  std::size_t fewest = 4;
  for (int i = 0; i < 600; ++i) {
    const BehaviourCommand command = follow->decide({scan.view(), pose, 0.1 * i});
    const std::vector<Eigen::Vector2d> path = follow->planned_path();
    if (command.state == BehaviourState::kReached) {
      EXPECT_TRUE(path.empty());
      break;
    }
    ASSERT_FALSE(path.empty()) << i;
    EXPECT_TRUE(path.front().isApprox(Eigen::Vector2d(pose.x, pose.y))) << i;
    EXPECT_TRUE(path.back().isApprox(Eigen::Vector2d(3.0, 1.0))) << i;
    EXPECT_LE(path.size(), fewest) << "waypoints passed do not come back";
    fewest = std::min(fewest, path.size());
    pose = step(pose, command, 0.1);
  }
  EXPECT_EQ(fewest, 2U) << "the path shrank to the robot and the last waypoint";
}

TEST(PlannedPath, EscapeReportsTheInnerBehavioursPathUntilItEscapes) {
  const auto rebuild = [] { return make_goto(pointbug_params_for(bearcat_shape()), 3.0, 0.0, 0.1, 0.5); };
  auto escape = make_escape(rebuild, bearcat_shape(), GuardParams{});
  const OpenScan scan;
  static_cast<void>(escape->decide({scan.view(), geometry::Pose2{}, 0.0}));
  const std::vector<Eigen::Vector2d> path = escape->planned_path();
  ASSERT_EQ(path.size(), 2U);
  EXPECT_TRUE(path.back().isApprox(Eigen::Vector2d(3.0, 0.0)));
}

}  // namespace
}  // namespace occgeo::service::control
