#pragma once

#include <array>
#include <cstdint>
#include <ostream>
#include <string_view>

// The states the behaviours report with each command. The wire's BehaviourState (proto/occgeo/v1/control.proto)
// numbers these the same, 1 to kBehaviourStateCount - 1, and adds the states only the server sets (estop, teleop,
// ...); a test checks the two agree name for name.

namespace occgeo::service::control {

enum class BehaviourState : std::uint8_t {
  kNone = 0,  // no state: a wrapper's "nothing to add, use the inner behaviour's command"
  // The Bearcat (seed 000 §4.2).
  kClear,
  kAvoidRightObstacle,
  kAvoidLeftObstacle,
  kSteerGap,
  kNoGap,
  kPassBetween,
  kDeadlock,
  // Wander (seed 001).
  kWanderStraight,
  kWanderTurn,
  kAvoidTurn,
  kAvoidEaseOff,
  // PointBug, then the servo-swept robot's waits.
  kAimAtGoal,
  kStepToGoal,
  kTurnToSuddenPoint,
  kDriveToSuddenPoint,
  kReached,
  kNoPath,
  kNoSweepReading,
  kLookAhead,
  kSweep,
  kNoPose,
  // PTEM guidance (seed 004 §4.4).
  kTrackTarget,
  kAvoid,
  kEscape,
  // The deadlock escapes, by what set them off.
  kEscapeBlocked,
  kEscapeNoPath,
  kEscapeLoop,
  kEscapeStall,
  kEscapeDeadlock,
  kEscapeStalled,
  kEscapeBackOff,
  kEscapeLookRound,
  // Yielding to moving obstacles.
  kYieldSlow,
  kYieldWait,
  kYieldAside,
};

inline constexpr std::size_t kBehaviourStateCount = static_cast<std::size_t>(BehaviourState::kYieldAside) + 1;

// The state's name as logs and people read it ("steer_gap"); "" for kNone.
[[nodiscard]] constexpr std::string_view name(BehaviourState state) {
  constexpr std::array<std::string_view, kBehaviourStateCount> kNames = {
      "",
      "clear",
      "avoid_right_obstacle",
      "avoid_left_obstacle",
      "steer_gap",
      "no_gap",
      "pass_between",
      "deadlock",
      "wander_straight",
      "wander_turn",
      "avoid_turn",
      "avoid_ease_off",
      "aim_at_goal",
      "step_to_goal",
      "turn_to_sudden_point",
      "drive_to_sudden_point",
      "reached",
      "no_path",
      "no_sweep_reading",
      "look_ahead",
      "sweep",
      "no_pose",
      "track_target",
      "avoid",
      "escape",
      "escape_blocked",
      "escape_no_path",
      "escape_loop",
      "escape_stall",
      "escape_deadlock",
      "escape_stalled",
      "escape_back_off",
      "escape_look_round",
      "yield_slow",
      "yield_wait",
      "yield_aside",
  };
  return kNames[static_cast<std::size_t>(state)];
}

// The name, for test failure messages and logs ("none" for kNone).
inline std::ostream& operator<<(std::ostream& out, BehaviourState state) {
  return out << (state == BehaviourState::kNone ? std::string_view("none") : name(state));
}

}  // namespace occgeo::service::control
