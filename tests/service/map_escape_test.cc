// The map-based escapes never leave a robot standing where the safety guard stops every way out they try: round the
// goal-less behaviours (make_map_escape), a Bearcat beside a box whose inner behaviour keeps steering into the box;
// round goto (make_escape), a Bearcat beside the same box whose way to its goal starts with a turn that swings a corner
// into it. Each is driven here as the server drives it (each command through guard_command, a stopped one not
// executed).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>

#include "bearcat_shape.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/mapping/himm_grid.h"
#include "occgeo/service/control/behaviour.h"
#include "occgeo/service/control/safety_guard.h"

namespace occgeo::service::control {
namespace {

constexpr double kCycle_s = 0.1;

// A 10 x 8 m room of 0.1 m cells, walls round it and a 0.8 x 0.6 m box centred at (3, 2) (the shipped room world's).
std::shared_ptr<const mapping::GridSnapshot> room_with_a_box() {
  mapfile::OccupancyImage image;
  image.width = 104;
  image.height = 84;
  image.resolution = 0.1;
  image.origin_x = -5.2;
  image.origin_y = -4.2;
  image.pixels.assign(static_cast<std::size_t>(image.width) * image.height, 254);
  for (std::uint32_t row = 0; row < image.height; ++row) {
    for (std::uint32_t col = 0; col < image.width; ++col) {
      const double x = image.origin_x + (col + 0.5) * image.resolution;
      const double y = image.origin_y + (image.height - 1 - row + 0.5) * image.resolution;
      const bool wall = std::abs(x) > 5.0 || std::abs(y) > 4.0;
      const bool box = std::abs(x - 3.0) < 0.4 && std::abs(y - 2.0) < 0.3;
      if (wall || box) image.pixels[static_cast<std::size_t>(row) * image.width + col] = 0;
    }
  }
  return mapping::HimmGrid::from_image(image, mapping::HimmParams{}).snapshot();
}

// The inner behaviour: steers forward and left, into the box, for ever (the Bearcat's steer_gap towards a gap the
// laser sees past the box's corner).
class IntoTheBox final : public Behaviour {
 public:
  [[nodiscard]] std::string_view name() const override { return "bearcat"; }
  BehaviourCommand decide(const BehaviourInput& /*input*/) override {
    BehaviourCommand command;
    command.linear_mps = 0.3;
    command.angular_radps = 0.6;
    command.state = BehaviourState::kSteerGap;
    return command;
  }
};

// A goto stand-in: its goal, heading straight for it, and reached within 0.3 m of it. The escape round it plans the way
// there over the map as soon as the straight way runs into something the map holds.
class StraightToGoal final : public Behaviour {
 public:
  explicit StraightToGoal(const Eigen::Vector2d& goal_W) : goal_W_(goal_W) {}
  [[nodiscard]] std::string_view name() const override { return "goto"; }
  [[nodiscard]] std::optional<Eigen::Vector2d> current_goal() const override { return goal_W_; }
  BehaviourCommand decide(const BehaviourInput& input) override {
    BehaviourCommand command;
    const Eigen::Vector2d to_goal = goal_W_ - input.X_WB->position();
    if (to_goal.norm() < 0.3) {
      command.stop = true;
      command.state = BehaviourState::kReached;
      return command;
    }
    const double error = geometry::wrap_angle(std::atan2(to_goal.y(), to_goal.x()) - input.X_WB->theta);
    command.linear_mps = std::abs(error) < 0.3 ? 0.3 : 0.0;
    command.angular_radps = std::clamp(2.0 * error, -0.6, 0.6);
    command.state = BehaviourState::kStepToGoal;
    return command;
  }

