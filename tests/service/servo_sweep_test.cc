// Seed 003's servo-swept LIDAR on the server: readings assembled into sweeps, and PointBug steering by them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "occgeo/service/control/behaviour.h"
#include "occgeo/service/control/servo_sweep.h"

namespace occgeo::service::control {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
const ServoSweepLimits kActivityBotServo{-90.0 * kDeg, 90.0 * kDeg, 1.0 * kDeg, 40.0};

// The servo going back and forth over its travel one step at a time, from servo_min, as the simulator's does.
class PingPongServo {
 public:
  double next() {
    const double angle = (-90 + position_) * kDeg;
    position_ += direction_;
    if (position_ == 180 || position_ == 0) direction_ = -direction_;
    return angle;
  }

 private:
  int position_ = 0;
  int direction_ = 1;
};

TEST(ServoSweepAssembler, CompletesOneSweepPerPassInEitherDirection) {
  ServoSweepAssembler assembler(kActivityBotServo);
  PingPongServo servo;
  std::vector<int> completed_at;
  for (int i = 0; i < 400; ++i) {
    const double angle = servo.next();
    if (assembler.add(angle, 2.0 + angle, 0.02 * i)) completed_at.push_back(i);
  }
  // min to max (181 readings), then max back to min: each pass completes when it reaches the far end.
  ASSERT_EQ(completed_at, (std::vector<int>{180, 360}));
  ASSERT_EQ(assembler.last_sweep().size(), 181U);
  EXPECT_NEAR(assembler.last_sweep().front().angle_rad, -90.0 * kDeg, 1e-12);
  EXPECT_NEAR(assembler.last_sweep().back().angle_rad, 90.0 * kDeg, 1e-12);
  EXPECT_NEAR(assembler.last_sweep()[90].range_m, 2.0, 1e-9);
  EXPECT_DOUBLE_EQ(assembler.last_sweep_started_s(), 0.02 * 180) << "the second pass began where the first ended";
}

TEST(ServoSweepAssembler, NoReturnReadsInfiniteAndTheNewestReadingAtAnAngleCounts) {
  ServoSweepAssembler assembler(kActivityBotServo);
  assembler.add(0.0, 3.0, 0.0);
  assembler.add(0.0, 2.0, 0.1);  // the servo came back to 0: newer
  assembler.add(-90.0 * kDeg, 40.0, 0.2);
  ASSERT_TRUE(assembler.add(90.0 * kDeg, 55.0, 0.3));
  const std::vector<SweepReading>& sweep = assembler.last_sweep();
  ASSERT_EQ(sweep.size(), 3U);
  EXPECT_TRUE(std::isinf(sweep[0].range_m));
  EXPECT_DOUBLE_EQ(sweep[1].range_m, 2.0);
  EXPECT_TRUE(std::isinf(sweep[2].range_m));
}

TEST(ServoSweepAssembler, ARestartDropsTheSweepInProgress) {
  ServoSweepAssembler assembler(kActivityBotServo);
  assembler.add(-90.0 * kDeg, 1.0, 0.0);
  assembler.restart();
  EXPECT_FALSE(assembler.add(90.0 * kDeg, 1.0, 0.1)) << "servo_min was covered before the restart only";
  EXPECT_TRUE(assembler.add(-90.0 * kDeg, 1.0, 0.2));
  EXPECT_EQ(assembler.last_sweep().size(), 2U);
}

TEST(ServoSweepAssembler, RefusesAnglesOutsideTheTravelAndBadLimitsNamingTheField) {
  ServoSweepAssembler assembler(kActivityBotServo);
  try {
    assembler.add(100.0 * kDeg, 1.0, 0.0);
    FAIL() << "an angle beyond servo_max was taken";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("ServoRange.servo_angle_rad"), std::string::npos) << error.what();
  }
  EXPECT_THROW(assembler.add(0.0, std::nan(""), 0.0), std::invalid_argument);
  ServoSweepLimits backwards = kActivityBotServo;
  backwards.servo_max_rad = backwards.servo_min_rad;
  try {
    ServoSweepAssembler bad(backwards);
    FAIL() << "an empty servo travel was taken";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("servo_max_rad"), std::string::npos) << error.what();
  }
}

struct Segment {
  double x0, y0, x1, y1;
};

// The single beam from (x, y) along heading: distance to the nearest segment, else the sensor's maximum.
double cast(double x, double y, double heading, const std::vector<Segment>& walls) {
  const double dx = std::cos(heading);
  const double dy = std::sin(heading);
  double best = 40.0;
  for (const Segment& w : walls) {
    const double ex = w.x1 - w.x0;
    const double ey = w.y1 - w.y0;
    const double denom = dx * ey - dy * ex;
    if (std::abs(denom) < 1e-12) continue;
    const double t = ((w.x0 - x) * ey - (w.y0 - y) * ex) / denom;
    const double u = ((w.x0 - x) * dy - (w.y0 - y) * dx) / denom;
    if (t > 0.0 && u >= 0.0 && u <= 1.0) best = std::min(best, t);
  }
  return best;
}

