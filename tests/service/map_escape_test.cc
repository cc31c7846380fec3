// The map-based escape round the goal-less behaviours (make_map_escape) never leaves a robot standing where the
// safety guard stops every way out it tries: a Bearcat beside a box, whose inner behaviour keeps steering into the box,
// is driven here as the server drives it (each command through guard_command, a stopped one not executed).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>

#include "bearcat_shape.h"
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

struct EscapeRun {
  double travelled_m = 0.0;
  double longest_standstill_s = 0.0;
  int guard_stops = 0;
};

// Drives for `seconds` from the wedged pose, each command through the guard as the server applies it.
EscapeRun drive(const GuardParams& escape_guard, double seconds) {
  const auto grid = room_with_a_box();
  const RobotShape robot = bearcat_shape();
  auto behaviour = make_map_escape([] { return std::make_unique<IntoTheBox>(); }, robot, escape_guard);
  const GuardParams server_guard;
  const GuardModels models{grid.get(), nullptr, nullptr};
  // Beside the box, facing away from it to the lower right: turning left swings the rear corner into the box.
  geometry::Pose2 pose{2.54, 1.13, -0.54};
  EscapeRun run;
  double still_since_s = 0.0;
  for (int k = 0; k < static_cast<int>(seconds / kCycle_s); ++k) {
    const double t = k * kCycle_s;
    BehaviourInput input;
    input.X_WB = pose;
    input.stamp_s = t;
    input.grid = grid.get();
    const BehaviourCommand command = behaviour->decide(input);
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

TEST(MapEscape, ARobotWedgedBesideABoxGetsOutOfWhereTheGuardStopsItsWayOut) {
  const EscapeRun run = drive(GuardParams{}, 120.0);
  EXPECT_GT(run.travelled_m, 5.0);
  EXPECT_LE(run.longest_standstill_s, 10.0);

  // With the escape blind to the guard (the behaviour before it checked its own commands), the same robot stands.
  GuardParams blind;
  blind.enabled = false;
  const EscapeRun stuck = drive(blind, 120.0);
  EXPECT_GT(stuck.longest_standstill_s, 30.0);
  std::cout << "wedged beside the box: " << run.travelled_m << " m, longest standstill " << run.longest_standstill_s
            << " s; blind to the guard: " << stuck.travelled_m << " m, longest standstill "
            << stuck.longest_standstill_s << " s\n";
}

}  // namespace
}  // namespace occgeo::service::control