 private:
  Eigen::Vector2d goal_W_;
};

struct EscapeRun {
  double travelled_m = 0.0;
  double longest_standstill_s = 0.0;
  int guard_stops = 0;
  bool reached = false;
};

// Drives `behaviour` for `seconds` from `pose`, each command through the guard as the server applies it.
EscapeRun drive(Behaviour& behaviour, geometry::Pose2 pose, double seconds) {
  const auto grid = room_with_a_box();
  const RobotShape robot = bearcat_shape();
  const GuardParams server_guard;
  const GuardModels models{grid.get(), nullptr, nullptr};
  EscapeRun run;
  double still_since_s = 0.0;
  for (int k = 0; k < static_cast<int>(seconds / kCycle_s); ++k) {
    const double t = k * kCycle_s;
    BehaviourInput input;
    input.X_WB = pose;
    input.stamp_s = t;
    input.grid = grid.get();
    const BehaviourCommand command = behaviour.decide(input);
    if (command.state == BehaviourState::kReached) {
      run.reached = true;
      break;
    }
    const GuardDecision decision =
        guard_command(models, robot.footprint, pose, command.linear_mps, command.angular_radps, server_guard);
    const bool moves = !command.stop && decision.action != GuardAction::kStop &&
                       (decision.linear_mps != 0.0 || decision.angular_radps != 0.0);
    if (decision.action == GuardAction::kStop) ++run.guard_stops;
    if (moves) {
      const geometry::Pose2 next = advance_pose(pose, decision.linear_mps, decision.angular_radps, kCycle_s);
      run.travelled_m += (next.position() - pose.position()).norm();
      pose = next;
      still_since_s = t;
    }
    run.longest_standstill_s = std::max(run.longest_standstill_s, t - still_since_s);
  }
  return run;
}

// Beside the box, facing away from it to the lower right: turning left swings the rear corner into the box.
const geometry::Pose2 kWedged{2.54, 1.13, -0.54};

EscapeRun drive_map_escape(const GuardParams& escape_guard, double seconds) {
  auto behaviour = make_map_escape([] { return std::make_unique<IntoTheBox>(); }, bearcat_shape(), escape_guard);
  return drive(*behaviour, kWedged, seconds);
}

TEST(MapEscape, ARobotWedgedBesideABoxGetsOutOfWhereTheGuardStopsItsWayOut) {
  const EscapeRun run = drive_map_escape(GuardParams{}, 120.0);
  EXPECT_GT(run.travelled_m, 5.0);
  EXPECT_LE(run.longest_standstill_s, 10.0);

  // With the escape blind to the guard (the behaviour before it checked its own commands), the same robot stands.
  GuardParams blind;
  blind.enabled = false;
  const EscapeRun stuck = drive_map_escape(blind, 120.0);
  EXPECT_GT(stuck.longest_standstill_s, 30.0);
  std::cout << "wedged beside the box: " << run.travelled_m << " m, longest standstill " << run.longest_standstill_s
            << " s; blind to the guard: " << stuck.travelled_m << " m, longest standstill "
            << stuck.longest_standstill_s << " s\n";
}

// Goto's escape follows a path whose first motion, a turn on the spot, the guard stops (as after stepping aside for a
// person into a door frame): it finds a motion the guard lets through and reaches the goal, where the escape blind to
// the guard stands for good.
TEST(GotoEscape, ARobotWhoseWayToTheGoalStartsWithATurnTheGuardStopsStillGetsThere) {
  // Above the box, behind the robot's left shoulder: the straight way passes the box's corner, and the path's first
  // heading is up and to the left.
  const Eigen::Vector2d goal_W(2.0, 3.0);
  const auto drive_goto = [&](const GuardParams& escape_guard) {
    auto behaviour =
        make_escape([&] { return std::make_unique<StraightToGoal>(goal_W); }, bearcat_shape(), escape_guard);
    return drive(*behaviour, kWedged, 120.0);
  };
  const EscapeRun run = drive_goto(GuardParams{});
  EXPECT_TRUE(run.reached);
  EXPECT_LE(run.longest_standstill_s, 10.0);

  GuardParams blind;
  blind.enabled = false;
  const EscapeRun stuck = drive_goto(blind);
  EXPECT_FALSE(stuck.reached);
  EXPECT_GT(stuck.longest_standstill_s, 30.0);
  std::cout << "goto's escape beside the box: reached " << run.reached << " after " << run.travelled_m
            << " m, longest standstill " << run.longest_standstill_s << " s; blind to the guard: reached "
            << stuck.reached << ", longest standstill " << stuck.longest_standstill_s << " s\n";
}

}  // namespace
}  // namespace occgeo::service::control