double distance_to(double x, double y, const Segment& w) {
  const double ex = w.x1 - w.x0;
  const double ey = w.y1 - w.y0;
  const double u = std::clamp(((x - w.x0) * ex + (y - w.y0) * ey) / (ex * ex + ey * ey), 0.0, 1.0);
  return std::hypot(x - (w.x0 + u * ex), y - (w.y0 + u * ey));
}

// The ActivityBot (LIDAR 0.05 m ahead of base_link, servo stepping 1° every 0.02 s) meets a plate across its way to
// the goal, whose lower end is nearer the line: it stops, sweeps standing, goes round that end and reaches the goal.
TEST(ServoGoto, StopsSweepsStandingAndGoesRoundThePlateToTheGoal) {
  const std::vector<Segment> walls{{0.8, -0.3, 0.8, 0.6}};
  constexpr double kPeriod_s = 0.02;
  std::unique_ptr<Behaviour> behaviour = make_servo_goto(PointBugParams{}, kActivityBotServo, 0.0, 2.0, 0.0, kPeriod_s);
  geometry::Pose2 pose{0.0, 0.0, 0.0};
  PingPongServo servo;
  std::set<BehaviourState> states;
  double nearest_m = std::numeric_limits<double>::infinity();
  double lowest_y = 0.0;
  bool moved_while_sweeping = false;
  BehaviourState state = BehaviourState::kNone;
  for (int i = 0; i < 60000 && state != BehaviourState::kReached && state != BehaviourState::kNoPath; ++i) {
    const double angle = servo.next();
    const double range =
        cast(pose.x + 0.05 * std::cos(pose.theta), pose.y + 0.05 * std::sin(pose.theta), pose.theta + angle, walls);
    BehaviourInput input;
    input.X_WB = pose;
    input.stamp_s = kPeriod_s * i;
    input.servo = ServoSample{angle, range, input.stamp_s};
    const BehaviourCommand command = behaviour->decide(input);
    state = command.state;
    states.insert(state);
    if (state == BehaviourState::kSweep && (command.linear_mps != 0.0 || command.angular_radps != 0.0))
      moved_while_sweeping = true;
    if (!command.stop) {
      const double theta = pose.theta + command.angular_radps * kPeriod_s / 2.0;
      pose = {pose.x + command.linear_mps * kPeriod_s * std::cos(theta),
              pose.y + command.linear_mps * kPeriod_s * std::sin(theta),
              geometry::wrap_angle(pose.theta + command.angular_radps * kPeriod_s)};
    }
    nearest_m = std::min(nearest_m, distance_to(pose.x, pose.y, walls[0]));
    lowest_y = std::min(lowest_y, pose.y);
  }
  EXPECT_EQ(state, BehaviourState::kReached) << "ended at " << pose.x << ", " << pose.y;
  EXPECT_LT(std::hypot(pose.x - 2.0, pose.y), 0.02);
  EXPECT_TRUE(states.contains(BehaviourState::kSweep));
  EXPECT_TRUE(states.contains(BehaviourState::kDriveToSuddenPoint));
  EXPECT_FALSE(moved_while_sweeping);
  EXPECT_LT(lowest_y, -0.3) << "round the plate's lower end";
  // Half the ActivityBot's 0.13 m width clear of the plate all the way.
  EXPECT_GT(nearest_m, 0.065);
}

TEST(ServoGoto, StandsUntilTheServoHasLookedAheadAtTheCurrentHeading) {
  std::unique_ptr<Behaviour> behaviour = make_servo_goto(PointBugParams{}, kActivityBotServo, 0.0, 2.0, 0.0, 0.02);
  BehaviourInput input;
  input.X_WB = geometry::Pose2{0.0, 0.0, 0.0};
  input.servo = ServoSample{-90.0 * kDeg, 40.0, 0.0};
  EXPECT_EQ(behaviour->decide(input).state, BehaviourState::kLookAhead);
  input.servo = ServoSample{0.0, 40.0, 0.02};
  const BehaviourCommand command = behaviour->decide(input);
  EXPECT_EQ(command.state, BehaviourState::kStepToGoal);
  EXPECT_GT(command.linear_mps, 0.0);
  input.servo.reset();
  EXPECT_TRUE(behaviour->decide(input).stop) << "no reading: no decision";
}

}  // namespace
}  // namespace occgeo::service::control
