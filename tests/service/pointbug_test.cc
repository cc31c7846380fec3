// The modified PointBug behaviour of seed 003 (§2.2, §4.1–4.4 and its Propeller C listing) on synthetic servo
// sweeps: hand-written per-degree sweeps for the search rules, and sweeps ray-cast against walls for whole runs.
#include "occgeo/service/control/pointbug.h"

#include <gtest/gtest.h>

#include "../support/error_message.h"

#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace occgeo::service::control {
namespace {

constexpr double kLidarMax_m = 2.0;
constexpr double kTolerance = 1e-9;

double radians(double degrees) { return degrees * std::numbers::pi / 180.0; }

// A +-90 degree sweep at 1 degree whose reading at signed degree d (left positive) is range_of(d).
std::vector<SweepReading> sweep_of(const std::function<double(int)>& range_of) {
  std::vector<SweepReading> readings;
  for (int degree = -90; degree <= 90; ++degree) readings.push_back({radians(degree), range_of(degree)});
  return readings;
}

struct Segment {
  double x0_m, y0_m, x1_m, y1_m;
};

double ray_distance(double ox, double oy, double dx, double dy, const Segment& s) {
  const double ex = s.x1_m - s.x0_m;
  const double ey = s.y1_m - s.y0_m;
  const double denominator = dx * ey - dy * ex;
  if (denominator == 0.0) return std::numeric_limits<double>::infinity();
  const double px = s.x0_m - ox;
  const double py = s.y0_m - oy;
  const double along_ray = (px * ey - py * ex) / denominator;
  const double along_segment = (px * dy - py * dx) / denominator;
  if (along_ray <= 0.0 || along_segment < 0.0 || along_segment > 1.0) return std::numeric_limits<double>::infinity();
  return along_ray;
}

// The sweep seen from a pose among walls (the sensor at the wheel axle centre, as the listing assumes).
std::vector<SweepReading> cast(const Pose2& pose, const std::vector<Segment>& walls) {
  return sweep_of([&](int degree) {
    const double angle = pose.theta + radians(degree);
    double range = kLidarMax_m;
    for (const Segment& wall : walls) {
      range = std::min(range, ray_distance(pose.x, pose.y, std::cos(angle), std::sin(angle), wall));
    }
    return range;
  });
}

struct DrivenRun {
  std::vector<std::string> states;
  std::vector<SuddenPoint> sudden_points;
  Pose2 final_pose;
  std::string final_state;
};

// Runs the behaviour executing each decision's target as drive_goto would: turn, then drive.
DrivenRun run_to_goal(Pose2 pose, double goal_x, double goal_y, const std::vector<Segment>& walls) {
  PointBugBehaviour behaviour(PointBugParams{}, goal_x, goal_y);
  DrivenRun run;
  for (int cycle = 0; cycle < 5000; ++cycle) {
    const std::vector<SweepReading> readings = cast(pose, walls);
    const PointBugDecision decision = behaviour.decide(pose, Sweep{readings, kLidarMax_m});
    if (run.states.empty() || run.states.back() != name(decision.state)) run.states.emplace_back(name(decision.state));
    if (decision.state == BehaviourState::kTurnToSuddenPoint) run.sudden_points.push_back(*decision.sudden_point);
    if (decision.stop) {
      run.final_state = std::string(name(decision.state));
      break;
    }
    pose.theta += decision.target.turn_rad;
    pose.x += decision.target.distance_m * std::cos(pose.theta);
    pose.y += decision.target.distance_m * std::sin(pose.theta);
  }
  run.final_pose = pose;
  return run;
}

TEST(PointBugTest, ClearPathGoesStraightToTheGoalAndReportsReached) {
  const DrivenRun run = run_to_goal(Pose2{0.0, 0.0, 0.0}, 0.3, 0.4, {});
  EXPECT_EQ(run.final_state, "reached");
  EXPECT_EQ(run.states, (std::vector<std::string>{"aim_at_goal", "step_to_goal", "reached"}));
  EXPECT_TRUE(run.sudden_points.empty());
  EXPECT_LE(std::hypot(run.final_pose.x - 0.3, run.final_pose.y - 0.4), PointBugParams{}.goal_tolerance_m);
}

TEST(PointBugTest, SteppingCommandsBodyVelocityAndADriveGotoStep) {
  PointBugBehaviour behaviour(PointBugParams{}, 1.0, 0.0);
  const std::vector<SweepReading> readings = sweep_of([](int) { return kLidarMax_m; });
  const PointBugDecision decision = behaviour.decide(Pose2{}, Sweep{readings, kLidarMax_m});
  EXPECT_EQ(decision.state, BehaviourState::kStepToGoal);
  EXPECT_DOUBLE_EQ(decision.linear_mps, 4.0 * 3.25e-3);
  EXPECT_EQ(decision.angular_radps, 0.0);
  EXPECT_DOUBLE_EQ(decision.target.distance_m, 9.75e-3);
  EXPECT_FALSE(decision.stop);
}

// A wall 0.25 m ahead from y = -0.1 m (right end) to y = +1 m: the right beams leave it after 21 degrees
// (0.25 tan 21 = 0.096 m, 0.25 tan 22 = 0.101 m), the left ones after 75.
const std::vector<Segment> kWallWithRightEdge{{0.25, -0.1, 0.25, 1.0}};

TEST(PointBugTest, WallWithAnEdgeGivesTheSuddenPointOnThatSideWithTheSeedsCorrections) {
  const std::vector<SweepReading> readings = cast(Pose2{}, kWallWithRightEdge);
  const Sweep sweep{readings, kLidarMax_m};
  const std::optional<SuddenPoint> right = find_sudden_point(sweep, SweepSide::kRight, PointBugParams{});
  ASSERT_TRUE(right.has_value());
  EXPECT_EQ(right->edge_angle_deg, 21);
  EXPECT_NEAR(right->edge_range_m, 0.25 / std::cos(radians(21.0)), kTolerance);
  EXPECT_NEAR(right->turn_deg, 21.0 + 15.0, kTolerance);                               // angr + 15
  EXPECT_NEAR(right->distance_m, 0.25 / std::cos(radians(21.0)) + 0.120, kTolerance);  // a0 + 120 mm
  EXPECT_NEAR(right->turn_rad, -radians(36.0), kTolerance);

  const std::optional<SuddenPoint> left = find_sudden_point(sweep, SweepSide::kLeft, PointBugParams{});
  ASSERT_TRUE(left.has_value());
  EXPECT_EQ(left->edge_angle_deg, 75);
  EXPECT_NEAR(left->turn_deg, 90.0, kTolerance);

  PointBugBehaviour behaviour(PointBugParams{}, 1.0, 0.0);
  const PointBugDecision decision = behaviour.decide(Pose2{}, sweep);
  EXPECT_EQ(decision.state, BehaviourState::kTurnToSuddenPoint);
  ASSERT_TRUE(decision.sudden_point.has_value());
  EXPECT_EQ(decision.sudden_point->side, SweepSide::kRight);
  EXPECT_NEAR(decision.target.turn_rad, -radians(36.0), kTolerance);
  EXPECT_NEAR(decision.target.distance_m, right->distance_m, kTolerance);
  EXPECT_LT(decision.angular_radps, 0.0);
  EXPECT_EQ(decision.linear_mps, 0.0);
  EXPECT_NEAR(decision.sudden_point->world_x_m, right->distance_m * std::cos(radians(36.0)), kTolerance);
  EXPECT_NEAR(decision.sudden_point->world_y_m, -right->distance_m * std::sin(radians(36.0)), kTolerance);
}

TEST(PointBugTest, MirroredWallGoesLeft) {
  const std::vector<SweepReading> readings = cast(Pose2{}, {{0.25, 0.1, 0.25, -1.0}});
  PointBugBehaviour behaviour(PointBugParams{}, 1.0, 0.0);
  const PointBugDecision decision = behaviour.decide(Pose2{}, Sweep{readings, kLidarMax_m});
  ASSERT_TRUE(decision.sudden_point.has_value());
  EXPECT_EQ(decision.sudden_point->side, SweepSide::kLeft);
  EXPECT_NEAR(decision.target.turn_rad, radians(36.0), kTolerance);
}

TEST(PointBugTest, EqualAnglesGoLeftAsTheListingDoes) {
  const std::vector<SweepReading> readings = sweep_of([](int degree) { return std::abs(degree) <= 20 ? 0.25 : 1.5; });
  PointBugBehaviour behaviour(PointBugParams{}, 1.0, 0.0);
  const PointBugDecision decision = behaviour.decide(Pose2{}, Sweep{readings, kLidarMax_m});
  ASSERT_TRUE(decision.right && decision.left);
  EXPECT_EQ(decision.right->turn_deg, decision.left->turn_deg);
  EXPECT_EQ(decision.sudden_point->side, SweepSide::kLeft);
}

// Right side: the obstacle ends at 21 degrees (0.25 m), then a post closer than a0 + 200 mm stands in the gap.
std::vector<SweepReading> right_edge_with_post_at(int post_first_deg, int post_last_deg) {
  return sweep_of([=](int degree) {
    const int right = -degree;
    if (right < 0) return 0.25;  // the left side is blocked throughout
    if (right <= 21) return 0.25;
    if (right >= post_first_deg && right <= post_last_deg) return 0.35;
    return 1.5;
  });
}

TEST(PointBugTest, GapCheckRejectsAGapNarrowerThan30Degrees) {
  // The post at 51 degrees is 30 past the edge: the gap is too narrow, and the search resumes after the post,
  // whose own edge at 56 degrees (0.35 m) is followed by a clear 30 degrees.
  const std::vector<SweepReading> narrow = right_edge_with_post_at(51, 56);
  const std::optional<SuddenPoint> point =
      find_sudden_point(Sweep{narrow, kLidarMax_m}, SweepSide::kRight, PointBugParams{});
  ASSERT_TRUE(point.has_value());
  EXPECT_EQ(point->edge_angle_deg, 56);
  EXPECT_NEAR(point->edge_range_m, 0.35, kTolerance);
  EXPECT_NEAR(point->turn_deg, 71.0, kTolerance);
  EXPECT_NEAR(point->distance_m, 0.47, kTolerance);
  // At 52 degrees the post is 31 past the edge, the reading the listing takes but never checks: the gap holds.
  const std::vector<SweepReading> wide = right_edge_with_post_at(52, 56);
  const std::optional<SuddenPoint> kept =
      find_sudden_point(Sweep{wide, kLidarMax_m}, SweepSide::kRight, PointBugParams{});
  ASSERT_TRUE(kept.has_value());
  EXPECT_EQ(kept->edge_angle_deg, 21);
  EXPECT_NEAR(kept->turn_deg, 36.0, kTolerance);
}

TEST(PointBugTest, NoSuddenPointWithin90DegreesOnEitherSideIsNoPath) {
  // Enclosed at 0.25 m all round; and a jump at exactly 89 degrees, which the listing's limit check discards.
  for (const int jump_deg : {91, 89}) {
    const std::vector<SweepReading> readings =
        sweep_of([=](int degree) { return std::abs(degree) >= jump_deg ? 1.5 : 0.25; });
    PointBugBehaviour behaviour(PointBugParams{}, 1.0, 0.0);
    const PointBugDecision decision = behaviour.decide(Pose2{}, Sweep{readings, kLidarMax_m});
    EXPECT_EQ(decision.state, BehaviourState::kNoPath) << jump_deg;
    EXPECT_TRUE(decision.stop);
    EXPECT_EQ(decision.linear_mps, 0.0);
    EXPECT_EQ(decision.angular_radps, 0.0);
    EXPECT_FALSE(decision.right.has_value());
    EXPECT_FALSE(decision.left.has_value());
    EXPECT_EQ(behaviour.state(), PointBugBehaviour::State::kNoPath);
  }
  // A jump at 88 degrees still counts.
  const std::vector<SweepReading> readings = sweep_of([](int degree) { return degree <= -88 ? 1.5 : 0.25; });
  PointBugBehaviour behaviour(PointBugParams{}, 1.0, 0.0);
  const PointBugDecision decision = behaviour.decide(Pose2{}, Sweep{readings, kLidarMax_m});
  ASSERT_TRUE(decision.sudden_point.has_value());
  EXPECT_EQ(decision.sudden_point->edge_angle_deg, 87);
}

// Seed 003 §2.2.2 (Fig-2.11): PointBug takes the point of minimum angular deviation (B, 6 degrees) although the
// path through the other (A, 24.4 degrees) is shorter; the listing keeps that rule (angr < angl; dr and dl are
// declared but unused). Recreated with a wall receding to the right whose edge is at 6 degrees but far, and a near
// edge at 24 degrees on the left.
TEST(PointBugTest, SeedExperimentMinimumDeviationBeatsTheShorterPath) {
  const std::vector<SweepReading> readings = sweep_of([](int degree) {
    if (degree <= 0 && degree >= -6) return 0.29 + 0.085 * -degree;  // oblique wall, 0.29 .. 0.80 m
    if (degree > 0 && degree <= 24) return 0.29;
    return 1.9;
  });
  const double goal_x = 0.9;
  PointBugBehaviour behaviour(PointBugParams{}, goal_x, 0.0);
  const PointBugDecision decision = behaviour.decide(Pose2{}, Sweep{readings, kLidarMax_m});
  ASSERT_TRUE(decision.right && decision.left);
  EXPECT_EQ(decision.right->edge_angle_deg, 6);
  EXPECT_EQ(decision.left->edge_angle_deg, 24);
  EXPECT_EQ(decision.sudden_point->side, SweepSide::kRight);
  const auto path_through = [&](const SuddenPoint& p) {
    const double x = p.distance_m * std::cos(p.turn_rad);
    const double y = p.distance_m * std::sin(p.turn_rad);
    return p.distance_m + std::hypot(goal_x - x, y);
  };
  EXPECT_LT(path_through(*decision.left), path_through(*decision.right));
}

TEST(PointBugTest, WholeRunAroundAWallReachesTheGoalThroughTheSuddenPoint) {
  const std::vector<Segment> walls{{0.4, -0.1, 0.4, 0.6}};
  const DrivenRun run = run_to_goal(Pose2{0.0, 0.0, 0.0}, 1.0, 0.0, walls);
  EXPECT_EQ(run.final_state, "reached");
  ASSERT_EQ(run.sudden_points.size(), 1U);
  EXPECT_EQ(run.sudden_points[0].side, SweepSide::kRight);
  EXPECT_GT(run.sudden_points[0].world_x_m, 0.4);  // the corrected point lies past the wall's end
  EXPECT_LT(run.sudden_points[0].world_y_m, -0.1);
  // Executing turn_to_sudden_point's target as drive_goto turns and drives at once, so drive_to_sudden_point only
  // appears when a server follows the body velocity instead.
  EXPECT_EQ(run.states, (std::vector<std::string>{"step_to_goal", "turn_to_sudden_point", "aim_at_goal", "step_to_goal",
                                                  "reached"}));
  EXPECT_LE(std::hypot(run.final_pose.x - 1.0, run.final_pose.y), PointBugParams{}.goal_tolerance_m);
}

TEST(PointBugTest, ValidationErrorsNameTheField) {
  using occgeo::testing::invalid_argument_message;
  const auto params_error = [](auto mutate) {
    PointBugParams params;
    mutate(params);
    return invalid_argument_message([&] { params.validate(); });
  };
  EXPECT_EQ(invalid_argument_message([] { PointBugParams{}.validate(); }), "");
  EXPECT_NE(params_error([](PointBugParams& p) { p.obstacle_range_m = 0.0; }).find("obstacle_range_m"),
            std::string::npos);
  EXPECT_NE(params_error([](PointBugParams& p) { p.sudden_jump_m = -1.0; }).find("sudden_jump_m"), std::string::npos);
  EXPECT_NE(params_error([](PointBugParams& p) { p.gap_deg = 0; }).find("gap_deg"), std::string::npos);
  EXPECT_NE(params_error([](PointBugParams& p) { p.angle_extension_deg = 100.0; }).find("angle_extension_deg"),
            std::string::npos);
  EXPECT_NE(params_error([](PointBugParams& p) {
              p.distance_extension_m = std::numeric_limits<double>::infinity();
            }).find("distance_extension_m"),
            std::string::npos);
  EXPECT_NE(params_error([](PointBugParams& p) { p.sweep_limit_deg = 1; }).find("sweep_limit_deg"), std::string::npos);
  EXPECT_NE(invalid_argument_message([] { PointBugBehaviour(PointBugParams{}, std::nan(""), 0.0); }).find("goal_x_m"),
            std::string::npos);

  PointBugBehaviour behaviour(PointBugParams{}, 1.0, 0.0);
  const std::vector<SweepReading> side_only{{radians(30.0), 1.0}};
  EXPECT_NE(invalid_argument_message([&] {
              (void)behaviour.decide(Pose2{}, Sweep{side_only, kLidarMax_m});
            }).find("Sweep.readings"),
            std::string::npos);
  const std::vector<SweepReading> negative{{0.0, -1.0}};
  EXPECT_NE(invalid_argument_message([&] {
              (void)behaviour.decide(Pose2{}, Sweep{negative, kLidarMax_m});
            }).find("Sweep.readings.range_m"),
            std::string::npos);
  EXPECT_NE(invalid_argument_message([&] {
              (void)behaviour.decide(Pose2{std::nan(""), 0.0, 0.0}, Sweep{negative, 1.0});
            }).find("Pose2.x"),
            std::string::npos);
}

}  // namespace
}  // namespace occgeo::service::control
