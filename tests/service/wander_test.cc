// The wander and avoid behaviours of seed 001 (§2.1–2.2, Figures 1–2) on synthetic 16-sonar rings and laser scans,
// ray-cast against a wall in the world frame while the behaviour's own commands turn the robot.
#include "occgeo/service/control/wander.h"

#include <gtest/gtest.h>

#include "../support/error_message.h"

#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace occgeo::service::control {
namespace {

constexpr double kSonarMax_m = 6.5;  // the Scout's sonars read up to about 6.5 m

RangeSet ring(const std::vector<double>& ranges_m) {
  const std::vector<double> bearings = scout_sonar_bearings_rad();
  return range_set_from_ring(bearings, ranges_m, kSonarMax_m);
}

RangeSet clear_ring() { return ring(std::vector<double>(16, kSonarMax_m)); }

// A ring whose one sonar sees something at range_m.
RangeSet ring_with(std::size_t sonar, double range_m) {
  std::vector<double> ranges(16, kSonarMax_m);
  ranges[sonar] = range_m;
  return ring(ranges);
}

// The ring seen from the origin at yaw_rad with a wall along x = wall_x_m (world frame).
RangeSet ring_facing_wall(double yaw_rad, double wall_x_m) {
  std::vector<double> ranges;
  for (const double bearing : scout_sonar_bearings_rad()) {
    const double c = std::cos(yaw_rad + bearing);
    ranges.push_back(c > 1e-9 ? std::min(wall_x_m / c, kSonarMax_m) : kSonarMax_m);
  }
  return ring(ranges);
}

WanderParams seeded(std::uint64_t seed) {
  WanderParams params;
  params.seed = seed;
  return params;
}

// Odometry for one 0.1 s cycle of the last command.
WanderProgress progress_of(const WanderDecision& last) {
  return WanderProgress{0.1, std::abs(last.linear_mps) * 0.1, std::abs(last.angular_radps) * 0.1};
}

struct Trace {
  std::vector<std::string> states;
  std::vector<double> angular;
  std::vector<double> run_lengths;  // the length each straight run started with
  int runs_ended = 0;               // straight runs that reached their length
  int turns_after_run = 0;          // of those, how many went on to turn_little
};

// Drives the behaviour for cycles in open space, recording its decisions.
Trace wander_in_open_space(const WanderParams& params, int cycles) {
  WanderBehaviour behaviour(params);
  Trace trace;
  WanderDecision last = behaviour.decide(clear_ring(), WanderProgress{});
  trace.run_lengths.push_back(last.remaining_m);
  for (int cycle = 0; cycle < cycles; ++cycle) {
    const WanderDecision next = behaviour.decide(clear_ring(), progress_of(last));
    const bool was_straight = last.state == BehaviourState::kWanderStraight;
    const bool new_run =
        next.state == BehaviourState::kWanderStraight && (!was_straight || next.remaining_m > last.remaining_m);
    if (was_straight && (next.state == BehaviourState::kWanderTurn || new_run)) {
      ++trace.runs_ended;
      if (next.state == BehaviourState::kWanderTurn) ++trace.turns_after_run;
    }
    if (new_run) trace.run_lengths.push_back(next.remaining_m);
    trace.states.emplace_back(name(next.state));
    trace.angular.push_back(next.angular_radps);
    last = next;
  }
  return trace;
}

TEST(WanderTest, SameSeedGivesSameDecisions) {
  const Trace first = wander_in_open_space(seeded(42), 5000);
  const Trace second = wander_in_open_space(seeded(42), 5000);
  EXPECT_EQ(first.states, second.states);
  EXPECT_EQ(first.angular, second.angular);
  EXPECT_EQ(first.run_lengths, second.run_lengths);
}

TEST(WanderTest, DifferentSeedGivesDifferentRuns) {
  const Trace first = wander_in_open_space(seeded(42), 5000);
  const Trace second = wander_in_open_space(seeded(43), 5000);
  EXPECT_NE(first.run_lengths, second.run_lengths);
  EXPECT_NE(first.states, second.states);
}

TEST(WanderTest, StraightRunsHaveLengthsWithinTheConfiguredRange) {
  WanderParams params = seeded(7);
  params.run_length_min_m = 0.8;
  params.run_length_max_m = 1.2;
  const Trace trace = wander_in_open_space(params, 20000);
  ASSERT_GT(trace.run_lengths.size(), 100U);
  for (const double length : trace.run_lengths) {
    EXPECT_GE(length, 0.8);
    EXPECT_LE(length, 1.2);
  }
}

TEST(WanderTest, TurnLittleFollowsAboutHalfTheRuns) {
  const Trace trace = wander_in_open_space(seeded(11), 200000);
  ASSERT_GT(trace.runs_ended, 1000);
  const double fraction = static_cast<double>(trace.turns_after_run) / trace.runs_ended;
  // Binomial with p = 0.5: the standard deviation is below 0.016 at 1000 runs; 0.06 is about four of them.
  EXPECT_NEAR(fraction, 0.5, 0.06);
  // Both directions of turn_little occur.
  bool left = false;
  bool right = false;
  for (std::size_t cycle = 0; cycle < trace.states.size(); ++cycle) {
    if (trace.states[cycle] != "wander_turn") continue;
    left = left || trace.angular[cycle] > 0.0;
    right = right || trace.angular[cycle] < 0.0;
  }
  EXPECT_TRUE(left);
  EXPECT_TRUE(right);
}

TEST(WanderTest, WanderTurnTurnsInPlaceAtTheConfiguredRate) {
  const Trace trace = wander_in_open_space(seeded(3), 20000);
  for (std::size_t cycle = 0; cycle < trace.states.size(); ++cycle) {
    if (trace.states[cycle] == "wander_turn") {
      EXPECT_EQ(std::abs(trace.angular[cycle]), WanderParams{}.turn_speed_radps);
    }
    if (trace.states[cycle] == "wander_straight") {
      EXPECT_EQ(trace.angular[cycle], 0.0);
    }
  }
}

TEST(WanderTest, FrontalObstacleMakesAvoidTurnOneWayUntilTheFrontIsClear) {
  int turned_left = 0;
  int turned_right = 0;
  for (std::uint64_t seed = 0; seed < 40; ++seed) {
    WanderBehaviour behaviour(seeded(seed));
    double yaw = 0.0;
    WanderDecision decision = behaviour.decide(ring_facing_wall(yaw, 0.4), WanderProgress{});
    ASSERT_EQ(decision.state, BehaviourState::kAvoidTurn);
    ASSERT_TRUE(decision.front_blocked);
    const double direction = decision.angular_radps;
    ASSERT_NE(direction, 0.0);
    EXPECT_EQ(decision.linear_mps, 0.0);
    (direction > 0.0 ? turned_left : turned_right) += 1;
    int cycles = 0;
    while (decision.state == BehaviourState::kAvoidTurn) {
      ASSERT_LT(++cycles, 1000);
      EXPECT_EQ(decision.angular_radps, direction) << "avoid changed direction";
      EXPECT_EQ(decision.linear_mps, 0.0);
      yaw += decision.angular_radps * 0.1;
      const RangeSet readings = ring_facing_wall(yaw, 0.4);
      decision = behaviour.decide(readings, progress_of(decision));
    }
    EXPECT_EQ(decision.state, BehaviourState::kWanderStraight);
    EXPECT_FALSE(decision.front_blocked);
    EXPECT_FALSE(behaviour.front_blocked(ring_facing_wall(yaw, 0.4)));
    // The frontal sector (-67.5..+45 degrees) no longer points at the wall closer than 0.6 m: the wall is at
    // least 48 degrees outside it.
    EXPECT_GT(std::abs(yaw), 0.5);
  }
  // The direction is a fair coin: both occur over 40 seeds.
  EXPECT_GT(turned_left, 5);
  EXPECT_GT(turned_right, 5);
}

TEST(WanderTest, AvoidSubsumesAStraightRunMidway) {
  WanderBehaviour behaviour(seeded(5));
  WanderDecision decision = behaviour.decide(clear_ring(), WanderProgress{});
  ASSERT_EQ(decision.state, BehaviourState::kWanderStraight);
  decision = behaviour.decide(ring_with(15, 0.3), progress_of(decision));  // sonar 15: 22.5 degrees right
  EXPECT_EQ(decision.state, BehaviourState::kAvoidTurn);
  decision = behaviour.decide(clear_ring(), progress_of(decision));
  EXPECT_EQ(decision.state, BehaviourState::kWanderStraight);
}

TEST(WanderTest, EveryFrontSonarTriggersAvoid) {
  for (const std::size_t sonar : {0U, 1U, 2U, 13U, 14U, 15U}) {
    WanderBehaviour behaviour(seeded(1));
    EXPECT_EQ(behaviour.decide(ring_with(sonar, 0.59), WanderProgress{}).state, BehaviourState::kAvoidTurn)
        << "sonar " << sonar;
    WanderBehaviour far(seeded(1));
    EXPECT_EQ(far.decide(ring_with(sonar, 0.61), WanderProgress{}).state, BehaviourState::kWanderStraight)
        << "sonar " << sonar;
  }
}

TEST(WanderTest, ObstaclesBesideAndBehindDoNotTriggerAvoid) {
  for (std::size_t sonar = 3; sonar <= 12; ++sonar) {
    WanderBehaviour behaviour(seeded(1));
    const WanderDecision decision = behaviour.decide(ring_with(sonar, 0.1), WanderProgress{});
    EXPECT_EQ(decision.state, BehaviourState::kWanderStraight) << "sonar " << sonar;
    EXPECT_FALSE(decision.front_blocked);
  }
}

TEST(WanderTest, LaserScanConvertsAndOnlyItsFrontTriggersAvoid) {
  // A 240 degree scan at 1 degree: an obstacle at 0.2 m at bearings beyond -67.5 degrees (right) is ignored, one
  // at +10 degrees triggers avoid.
  std::vector<float> ranges(241, 5.0F);
  for (std::size_t beam = 0; beam < 50; ++beam) ranges[beam] = 0.2F;  // -120..-71 degrees
  const ScanView scan{-120.0 * std::numbers::pi / 180.0, std::numbers::pi / 180.0, ranges, 5.6};
  const RangeSet set = range_set_from_scan(scan);
  ASSERT_EQ(set.beams.size(), 241U);
  EXPECT_DOUBLE_EQ(set.beams[120].bearing_rad, 0.0);
  WanderBehaviour behaviour(seeded(1));
  EXPECT_EQ(behaviour.decide(set, WanderProgress{}).state, BehaviourState::kWanderStraight);
  ranges[130] = 0.2F;  // +10 degrees
  EXPECT_EQ(behaviour.decide(range_set_from_scan(scan), WanderProgress{}).state, BehaviourState::kAvoidTurn);
}

TEST(WanderTest, ProgressWithoutOdometryIsEstimatedFromTheLastCommand) {
  WanderParams params = seeded(9);
  params.run_length_min_m = 1.0;
  params.run_length_max_m = 1.0;
  WanderBehaviour behaviour(params);
  WanderDecision decision = behaviour.decide(clear_ring(), WanderProgress{});
  EXPECT_DOUBLE_EQ(decision.remaining_m, 1.0);
  decision = behaviour.decide(clear_ring(), WanderProgress{1.0, std::nullopt, std::nullopt});  // 0.3 m at 0.3 m/s
  EXPECT_DOUBLE_EQ(decision.remaining_m, 0.7);
}

TEST(WanderTest, ValidationErrorsNameTheField) {
  using occgeo::testing::invalid_argument_message;
  const auto params_error = [](auto mutate) {
    WanderParams params;
    mutate(params);
    return invalid_argument_message([&] { params.validate(); });
  };
  EXPECT_EQ(invalid_argument_message([] { WanderParams{}.validate(); }), "");
  EXPECT_NE(params_error([](WanderParams& p) { p.obstacle_threshold_m = 0.0; }).find("obstacle_threshold_m"),
            std::string::npos);
  EXPECT_NE(params_error([](WanderParams& p) { p.run_length_max_m = 0.1; }).find("run_length_max_m"),
            std::string::npos);
  EXPECT_NE(params_error([](WanderParams& p) { p.turn_probability = 1.5; }).find("turn_probability"),
            std::string::npos);
  EXPECT_NE(params_error([](WanderParams& p) { p.front_sector_left_rad = -0.1; }).find("front_sector_left_rad"),
            std::string::npos);
  EXPECT_NE(params_error([](WanderParams& p) { p.turn_little_max_rad = 0.01; }).find("turn_little_max_rad"),
            std::string::npos);
  EXPECT_NE(params_error([](WanderParams& p) {
              p.turn_speed_radps = std::numeric_limits<double>::quiet_NaN();
            }).find("turn_speed_radps"),
            std::string::npos);
  EXPECT_NE(invalid_argument_message([] {
              WanderBehaviour behaviour{[] {
                WanderParams p;
                p.linear_speed_mps = -1.0;
                return p;
              }()};
            }).find("linear_speed_mps"),
            std::string::npos);

  WanderBehaviour behaviour(WanderParams{});
  const std::vector<double> two{0.0, 0.1};
  const std::vector<double> one{1.0};
  EXPECT_NE(invalid_argument_message([&] { (void)range_set_from_ring(two, one, 5.0); }).find("ranges_m"),
            std::string::npos);
  const RangeSet behind = range_set_from_ring(std::vector<double>{std::numbers::pi}, one, 5.0);
  EXPECT_NE(invalid_argument_message([&] { (void)behaviour.decide(behind, WanderProgress{}); }).find("RangeSet.beams"),
            std::string::npos);
  EXPECT_NE(invalid_argument_message([&] {
              (void)behaviour.decide(clear_ring(), WanderProgress{-1.0, {}, {}});
            }).find("WanderProgress.elapsed_s"),
            std::string::npos);
  RangeSet bad = clear_ring();
  bad.range_max_m = 0.0;
  EXPECT_NE(
      invalid_argument_message([&] { (void)behaviour.decide(bad, WanderProgress{}); }).find("RangeSet.range_max_m"),
      std::string::npos);
}

}  // namespace
}  // namespace occgeo::service::control
