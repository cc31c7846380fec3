// Moving obstacles in the control loop: the PTEM's clusters tracked across scans (velocities), the guard's prediction,
// and goto/waypoints yielding (make_yield) to a person crossing ahead or walking head-on. Scans are ray-cast from the
// robot's laser into a world of walls and discs and fed to the real PtemModel, ten a second.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "bearcat_shape.h"
#include "occgeo/service/control/behaviour.h"
#include "occgeo/service/control/cluster_tracker.h"
#include "occgeo/service/control/safety_guard.h"

namespace occgeo::service::control {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kScanPeriod_s = 0.1;
constexpr double kMaxRange_m = 8.0;
constexpr int kBeams = 361;  // 0.5° over ±90°

struct Disc {
  Eigen::Vector2d start_W;
  Eigen::Vector2d velocity_W;
  double radius_m;
  [[nodiscard]] Eigen::Vector2d at(double t_s) const { return start_W + velocity_W * t_s; }
};

struct Segment {
  Eigen::Vector2d a_W;
  Eigen::Vector2d b_W;
};

struct World {
  std::vector<Segment> walls;
  std::vector<Disc> discs;

  // Range along a unit direction from origin, or +inf.
  [[nodiscard]] double cast(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir, double t_s) const {
    double best = std::numeric_limits<double>::infinity();
    for (const Segment& wall : walls) {
      const Eigen::Vector2d e = wall.b_W - wall.a_W;
      const double denom = dir.x() * e.y() - dir.y() * e.x();
      if (std::abs(denom) < 1e-12) continue;
      const Eigen::Vector2d w = wall.a_W - origin;
      const double r = (w.x() * e.y() - w.y() * e.x()) / denom;
      const double s = (w.x() * dir.y() - w.y() * dir.x()) / denom;
      if (r > 0.0 && s >= 0.0 && s <= 1.0) best = std::min(best, r);
    }
    for (const Disc& disc : discs) {
      const Eigen::Vector2d oc = disc.at(t_s) - origin;
      const double along = oc.dot(dir);
      const double miss_sq = oc.squaredNorm() - along * along;
      const double r_sq = disc.radius_m * disc.radius_m;
      if (miss_sq > r_sq || along <= 0.0) continue;
      best = std::min(best, along - std::sqrt(r_sq - miss_sq));
    }
    return best;
  }

