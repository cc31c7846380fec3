// The safety guard on its own: a footprint swept along the commanded motion against occupied cells.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

#include "occgeo/service/control/safety_guard.h"

namespace occgeo::service::control {
namespace {

// Occupied cells given explicitly, 0.1 m each: the grid model as the guard reads it.
class CellSet final : public geometry::OccupiedCellSource {
 public:
  [[nodiscard]] double cell_size() const override { return 0.1; }
  void for_each_occupied(geometry::CellIndex min, geometry::CellIndex max,
                         const std::function<bool(const geometry::CellIndex&)>& visit) const override {
    for (const auto& [ix, iy] : cells_) {
      if (ix < min.ix || ix > max.ix || iy < min.iy || iy > max.iy) continue;
      if (!visit({ix, iy})) return;
    }
  }
  void add(int ix, int iy) { cells_.insert({ix, iy}); }
  // A wall of cells across x = [wall_x, wall_x + 0.1), y in [-2, 2).
  static CellSet wall_at(double wall_x_m) {
    CellSet set;
    const int ix = static_cast<int>(std::floor(wall_x_m / 0.1 + 1e-9));
    for (int iy = -20; iy < 20; ++iy) set.add(ix, iy);
    return set;
  }

 private:
  std::set<std::pair<int, int>> cells_;
};

// The simulator's Bearcat: 1.0 m x 0.8 m, base_link at its centre.
const geometry::Footprint kBearcat =
    geometry::BoxFootprint{.length = 1.0, .width = 0.8, .height = 1.2, .center_x = 0.0};

GuardDecision guard_towards_wall(double gap_m, double linear_mps, double angular_radps = 0.0) {
  // The robot's front is gap_m short of the wall.
  const CellSet wall = CellSet::wall_at(0.5 + gap_m);
  return guard_command({&wall, nullptr, nullptr}, kBearcat, {0.0, 0.0, 0.0}, linear_mps, angular_radps, GuardParams{});
}

TEST(SafetyGuard, StopsFullSpeedShortlyBeforeAWall) {
  const GuardDecision near = guard_towards_wall(0.3, 1.2);
  EXPECT_EQ(near.action, GuardAction::kStop);
  EXPECT_EQ(near.zone, "stop");
  EXPECT_EQ(near.model, "grid");
  EXPECT_EQ(near.linear_mps, 0.0);
  EXPECT_NEAR(near.time_to_contact_s, 0.3 / 1.2, 0.05);
  EXPECT_NEAR(near.distance_to_contact_m, 0.3, 0.06);
}

TEST(SafetyGuard, SlowsDownWhenContactLiesWithinTheHorizonButNotSoon) {
  const GuardDecision decision = guard_towards_wall(0.9, 1.2);
  EXPECT_EQ(decision.action, GuardAction::kSlow);
  EXPECT_EQ(decision.zone, "slowdown");
  EXPECT_NEAR(decision.linear_mps, 0.6, 1e-12);
  EXPECT_NEAR(decision.time_to_contact_s, 0.75, 0.05);
}

TEST(SafetyGuard, PassesWhenTheWallIsBeyondTheHorizonOrTheRobotTurnsAway) {
  const GuardDecision far = guard_towards_wall(2.0, 1.2);
  EXPECT_EQ(far.action, GuardAction::kPass);
  EXPECT_EQ(far.linear_mps, 1.2);
  EXPECT_EQ(far.time_to_contact_s, 1.0);
  const GuardDecision backing = guard_towards_wall(0.5, -0.5);
  EXPECT_EQ(backing.action, GuardAction::kPass);
  EXPECT_EQ(backing.linear_mps, -0.5);
}

TEST(SafetyGuard, ATurnInPlaceThatSwingsACornerIntoTheWallIsStopped) {
  // The box's corners reach 0.64 m from its centre; a wall 0.1 m ahead of the front face is within that reach.
  const GuardDecision turning = guard_towards_wall(0.15, 0.0, 2.0);
  EXPECT_EQ(turning.action, GuardAction::kStop);
  // With the wall 0.3 m away the corners clear it: the turn passes (limited, as the wall is close).
  const GuardDecision clear = guard_towards_wall(0.3, 0.0, 0.5);
  EXPECT_NE(clear.action, GuardAction::kStop);
}

TEST(SafetyGuard, LimitsSpeedsAlongsideAnObstacle) {
  CellSet side;
  for (int ix = -20; ix < 40; ++ix) side.add(ix, 6);  // a wall 0.2 m beside the left face (y = 0.4)
  const GuardDecision decision =
      guard_command({&side, nullptr, nullptr}, kBearcat, {0.0, 0.0, 0.0}, 1.0, 0.0, GuardParams{});
  EXPECT_EQ(decision.action, GuardAction::kLimit);
  EXPECT_EQ(decision.zone, "limit");
  EXPECT_NEAR(decision.linear_mps, GuardParams{}.limit_linear_mps, 1e-12);
}

TEST(SafetyGuard, ARobotAlreadyTouchingMayOnlyBackAwayOrTurn) {
  const CellSet wall = CellSet::wall_at(0.45);  // overlaps the front face
  const GuardModels models{&wall, nullptr, nullptr};
  const GuardDecision forward = guard_command(models, kBearcat, {0.0, 0.0, 0.0}, 0.5, 0.0, GuardParams{});
  EXPECT_EQ(forward.action, GuardAction::kStop);
  EXPECT_EQ(forward.zone, "contact");
  const GuardDecision reverse = guard_command(models, kBearcat, {0.0, 0.0, 0.0}, -1.0, 0.0, GuardParams{});
  EXPECT_EQ(reverse.action, GuardAction::kLimit);
  EXPECT_NEAR(reverse.linear_mps, -GuardParams{}.limit_linear_mps, 1e-12);
}

TEST(SafetyGuard, ARobotTouchingAWallAlongsideMayBackAlongItButNotSwingACornerIntoIt) {
  // Wall cells y in [0.4, 0.5): the left face (y = 0.4) touches them, their centres 5 cm beyond it; the wall's own face
  // may lie anywhere in them. A turn in place either way swings a left corner towards them.
  CellSet side;
  for (int ix = -20; ix < 40; ++ix) side.add(ix, 4);
  const GuardModels models{&side, nullptr, nullptr};
  for (const double yaw_rate : {0.6, -0.6}) {
    const GuardDecision turn = guard_command(models, kBearcat, {0.0, 0.0, 0.0}, 0.0, yaw_rate, GuardParams{});
    EXPECT_EQ(turn.action, GuardAction::kStop) << yaw_rate;
    EXPECT_EQ(turn.zone, "contact");
    const GuardDecision backing_turn = guard_command(models, kBearcat, {0.0, 0.0, 0.0}, -0.3, yaw_rate, GuardParams{});
    EXPECT_EQ(backing_turn.action, GuardAction::kStop) << yaw_rate;
  }
  // Backing straight keeps the gap: it goes on, limited as the wall is close.
  const GuardDecision backing = guard_command(models, kBearcat, {0.0, 0.0, 0.0}, -0.5, 0.0, GuardParams{});
  EXPECT_EQ(backing.action, GuardAction::kLimit);
  EXPECT_NEAR(backing.linear_mps, -GuardParams{}.limit_linear_mps, 1e-12);
  // Turned 0.1 rad towards the wall, its front corner in a wall cell: backing carries it away, and goes on.
  const GuardDecision leaving = guard_command(models, kBearcat, {0.0, -0.02, 0.1}, -0.3, 0.0, GuardParams{});
  EXPECT_EQ(leaving.zone, "contact");
  EXPECT_NE(leaving.action, GuardAction::kStop);
}

TEST(SafetyGuard, DisabledOrStandingStillChangesNothing) {
  GuardParams off;
  off.enabled = false;
  const CellSet wall = CellSet::wall_at(0.6);
  EXPECT_EQ(guard_command({&wall, nullptr, nullptr}, kBearcat, {}, 1.2, 0.0, off).action, GuardAction::kPass);
  EXPECT_EQ(guard_command({&wall, nullptr, nullptr}, kBearcat, {}, 0.0, 0.0, GuardParams{}).action, GuardAction::kPass);
}

// A laser scan from the origin looking along yaw_rad (180 degrees, 4 m) whose returns are the near half of a person's
// disc at person_W (radius 0.25 m) as seen from the origin; points_W holds them.
mapping::PtemScan scan_of_person(double stamp_s, const Eigen::Vector2d& person_W, double yaw_rad,
                                 std::vector<Eigen::Vector2d>& points_W) {
  mapping::PtemScan scan;
  scan.stamp_s = stamp_s;
  scan.yaw_WS = yaw_rad;
  scan.field_of_view_rad = M_PI;
  scan.max_range_m = 4.0;
  points_W.clear();
  const double towards_origin = std::atan2(-person_W.y(), -person_W.x());
  for (double a = towards_origin - M_PI / 2.0; a <= towards_origin + M_PI / 2.0 + 1e-9; a += 0.1) {
    points_W.push_back(person_W + 0.25 * Eigen::Vector2d(std::cos(a), std::sin(a)));
  }
  scan.points_W = points_W;
  return scan;
}

// A walker's returns are not in the grid once they are tracked as moving (World::moving_clusters_on_strand): the
// guard keeps the robot from driving into what the laser sees now of the tracked walker, and forgets it once it is
// older than scan_returns_max_age_s (a cluster the laser no longer looks at). Returns of anything not tracked as moving
// are the grid's to judge: a robot wedged beside a box whose every face returns would otherwise never turn out.
TEST(SafetyGuard, StopsADriveIntoTheLatestReturnsOfATrackedWalkerThatTheGridDoesNotHold) {
  mapping::PtemModel ptem(mapping::PtemParams{});
  std::vector<Eigen::Vector2d> points_W;
  ptem.insert_scan(scan_of_person(1.0, {1.0, 0.0}, 0.0, points_W));
  const CellSet nothing;
  TrackedObstacle walker;
  walker.centre_W = {1.0, 0.0};
  walker.radius_m = 0.25;
  walker.stamp_s = 1.0;
  walker.moving = true;
  const std::vector<TrackedObstacle> tracked{walker};
  const GuardModels models{&nothing, nullptr, nullptr, ptem.snapshot().get(), tracked};
  const GuardDecision into = guard_command(models, kBearcat, {0.0, 0.0, 0.0}, 0.5, 0.0, GuardParams{});
  EXPECT_NE(into.action, GuardAction::kPass);
  EXPECT_EQ(into.model, "scan_returns");
  EXPECT_LT(into.distance_to_contact_m, 0.4);
  // Backing away is not stopped (only limited: the person is within limit_distance_m of the front).
  const GuardDecision away = guard_command(models, kBearcat, {0.0, 0.0, 0.0}, -0.5, 0.0, GuardParams{});
  EXPECT_NE(away.action, GuardAction::kStop);
  EXPECT_LT(away.linear_mps, 0.0);
  // Off: nothing to stop for.
  GuardParams off;
  off.check_scan_returns = false;
  EXPECT_EQ(guard_command(models, kBearcat, {0.0, 0.0, 0.0}, 0.5, 0.0, off).action, GuardAction::kPass);
  // The same returns with nothing tracked there (a still thing the grid has not taken yet): the grid's to judge.
  const TrackedObstacle elsewhere{{-3.0, 2.0}, {0.5, 0.0}, 0.25, 1.0, true};
  const std::vector<TrackedObstacle> other{elsewhere};
  EXPECT_EQ(guard_command({&nothing, nullptr, nullptr, ptem.snapshot().get(), other}, kBearcat, {0.0, 0.0, 0.0}, 0.5,
                          0.0, GuardParams{})
                .action,
            GuardAction::kPass);
  EXPECT_EQ(guard_command({&nothing, nullptr, nullptr, ptem.snapshot().get()}, kBearcat, {0.0, 0.0, 0.0}, 0.5, 0.0,
                          GuardParams{})
                .action,
            GuardAction::kPass);
  // A second later the laser looks the other way: the person's cluster is kept by the PTEM but no longer counts.
  ptem.insert_scan(scan_of_person(2.0, {-3.0, 0.0}, M_PI, points_W));
  EXPECT_EQ(guard_command({&nothing, nullptr, nullptr, ptem.snapshot().get(), tracked}, kBearcat, {0.0, 0.0, 0.0}, 0.5,
                          0.0, GuardParams{})
                .action,
            GuardAction::kPass);
}

TEST(SafetyGuard, ParamsOutOfRangeAreNamed) {
  GuardParams bad;
  bad.stop_time_s = 2.0;  // beyond the horizon
  try {
    bad.validate();
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("stop_time_s"), std::string::npos) << e.what();
  }
  bad = GuardParams{};
  bad.slowdown_ratio = 0.0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

}  // namespace
}  // namespace occgeo::service::control
