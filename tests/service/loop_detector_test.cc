// The loop and stall detector on synthetic trajectories: circling (PointBug's endless loop, seed 003 Fig 2.10; PTEM
// guidance's loop, seed 004 §6.3.2) is caught, a straight approach, a detour that makes progress and a spiral that
// closes in on the goal are not.
#include "occgeo/service/control/loop_detector.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace occgeo::service::control {
namespace {

constexpr double kDt_s = 0.1;
constexpr double kSpeed_mps = 0.3;

struct Outcome {
  std::optional<double> loop_time_s;
  std::optional<double> stall_time_s;
  LoopStatus last;
};

// Feeds the pose at t = 0, dt, 2 dt, ... up to duration_s.
Outcome run(LoopDetector& detector, double duration_s, const std::function<Pose2(double)>& pose_at,
            std::optional<Eigen::Vector2d> goal_W, BehaviourState state = BehaviourState::kNone) {
  Outcome outcome;
  const int steps = static_cast<int>(std::round(duration_s / kDt_s));
  for (int i = 0; i <= steps; ++i) {
    const double t = i * kDt_s;
    outcome.last = detector.update({pose_at(t), t, goal_W, state});
    if (outcome.last.loop && !outcome.loop_time_s) outcome.loop_time_s = t;
    if (outcome.last.stalled && !outcome.stall_time_s) outcome.stall_time_s = t;
  }
  return outcome;
}

// Counter-clockwise on a circle of radius_m about (cx, cy), starting at angle 0, at kSpeed_mps.
std::function<Pose2(double)> circling(double cx, double cy, double radius_m) {
  return [=](double t) {
    const double angle = kSpeed_mps * t / radius_m;
    return Pose2{cx + radius_m * std::cos(angle), cy + radius_m * std::sin(angle), angle + std::numbers::pi / 2.0};
  };
}

// Along a polyline at kSpeed_mps, heading along each leg; stands at the end.
std::function<Pose2(double)> polyline(std::vector<Eigen::Vector2d> corners) {
  return [corners = std::move(corners)](double t) {
    double left_m = kSpeed_mps * t;
    for (std::size_t i = 0; i + 1 < corners.size(); ++i) {
      const Eigen::Vector2d leg = corners[i + 1] - corners[i];
      const double yaw = std::atan2(leg.y(), leg.x());
      if (left_m <= leg.norm() || i + 2 == corners.size()) {
        const Eigen::Vector2d p = corners[i] + leg.normalized() * std::min(left_m, leg.norm());
        return Pose2{p.x(), p.y(), yaw};
      }
      left_m -= leg.norm();
    }
    return Pose2{corners.back().x(), corners.back().y(), 0.0};
  };
}

TEST(LoopDetector, CirclingIsALoopOnTheThirdPass) {
  LoopDetectorParams params;
  params.stall_time_s = 120.0;  // with the default 30 s the circling robot is called stalled first
  LoopDetector detector(params);
  // A 1 m circle whose start is its closest point to the goal: one lap takes 2 pi / 0.3 = 20.9 s, so the third pass
  // through the start comes at 41.9 s.
  const double lap_s = 2.0 * std::numbers::pi * 1.0 / kSpeed_mps;
  const Outcome outcome = run(detector, 80.0, circling(2.0, 0.0, 1.0), Eigen::Vector2d(10.0, 0.0));
  ASSERT_TRUE(outcome.loop_time_s.has_value());
  // The pass is detected when the robot comes within revisit_radius_m (0.3 m, 1 s at 0.3 m/s) of the first one.
  EXPECT_GT(*outcome.loop_time_s, 2.0 * lap_s - 1.5);
  EXPECT_LT(*outcome.loop_time_s, 2.0 * lap_s + 0.5);
  EXPECT_EQ(outcome.last.reason, LoopReason::kLoop);
  EXPECT_GE(outcome.last.passes, 2);
  EXPECT_LT((outcome.last.loop_point_W - Eigen::Vector2d(3.0, 0.0)).norm(), 0.35);
}

TEST(LoopDetector, CirclingTowardAGoalIsAStallThenALoop) {
  LoopDetector detector(LoopDetectorParams{});
  const Outcome outcome = run(detector, 80.0, circling(2.0, 0.0, 1.0), Eigen::Vector2d(10.0, 0.0));
  // The closest point of the circle is first reached at the start: no progress from then on.
  ASSERT_TRUE(outcome.stall_time_s.has_value());
  EXPECT_NEAR(*outcome.stall_time_s, 30.0, kDt_s / 2.0);
  EXPECT_TRUE(outcome.loop_time_s.has_value());
  EXPECT_EQ(outcome.last.reason, LoopReason::kStall);
}

TEST(LoopDetector, CirclingWithoutAGoalIsALoop) {
  LoopDetector detector(LoopDetectorParams{});
  const Outcome outcome = run(detector, 60.0, circling(0.0, 0.0, 0.8), std::nullopt);
  EXPECT_TRUE(outcome.loop_time_s.has_value());
  EXPECT_FALSE(outcome.stall_time_s.has_value());  // no goal, no stall
}

TEST(LoopDetector, PointBugStyleCycleOfLegsIsALoop) {
  // Seed 003 Fig 2.10: PointBug drives from sudden point to sudden point round the same obstacles for ever. Straight
  // legs with turns on the spot, the same states at the same places each time round.
  std::vector<Eigen::Vector2d> corners;
  for (int lap = 0; lap < 3; ++lap) {
    for (const Eigen::Vector2d& corner : {Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(2.0, 0.5),
                                          Eigen::Vector2d(1.5, 2.5), Eigen::Vector2d(-0.5, 1.5)}) {
      corners.push_back(corner);
    }
  }
  corners.push_back({0.0, 0.0});
  const auto pose_at = polyline(corners);
  LoopDetector detector(LoopDetectorParams{});
  bool loop = false;
  for (int i = 0; i <= static_cast<int>(90.0 / kDt_s) && !loop; ++i) {
    const double t = i * kDt_s;
    const Pose2 pose = pose_at(t);
    // The state: driving to the sudden point on legs toward +x, stepping toward the goal otherwise.
    const BehaviourState state =
        std::cos(pose.theta) > 0.0 ? BehaviourState::kDriveToSuddenPoint : BehaviourState::kStepToGoal;
    loop = detector.update({pose, t, Eigen::Vector2d(4.0, 4.0), state}).loop;
  }
  EXPECT_TRUE(loop);
  EXPECT_GE(detector.status().passes, 2);
}

TEST(LoopDetector, OneRevisitIsNotYetALoop) {
  LoopDetector detector(LoopDetectorParams{});
  // 1.5 laps: the start is passed twice.
  const double lap_s = 2.0 * std::numbers::pi * 1.0 / kSpeed_mps;
  const Outcome outcome = run(detector, 1.5 * lap_s, circling(2.0, 0.0, 1.0), Eigen::Vector2d(10.0, 0.0));
  EXPECT_FALSE(outcome.loop_time_s.has_value());
  EXPECT_EQ(outcome.last.passes, 1);  // half way round the second lap: passed here once, a lap ago
}

TEST(LoopDetector, StraightApproachIsNeither) {
  LoopDetector detector(LoopDetectorParams{});
  const Outcome outcome = run(detector, 36.0, polyline({{0.0, 0.0}, {11.0, 0.0}}), Eigen::Vector2d(12.0, 0.0));
  EXPECT_FALSE(outcome.loop_time_s.has_value());
  EXPECT_FALSE(outcome.stall_time_s.has_value());
  EXPECT_EQ(outcome.last.reason, LoopReason::kNone);
  EXPECT_LT(outcome.last.since_progress_s, 1.0);
  EXPECT_NEAR(*outcome.last.best_goal_distance_m, 12.0 - 36.0 * kSpeed_mps, 1e-9);
}

TEST(LoopDetector, DetourThatMakesProgressIsNeither) {
  LoopDetector detector(LoopDetectorParams{});
  // Back and around a wall between the robot and the goal: the goal distance grows from 6 m to 8.1 m and only beats
  // its start value again after 22.6 s, inside the 30 s stall time; no place is passed twice.
  const Outcome outcome =
      run(detector, 70.0, polyline({{0.0, 0.0}, {-1.0, 4.0}, {7.0, 4.0}, {6.2, 0.5}}), Eigen::Vector2d(6.0, 0.0));
  EXPECT_FALSE(outcome.loop_time_s.has_value());
  EXPECT_FALSE(outcome.stall_time_s.has_value());
  EXPECT_GT(outcome.last.since_progress_s, 10.0);  // it stood at the end for a while: progress tracking is live
}

TEST(LoopDetector, SpiralClosingInOnTheGoalIsNotALoop) {
  LoopDetector detector(LoopDetectorParams{});
  // Laps of a 1 m circle whose centre moves 0.5 m toward the goal per lap: the same headings come back every lap,
  // but never within 0.3 m of an earlier pass.
  const double lap_s = 2.0 * std::numbers::pi / kSpeed_mps;
  const auto spiral = [&](double t) {
    const Pose2 on_circle = circling(0.0, 0.0, 1.0)(t);
    return Pose2{on_circle.x + 0.5 * t / lap_s, on_circle.y, on_circle.theta};
  };
  const Outcome outcome = run(detector, 5.0 * lap_s, spiral, Eigen::Vector2d(20.0, 0.0));
  EXPECT_FALSE(outcome.loop_time_s.has_value());
  EXPECT_FALSE(outcome.stall_time_s.has_value());
}

TEST(LoopDetector, StandingStillIsAStallNotALoop) {
  LoopDetector detector(LoopDetectorParams{});
  const Outcome outcome = run(
      detector, 40.0,
      [](double) {
        return Pose2{1.0, 1.0, 0.3};
      },
      Eigen::Vector2d(5.0, 5.0));
  ASSERT_TRUE(outcome.stall_time_s.has_value());
  EXPECT_NEAR(*outcome.stall_time_s, 30.0, kDt_s / 2.0);
  EXPECT_FALSE(outcome.loop_time_s.has_value());
  EXPECT_EQ(outcome.last.reason, LoopReason::kStall);
}

TEST(LoopDetector, PassesInAnotherStateDoNotCount) {
  LoopDetectorParams params;
  LoopDetector same_state(params);
  LoopDetector alternating(params);
  const auto pose_at = circling(2.0, 0.0, 1.0);
  const double lap_s = 2.0 * std::numbers::pi / kSpeed_mps;
  bool alternating_loop = false;
  for (int i = 0; i <= static_cast<int>(3.2 * lap_s / kDt_s); ++i) {
    const double t = i * kDt_s;
    same_state.update({pose_at(t), t, std::nullopt, BehaviourState::kDriveToSuddenPoint});
    // Each lap in a different state: the robot is doing something new each time round.
    const int lap = static_cast<int>(t / lap_s);
    const auto state = static_cast<BehaviourState>(1 + lap);
    alternating_loop = alternating.update({pose_at(t), t, std::nullopt, state}).loop || alternating_loop;
  }
  EXPECT_TRUE(same_state.status().loop);
  EXPECT_FALSE(alternating_loop);
}

TEST(LoopDetector, ResetClearsTheVerdict) {
  LoopDetector detector(LoopDetectorParams{});
  const Outcome circled = run(detector, 60.0, circling(0.0, 0.0, 0.8), std::nullopt);
  ASSERT_TRUE(circled.last.loop);
  detector.reset();
  EXPECT_FALSE(detector.status().loop);
  EXPECT_EQ(detector.status().reason, LoopReason::kNone);
  EXPECT_EQ(detector.sample_count(), 0U);
  const LoopStatus next = detector.update({Pose2{0.8, 0.0, 1.57}, 60.1, std::nullopt, BehaviourState::kNone});
  EXPECT_FALSE(next.loop);
  EXPECT_EQ(next.passes, 0);
}

TEST(LoopDetector, RejectsBadInputNamingTheField) {
  LoopDetectorParams params;
  params.revisit_radius_m = -1.0;
  EXPECT_THROW(
      {
        try {
          LoopDetector detector(params);
        } catch (const std::invalid_argument& error) {
          EXPECT_NE(std::string(error.what()).find("revisit_radius_m"), std::string::npos) << error.what();
          throw;
        }
      },
      std::invalid_argument);
  LoopDetector detector(LoopDetectorParams{});
  detector.update({Pose2{0.0, 0.0, 0.0}, 5.0, std::nullopt, BehaviourState::kNone});
  try {
    detector.update({Pose2{0.0, 0.0, 0.0}, 4.0, std::nullopt, BehaviourState::kNone});
    ADD_FAILURE() << "time going backwards was accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("time_s"), std::string::npos) << error.what();
  }
  try {
    detector.update({Pose2{std::nan(""), 0.0, 0.0}, 6.0, std::nullopt, BehaviourState::kNone});
    ADD_FAILURE() << "a NaN pose was accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("pose.x"), std::string::npos) << error.what();
  }
  EXPECT_EQ(detector.sample_count(), 1U);  // the rejected observations changed nothing
}

}  // namespace
}  // namespace occgeo::service::control