  // The laser's returns (world frame) and ranges from a sensor at p_WS, heading yaw.
  void scan(const Eigen::Vector2d& p_WS, double yaw, double t_s, std::vector<Eigen::Vector2d>& points_W,
            std::vector<float>& ranges) const {
    points_W.clear();
    ranges.assign(kBeams, static_cast<float>(kMaxRange_m));
    for (int i = 0; i < kBeams; ++i) {
      const double bearing = yaw - kPi / 2 + i * kPi / (kBeams - 1);
      const Eigen::Vector2d dir(std::cos(bearing), std::sin(bearing));
      const double r = cast(p_WS, dir, t_s);
      if (r >= kMaxRange_m) continue;
      ranges[static_cast<std::size_t>(i)] = static_cast<float>(r);
      points_W.push_back(p_WS + r * dir);
    }
  }
};

void insert(mapping::PtemModel& model, const World& world, const Eigen::Vector2d& p_WS, double yaw, double t_s,
            std::vector<Eigen::Vector2d>& points_W, std::vector<float>& ranges) {
  world.scan(p_WS, yaw, t_s, points_W, ranges);
  mapping::PtemScan scan;
  scan.stamp_s = t_s;
  scan.p_WS = p_WS;
  scan.yaw_WS = yaw;
  scan.field_of_view_rad = kPi;
  scan.max_range_m = kMaxRange_m;
  scan.points_W = points_W;
  model.insert_scan(scan);
}

const TrackedObstacle* nearest_track(const std::vector<TrackedObstacle>& tracks, const Eigen::Vector2d& p_W) {
  const TrackedObstacle* best = nullptr;
  for (const TrackedObstacle& track : tracks) {
    if (best == nullptr || (track.centre_W - p_W).norm() < (best->centre_W - p_W).norm()) best = &track;
  }
  return best;
}

TEST(ClusterTracker, EstimatesAWalkersVelocityAndLeavesTheWallsStill) {
  World world;
  world.walls = {{{-1.0, 2.5}, {7.0, 2.5}}, {{-1.0, -2.5}, {7.0, -2.5}}};
  const Disc person{{3.0, -1.8}, {0.15, 0.6}, 0.25};
  world.discs = {person};
  mapping::PtemModel model(mapping::PtemParams{});
  ClusterTracker tracker;
  std::vector<Eigen::Vector2d> points;
  std::vector<float> ranges;
  for (int k = 0; k <= 30; ++k) {
    const double t = k * kScanPeriod_s;
    insert(model, world, {0.0, 0.0}, 0.0, t, points, ranges);
    tracker.update(*model.snapshot(), {0.0, 0.0}, kMaxRange_m);
    if (k < 6) continue;
    SCOPED_TRACE("scan " + std::to_string(k));
    const TrackedObstacle* walker = nearest_track(tracker.tracks(), person.at(t));
    ASSERT_NE(walker, nullptr);
    EXPECT_LT((walker->centre_W - person.at(t)).norm(), 0.3);
    EXPECT_NEAR(walker->velocity_W.x(), person.velocity_W.x(), 0.1);
    EXPECT_NEAR(walker->velocity_W.y(), person.velocity_W.y(), 0.1);
    EXPECT_TRUE(walker->moving);
    // The walls' clusters never move; their velocities are ~0 but for a fragment at the edge of the person's shadow.
    int walls = 0;
    int still = 0;
    for (const TrackedObstacle& track : tracker.tracks()) {
      if (&track == walker) continue;
      EXPECT_FALSE(track.moving) << "a wall cluster at " << track.centre_W.transpose() << " moves";
      ++walls;
      still += track.velocity_W.norm() < 0.05 ? 1 : 0;
    }
    EXPECT_GE(still, walls - 1);
  }
  // The same snapshot twice is one observation, not a second one at zero time apart.
  const std::vector<TrackedObstacle> before = tracker.tracks();
  tracker.update(*model.snapshot(), {0.0, 0.0}, kMaxRange_m);
  EXPECT_EQ(tracker.tracks().size(), before.size());
}

// A server's snapshot holds the tracker: one restored from it goes on exactly as the one that kept running (so that
// a world restored from its snapshot and journal maps the walker's returns as ingest did). Damaged bytes are refused.
TEST(ClusterTracker, ARestoredTrackerGoesOnAsTheOneThatKeptRunning) {
  World world;
  world.walls = {{{-1.0, 2.5}, {7.0, 2.5}}};
  world.discs = {{{3.0, -1.8}, {0.15, 0.6}, 0.25}};
  mapping::PtemModel model(mapping::PtemParams{});
  ClusterTracker running;
  std::optional<ClusterTracker> restored;
  std::vector<Eigen::Vector2d> points;
  std::vector<float> ranges;
  for (int k = 0; k <= 20; ++k) {
    const double t = k * kScanPeriod_s;
    insert(model, world, {0.0, 0.0}, 0.0, t, points, ranges);
    running.update(*model.snapshot(), {0.0, 0.0}, kMaxRange_m);
    if (restored) restored->update(*model.snapshot(), {0.0, 0.0}, kMaxRange_m);
    if (k == 8) {
      restored.emplace();
      restored->restore(running.serialize());
    }
  }
  ASSERT_TRUE(restored);
  ASSERT_EQ(restored->tracks().size(), running.tracks().size());
  ASSERT_FALSE(running.moving().empty());
  for (std::size_t i = 0; i < running.tracks().size(); ++i) {
    EXPECT_EQ(restored->tracks()[i].centre_W, running.tracks()[i].centre_W);
    EXPECT_EQ(restored->tracks()[i].velocity_W, running.tracks()[i].velocity_W);
    EXPECT_EQ(restored->tracks()[i].moving, running.tracks()[i].moving);
  }
  std::string damaged = running.serialize();
  damaged.resize(damaged.size() - 3);
  EXPECT_THROW(restored->restore(damaged), std::invalid_argument);
  EXPECT_THROW(restored->restore("not a tracker"), std::invalid_argument);
  EXPECT_EQ(restored->tracks().size(), running.tracks().size());  // unchanged by the refused bytes
}

// Driving past a square pillar, the robot sees one face, then two, then the next: the mean of the pillar's returns
// slides along at up to a few tenths of a metre per second, as a walker's would. Its returns stay on the same surface,
// so it is never moving (surface_moved_m); without that test (surface_moved_m = 0) the same drive makes it moving.
std::pair<int, int> scans_a_passed_pillar_is_moving(const ClusterTrackerParams& params) {
  World world;
  const double lo_x = 2.2, hi_x = 2.8, lo_y = 0.7, hi_y = 1.3;
  world.walls = {{{lo_x, lo_y}, {hi_x, lo_y}},
                 {{hi_x, lo_y}, {hi_x, hi_y}},
                 {{hi_x, hi_y}, {lo_x, hi_y}},
                 {{lo_x, hi_y}, {lo_x, lo_y}}};
  mapping::PtemModel model(mapping::PtemParams{});
  ClusterTracker tracker(params);
  std::vector<Eigen::Vector2d> points;
  std::vector<float> ranges;
  int moving_scans = 0;
  int scans = 0;
  for (int k = 0; k <= 50; ++k) {
    const double t = k * kScanPeriod_s;
    const Eigen::Vector2d p_WS(0.5 * t, 0.0);  // 0.5 m/s along x, the pillar 0.7 m to the left of the path
    insert(model, world, p_WS, 0.0, t, points, ranges);
    tracker.update(*model.snapshot(), p_WS, kMaxRange_m, LaserArc{0.0, -kPi / 2, kPi / 2});
    ++scans;
    moving_scans += tracker.moving().empty() ? 0 : 1;
  }
  return {moving_scans, scans};
}

TEST(ClusterTracker, APillarSeenFromADrivingRobotIsNotMoving) {
  const auto [moving, scans] = scans_a_passed_pillar_is_moving(ClusterTrackerParams{});
  EXPECT_EQ(moving, 0) << "of " << scans << " scans";
  ClusterTrackerParams without;
  without.surface_moved_m = 0.0;
  EXPECT_GT(scans_a_passed_pillar_is_moving(without).first, 0);
}

// A walker who passes out of the laser's arc (behind the robot) is kept, coasting on its velocity, for
// lost_out_of_view_after_s: the robot cannot see them go on, and a turn on the spot would swing its back into them. One
// who vanishes in plain view is dropped after lost_after_s.
TEST(ClusterTracker, AWalkerOutOfTheLasersArcCoastsOneGoneInViewIsDropped) {
  const LaserArc arc{0.0, -kPi / 2, kPi / 2};
  std::vector<Eigen::Vector2d> points;
  std::vector<float> ranges;
  {
    World world;
    const Disc behind{{2.0, 1.0}, {-0.6, 0.0}, 0.25};  // out of the arc (x < -0.25) from t = 3.75 s
    world.discs = {behind};
    mapping::PtemModel model(mapping::PtemParams{});
    ClusterTracker tracker;
    for (int k = 0; k <= 50; ++k) {
      const double t = k * kScanPeriod_s;
      insert(model, world, {0.0, 0.0}, 0.0, t, points, ranges);
      tracker.update(*model.snapshot(), {0.0, 0.0}, kMaxRange_m, arc);
    }
    // At t = 5 s, 1.25 s out of view: still there, behind the robot, where its velocity took it (the velocity of a
    // disc half out of the arc is underestimated: its visible part lags).
    const std::vector<TrackedObstacle> moving = tracker.moving();
    const TrackedObstacle* walker = nearest_track(moving, behind.at(5.0));
    ASSERT_NE(walker, nullptr) << "the walker who went behind the robot was dropped";
    EXPECT_LT(walker->centre_W.x(), -0.25) << walker->centre_W.transpose();
    EXPECT_LT((walker->centre_W - behind.at(5.0)).norm(), 0.8) << walker->centre_W.transpose();
    EXPECT_DOUBLE_EQ(walker->stamp_s, 5.0);
  }
  {
    World world;
    const Disc ahead{{3.0, -1.5}, {0.0, 0.6}, 0.25};
    world.discs = {ahead};
    mapping::PtemModel model(mapping::PtemParams{});
    ClusterTracker tracker;
    bool was_moving = false;
    for (int k = 0; k <= 30; ++k) {
      const double t = k * kScanPeriod_s;
      if (k == 20) world.discs.clear();  // gone at t = 2 s, in the middle of the laser's view
      insert(model, world, {0.0, 0.0}, 0.0, t, points, ranges);
      tracker.update(*model.snapshot(), {0.0, 0.0}, kMaxRange_m, arc);
      if (k == 19) was_moving = !tracker.moving().empty();
    }
    EXPECT_TRUE(was_moving);
    EXPECT_TRUE(tracker.moving().empty()) << "a walker unseen in view for a second is still tracked";
  }
}

// A tracked person (0.25 m disc) at centre_W walking at velocity_W, world frame.
TrackedObstacle walking_person(const Eigen::Vector2d& centre_W, const Eigen::Vector2d& velocity_W) {
  TrackedObstacle person;
  person.centre_W = centre_W;
  person.velocity_W = velocity_W;
  person.radius_m = 0.25;
  person.moving = true;
  return person;
}

TEST(SafetyGuard, StopsAMotionIntoAWalkersPredictedPathButNotOneOutOfIt) {
  const geometry::Footprint bearcat = bearcat_shape().footprint;
  // A person 1.2 m ahead of the front, 1.4 m to the right, walking left at 0.7 m/s: crosses 2 s from now.
  const std::vector<TrackedObstacle> moving{walking_person({1.7, -1.4}, {0.0, 0.7})};
  const GuardParams params;
  const GuardDecision ahead = guard_command({}, bearcat, {0.0, 0.0, 0.0}, 0.6, 0.0, params, moving);
  EXPECT_NE(ahead.action, GuardAction::kPass);
  EXPECT_EQ(ahead.model, "moving");
  const GuardDecision without = guard_command({}, bearcat, {0.0, 0.0, 0.0}, 0.6, 0.0, params);
  EXPECT_EQ(without.action, GuardAction::kPass);
  // Walking straight at the robot: backing away is what gets it out, and is not stopped.
  const std::vector<TrackedObstacle> head_on{walking_person({2.5, 0.0}, {-0.6, 0.0})};
  EXPECT_EQ(guard_command({}, bearcat, {0.0, 0.0, 0.0}, -0.4, 0.0, params, head_on).action, GuardAction::kPass);
}

TEST(SafetyGuard, AMotionThatClosesInOnAPersonComingAtTheRobotIsStopped) {
  const geometry::Footprint bearcat = bearcat_shape().footprint;
  // A person 0.15 m off the robot's left side (within the prediction margin already), drifting towards it at
  // 0.2 m/s: standing still, the robot is touched within a second whatever it does.
  const std::vector<TrackedObstacle> beside{walking_person({0.3, 0.8}, {0.0, -0.2})};
  const GuardParams params;
  // Turning left in place swings the front left corner into the person; so does an arc to the left.
  const GuardDecision turn_into = guard_command({}, bearcat, {0.0, 0.0, 0.0}, 0.0, 0.8, params, beside);
  EXPECT_EQ(turn_into.action, GuardAction::kStop);
  EXPECT_EQ(turn_into.model, "moving");
  EXPECT_EQ(guard_command({}, bearcat, {0.0, 0.0, 0.0}, 0.3, 0.8, params, beside).action, GuardAction::kStop);
  // Turning or arcing away to the right, or driving on out of the person's way, opens the gap: not stopped.
  EXPECT_EQ(guard_command({}, bearcat, {0.0, 0.0, 0.0}, 0.0, -0.8, params, beside).action, GuardAction::kPass);
  EXPECT_EQ(guard_command({}, bearcat, {0.0, 0.0, 0.0}, 0.4, -0.8, params, beside).action, GuardAction::kPass);
  const GuardDecision ahead = guard_command({}, bearcat, {0.0, 0.0, 0.0}, 0.6, 0.0, params, beside);
  EXPECT_EQ(ahead.action, GuardAction::kPass) << ahead.zone << " " << ahead.time_to_contact_s;
}

// The command source under the yielding: drives straight along its heading at a fixed speed.
class Straight final : public Behaviour {
 public:
  explicit Straight(double speed_mps) : speed_mps_(speed_mps) {}
  [[nodiscard]] std::string_view name() const override { return "goto"; }
  BehaviourCommand decide(const BehaviourInput& /*input*/) override {
    BehaviourCommand command;
    command.linear_mps = speed_mps_;
    command.state = BehaviourState::kStepToGoal;
    return command;
  }

 private:
  double speed_mps_;
};

struct DriveRun {
  std::set<std::string> states;
  double closest_gap_m = std::numeric_limits<double>::infinity();  // footprint to the person's disc
  std::vector<geometry::Pose2> poses;
  std::vector<std::string> state_per_step;
};

DriveRun drive(const World& world, Behaviour& behaviour, const RobotShape& robot, geometry::Pose2 pose,
               double seconds) {
  mapping::PtemModel model(mapping::PtemParams{});
  std::vector<Eigen::Vector2d> points;
  std::vector<float> ranges;
  DriveRun run;
  const int steps = static_cast<int>(seconds / kScanPeriod_s);
  for (int k = 0; k < steps; ++k) {
    const double t = k * kScanPeriod_s;
    const Eigen::Vector2d p_WS =
        pose.position() + robot.laser_x_m * Eigen::Vector2d(std::cos(pose.theta), std::sin(pose.theta));
    insert(model, world, p_WS, pose.theta, t, points, ranges);
    const auto snapshot = model.snapshot();
    BehaviourInput input;
    input.scan = {-kPi / 2, kPi / (kBeams - 1), ranges, kMaxRange_m};
    input.X_WB = pose;
    input.stamp_s = t;
    input.ptem = snapshot.get();
    const BehaviourCommand command = behaviour.decide(input);
    run.states.insert(std::string(name(command.state)));
    run.state_per_step.emplace_back(name(command.state));
    if (!command.stop) pose = advance_pose(pose, command.linear_mps, command.angular_radps, kScanPeriod_s);
    run.poses.push_back(pose);
    for (const Disc& disc : world.discs) {
      run.closest_gap_m = std::min(
          run.closest_gap_m, distance_to_footprint(robot.footprint, pose, disc.at(t + kScanPeriod_s)) - disc.radius_m);
    }
  }
  return run;
}

TEST(Yield, WaitsShortOfAPersonCrossingAheadThenGoesOn) {
  World world;
  // A person crosses the robot's line at x = 3.2 from the right at 0.6 m/s, reaching it after about 4.8 s, as the
  // robot's front (0.5 m/s) would.
  world.discs = {{{3.2, -2.9}, {0.0, 0.6}, 0.25}};
  const RobotShape robot = bearcat_shape();
  auto behaviour = make_yield(std::make_unique<Straight>(0.5), robot, GuardParams{});
  const DriveRun run = drive(world, *behaviour, robot, {0.0, 0.0, 0.0}, 14.0);
  EXPECT_TRUE(run.states.contains("yield_wait") || run.states.contains("yield_slow"));
  EXPECT_GT(run.closest_gap_m, 0.1) << "the robot reached the person";
  // It stood short of the crossing while waiting (its front before the person's near side), not in it.
  for (std::size_t k = 0; k < run.poses.size(); ++k) {
    if (run.state_per_step[k] == "yield_wait") {
      EXPECT_LT(run.poses[k].x + 0.5, 3.2 - 0.25);
    }
  }
  EXPECT_GT(run.poses.back().x, 4.5) << "the robot went on after the person had passed";
  EXPECT_EQ(run.state_per_step.back(), "step_to_goal");

  // Without the yielding the same robot drives into the person.
  Straight plain(0.5);
  EXPECT_LT(drive(world, plain, robot, {0.0, 0.0, 0.0}, 14.0).closest_gap_m, 0.0);
}

TEST(Yield, StepsAsideFromAPersonWalkingHeadOn) {
  World world;
  world.discs = {{{6.0, 0.05}, {-0.5, 0.0}, 0.25}};
  const RobotShape robot = bearcat_shape();
  auto behaviour = make_yield(std::make_unique<Straight>(0.3), robot, GuardParams{});
  const DriveRun run = drive(world, *behaviour, robot, {0.0, 0.0, 0.0}, 16.0);
  EXPECT_TRUE(run.states.contains("yield_aside"));
  EXPECT_GT(run.closest_gap_m, 0.0) << "the person walked into the robot";
  double widest_m = 0.0;
  for (const geometry::Pose2& pose : run.poses) widest_m = std::max(widest_m, std::abs(pose.y));
  EXPECT_GT(widest_m, 0.3) << "the robot did not leave the person's line";

  // Standing still in the person's way gets it hit: stepping aside is what avoided it.
  Straight standing(0.0);
  EXPECT_LT(drive(world, standing, robot, {0.0, 0.0, 0.0}, 16.0).closest_gap_m, 0.0);
}

TEST(Yield, GetsOutOfTheWayOfSomethingComingAlongAWallThatNoTrackFollows) {
  World world;
  // A wall 0.9 m to the robot's left and a person walking along it, 0.15 m from it, head-on at 0.45 m/s: a cluster
  // that close to a wall is taken for part of it, so the tracker never calls it moving. The robot stands in the way.
  world.walls = {{{-3.0, 0.9}, {10.0, 0.9}}};
  world.discs = {{{6.0, 0.5}, {-0.45, 0.0}, 0.25}};
  const RobotShape robot = bearcat_shape();
  {
    mapping::PtemModel model(mapping::PtemParams{});
    ClusterTracker tracker;
    std::vector<Eigen::Vector2d> points;
    std::vector<float> ranges;
    for (int k = 0; k <= 40; ++k) {
      const double t = k * kScanPeriod_s;
      insert(model, world, {robot.laser_x_m, 0.0}, 0.0, t, points, ranges);
      tracker.update(*model.snapshot(), {robot.laser_x_m, 0.0}, kMaxRange_m);
      ASSERT_TRUE(tracker.moving().empty()) << "the tracker follows the walker at " << t << " s";
    }
  }
  auto behaviour = make_yield(std::make_unique<Straight>(0.0), robot, GuardParams{});
  const DriveRun run = drive(world, *behaviour, robot, {0.0, 0.0, 0.0}, 16.0);
  EXPECT_GT(run.closest_gap_m, 0.0) << "the person walked into the robot";
  EXPECT_TRUE(run.states.contains("yield_aside"));

  // Standing where it was gets it hit.
  Straight standing(0.0);
  EXPECT_LT(drive(world, standing, robot, {0.0, 0.0, 0.0}, 16.0).closest_gap_m, 0.0);
}

}  // namespace
}  // namespace occgeo::service::control
