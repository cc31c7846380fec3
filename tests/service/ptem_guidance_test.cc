// PTEM waypoint guidance (seed 004 §4.4–4.5): the virtual target and its waits, the admissible heading range on an
// analytic threat field, and closed-loop runs of a kinematic vehicle past the seed's obstacles (thin r = 0.055 m and
// cone r = 0.15 m at 1.75 m, §5.1) with the real PtemModel, fed either one scan or the vehicle's own scans.
#include "occgeo/service/control/ptem_guidance.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "occgeo/mapping/ptem.h"

namespace occgeo::service::control {
namespace {

constexpr double kPi = std::numbers::pi;

double wrap(double angle_rad) {
  double wrapped = std::remainder(angle_rad, 2.0 * kPi);
  if (wrapped <= -kPi) wrapped += 2.0 * kPi;
  return wrapped;
}

// No threat anywhere, but a threshold: what an empty PTEM looks like.
class EmptyField final : public ThreatField {
 public:
  mapping::PtemThreat threat_and_gradient(const Eigen::Vector2d&) const override { return {}; }
  std::optional<double> restricted_threshold() const override { return 0.04; }
};

// One isotropic Gaussian f = exp(-|p - c|² / 2σ²) restricted from radius_m on: f_r = exp(-radius² / 2σ²).
class GaussianField final : public ThreatField {
 public:
  GaussianField(Eigen::Vector2d centre_W, double sigma_m, double radius_m)
      : centre_W_(std::move(centre_W)), sigma_m_(sigma_m), radius_m_(radius_m) {}
  mapping::PtemThreat threat_and_gradient(const Eigen::Vector2d& p_W) const override {
    const Eigen::Vector2d offset = p_W - centre_W_;
    const double value = std::exp(-offset.squaredNorm() / (2.0 * sigma_m_ * sigma_m_));
    return {value, -value * offset / (sigma_m_ * sigma_m_)};
  }
  std::optional<double> restricted_threshold() const override {
    return std::exp(-radius_m_ * radius_m_ / (2.0 * sigma_m_ * sigma_m_));
  }
  const Eigen::Vector2d& centre_W() const { return centre_W_; }

 private:
  Eigen::Vector2d centre_W_;
  double sigma_m_;
  double radius_m_;
};

// A disc obstacle of the simulated world.
struct Disc {
  Eigen::Vector2d centre_W;
  double radius_m;
};

// The URG-04LX of the seed (§3.2.1): 240 degrees, 683 beams, 4 m; the returns of the discs from a sensor pose.
std::vector<Eigen::Vector2d> scan_points(const Pose2& sensor, const std::vector<Disc>& discs) {
  constexpr int kBeams = 683;
  constexpr double kFieldOfView = 240.0 * kPi / 180.0;
  constexpr double kMaxRange = 4.0;
  std::vector<Eigen::Vector2d> points;
  const Eigen::Vector2d origin(sensor.x, sensor.y);
  for (int i = 0; i < kBeams; ++i) {
    const double angle = sensor.theta - kFieldOfView / 2.0 + kFieldOfView * i / (kBeams - 1);
    const Eigen::Vector2d direction(std::cos(angle), std::sin(angle));
    double nearest = std::numeric_limits<double>::infinity();
    for (const Disc& disc : discs) {
      const Eigen::Vector2d to_centre = disc.centre_W - origin;
      const double along = to_centre.dot(direction);
      const double miss_sq = to_centre.squaredNorm() - along * along;
      const double half_chord_sq = disc.radius_m * disc.radius_m - miss_sq;
      if (half_chord_sq < 0.0) continue;
      const double range = along - std::sqrt(half_chord_sq);
      if (range > 0.0) nearest = std::min(nearest, range);
    }
    if (nearest < kMaxRange) points.push_back(origin + nearest * direction);
  }
  return points;
}

void insert_scan(mapping::PtemModel& model, const Pose2& sensor, double stamp_s, const std::vector<Disc>& discs) {
  const std::vector<Eigen::Vector2d> points = scan_points(sensor, discs);
  mapping::PtemScan scan;
  scan.stamp_s = stamp_s;
  scan.p_WS = Eigen::Vector2d(sensor.x, sensor.y);
  scan.yaw_WS = sensor.theta;
  scan.field_of_view_rad = 240.0 * kPi / 180.0;
  scan.max_range_m = 4.0;
  scan.points_W = points;
  model.insert_scan(scan);
}

// Unicycle kinematics, integrated in 10 ms steps.
Pose2 drive(Pose2 pose, double linear_mps, double angular_radps, double duration_s) {
  constexpr double kStep_s = 0.01;
  for (double t = 0.0; t < duration_s - 1e-12; t += kStep_s) {
    pose.x += linear_mps * std::cos(pose.theta) * kStep_s;
    pose.y += linear_mps * std::sin(pose.theta) * kStep_s;
    pose.theta += angular_radps * kStep_s;
  }
  return pose;
}

// Whether some point of the vehicle's disc (its centre and 32 points on its rim) is restricted.
bool body_restricted(const mapping::PtemSnapshot& snapshot, const Pose2& pose, double body_radius_m) {
  const Eigen::Vector2d p(pose.x, pose.y);
  if (snapshot.restricted(p)) return true;
  for (int i = 0; i < 32 && body_radius_m > 0.0; ++i) {
    const double angle = 2.0 * kPi * i / 32.0;
    if (snapshot.restricted(p + body_radius_m * Eigen::Vector2d(std::cos(angle), std::sin(angle)))) return true;
  }
  return false;
}

struct RunResult {
  bool reached = false;
  double time_s = 0.0;
  bool entered_restricted = false;
  double min_obstacle_gap_m = std::numeric_limits<double>::infinity();  // body edge to obstacle surface
  std::vector<std::size_t> waypoint_indices;                            // as the decisions reported them
  std::vector<Pose2> poses;
  int avoid_decisions = 0;
};

constexpr double kControlPeriod_s = 0.1;

// Closed loop: a scan (when live) and a decision every 100 ms, the vehicle driving the command in between.
RunResult run_closed_loop(PtemGuidance& guidance, const std::function<std::vector<Disc>(double)>& discs_at,
                          bool live_scans, mapping::PtemModel& model, double max_time_s) {
  RunResult run;
  Pose2 pose{0.0, 0.0, 0.0};
  const double body_radius_m = guidance.params().body_radius_m;
  for (double t = 0.0; t <= max_time_s; t += kControlPeriod_s) {
    const std::vector<Disc> discs = discs_at(t);
    if (live_scans) insert_scan(model, pose, t, discs);
    const std::shared_ptr<const mapping::PtemSnapshot> snapshot = model.snapshot();
    run.entered_restricted = run.entered_restricted || body_restricted(*snapshot, pose, body_radius_m);
    for (const Disc& disc : discs) {
      run.min_obstacle_gap_m =
          std::min(run.min_obstacle_gap_m,
                   (Eigen::Vector2d(pose.x, pose.y) - disc.centre_W).norm() - disc.radius_m - body_radius_m);
    }
    const PtemGuidanceDecision decision = guidance.decide(pose, t, *snapshot);
    run.poses.push_back(pose);
    if (run.waypoint_indices.empty() || run.waypoint_indices.back() != decision.waypoint_index) {
      run.waypoint_indices.push_back(decision.waypoint_index);
    }
    if (decision.state == BehaviourState::kAvoid || decision.state == BehaviourState::kEscape) ++run.avoid_decisions;
    if (decision.reached) {
      run.reached = true;
      run.time_s = t;
      return run;
    }
    pose = drive(pose, decision.linear_mps, decision.angular_radps, kControlPeriod_s);
  }
  run.time_s = max_time_s;
  return run;
}

// Distance from p to the polyline through the points.
double distance_to_polyline(const Eigen::Vector2d& p, const std::vector<Eigen::Vector2d>& points) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < points.size(); ++i) {
    const Eigen::Vector2d along = points[i + 1] - points[i];
    const double t = std::clamp((p - points[i]).dot(along) / along.squaredNorm(), 0.0, 1.0);
    best = std::min(best, (points[i] + t * along - p).norm());
  }
  return best;
}

TEST(PtemGuidance, TracksWaypointsInTheOpen) {
  const std::vector<Eigen::Vector2d> waypoints{{3.0, 0.0}, {3.0, 3.0}, {0.0, 3.0}};
  PtemGuidance guidance(PtemGuidanceParams{}, waypoints);
  mapping::PtemModel empty(mapping::PtemParams{});
  const auto no_obstacles = [](double) { return std::vector<Disc>{}; };
  const RunResult run = run_closed_loop(guidance, no_obstacles, false, empty, 120.0);
  ASSERT_TRUE(run.reached);
  // 9 m of legs at the target's 0.25 m/s is 36 s, plus the waits at the corners.
  EXPECT_LT(run.time_s, 50.0);
  EXPECT_EQ(run.waypoint_indices, (std::vector<std::size_t>{0, 1, 2}));
  EXPECT_EQ(run.avoid_decisions, 0);
  // The vehicle cuts the corners by less than the proximity circle.
  std::vector<Eigen::Vector2d> legs{{0.0, 0.0}};
  legs.insert(legs.end(), waypoints.begin(), waypoints.end());
  double worst_m = 0.0;
  for (const Pose2& pose : run.poses) {
    worst_m = std::max(worst_m, distance_to_polyline({pose.x, pose.y}, legs));
  }
  EXPECT_LT(worst_m, guidance.params().proximity_radius_m);
  const Pose2& last = run.poses.back();
  EXPECT_LE((Eigen::Vector2d(last.x, last.y) - waypoints.back()).norm(), guidance.params().arrival_tolerance_m);
}

TEST(PtemGuidance, VirtualTargetWaitsAtEachWaypoint) {
  PtemGuidance guidance(PtemGuidanceParams{}, {{1.0, 0.0}, {1.0, 1.0}});
  const EmptyField field;
  const Pose2 parked{0.0, 0.0, 0.0};
  PtemGuidanceDecision decision = guidance.decide(parked, 0.0, field);
  EXPECT_TRUE(decision.target_W.isApprox(Eigen::Vector2d::Zero()));  // the target starts at the vehicle
  decision = guidance.decide(parked, 2.0, field);
  EXPECT_NEAR(decision.target_W.x(), 0.5, 1e-12);  // 0.25 m/s
  EXPECT_FALSE(decision.target_waiting);
  // The vehicle stays 1 m away: the target reaches the waypoint after 4 s and waits there.
  for (double t = 2.5; t <= 20.0; t += 0.5) decision = guidance.decide(parked, t, field);
  EXPECT_TRUE(decision.target_W.isApprox(Eigen::Vector2d(1.0, 0.0)));
  EXPECT_TRUE(decision.target_waiting);
  EXPECT_EQ(decision.waypoint_index, 0U);
  EXPECT_FALSE(decision.reached);
  // Inside the proximity circle (0.5 m) the target moves on, using the whole interval.
  decision = guidance.decide(Pose2{0.6, 0.0, 0.0}, 21.0, field);
  EXPECT_EQ(decision.waypoint_index, 1U);
  EXPECT_FALSE(decision.target_waiting);
  EXPECT_TRUE(decision.target_W.isApprox(Eigen::Vector2d(1.0, 0.25)));
  // At the last waypoint it waits for the vehicle to arrive within arrival_tolerance_m, then the run is over.
  decision = guidance.decide(Pose2{0.6, 0.0, 0.0}, 30.0, field);
  EXPECT_TRUE(decision.target_W.isApprox(Eigen::Vector2d(1.0, 1.0)));
  EXPECT_FALSE(decision.reached);
  decision = guidance.decide(Pose2{1.0, 0.9, kPi / 2.0}, 31.0, field);
  EXPECT_TRUE(decision.reached);
  EXPECT_TRUE(decision.stop);
  EXPECT_EQ(decision.linear_mps, 0.0);
  EXPECT_EQ(decision.angular_radps, 0.0);
  EXPECT_EQ(decision.state, BehaviourState::kReached);
}

TEST(PtemGuidance, TargetPausesWhenTooFarAhead) {
  PtemGuidance guidance(PtemGuidanceParams{}, {{5.0, 0.0}});
  const EmptyField field;
  PtemGuidanceDecision decision;
  for (double t = 0.0; t <= 30.0; t += 0.1) decision = guidance.decide(Pose2{0.0, 0.0, 0.0}, t, field);
  // It stops once it is more than max_target_lead_m (1.5 m) ahead; at most one 0.1 s step beyond.
  EXPECT_GT(decision.target_W.x(), 1.5);
  EXPECT_LE(decision.target_W.x(), 1.5 + 0.25 * 0.1 + 1e-9);
  EXPECT_TRUE(decision.target_waiting);
}

// A guidance one second after starting at pose, the target heading along desired_rad: its decision.
PtemGuidanceDecision decide_with_desired(const PtemGuidanceParams& params, const Pose2& pose, double desired_rad,
                                         const ThreatField& field) {
  const Eigen::Vector2d p(pose.x, pose.y);
  PtemGuidance guidance(params, {p + 5.0 * Eigen::Vector2d(std::cos(desired_rad), std::sin(desired_rad))});
  guidance.decide(pose, 0.0, field);
  return guidance.decide(pose, 1.0, field);
}

TEST(PtemGuidance, CommandsTheAdmissibleHeadingClosestToTheDesiredOne) {
  // Restricted within 0.3 m of the origin; the vehicle 0.2 m outside that, where the whole half-plane of headings
  // with a non-positive directional derivative is admissible.
  const GaussianField field({0.0, 0.0}, 0.1, 0.3);
  const PtemGuidanceParams params;
  const Pose2 pose{0.5, 0.0, 0.0};
  int checked = 0;
  for (int k = -179; k <= 180; ++k) {
    const double desired_rad = k * kPi / 180.0;
    const PtemGuidanceDecision decision = decide_with_desired(params, pose, desired_rad, field);
    ASSERT_TRUE(decision.heading_constrained);
    ASSERT_NEAR(decision.clearance_m, 0.2, 1e-9);  // exact for one Gaussian
    ASSERT_NEAR(decision.desired_heading_rad, desired_rad, 1e-9);
    EXPECT_NEAR(decision.admissible_centre_rad, 0.0, 1e-12);  // straight away from the threat
    EXPECT_NEAR(decision.admissible_half_width_rad, kPi / 2.0, 1e-12);
    const mapping::PtemThreat threat = field.threat_and_gradient({pose.x, pose.y});
    const Eigen::Vector2d commanded(std::cos(decision.commanded_heading_rad), std::sin(decision.commanded_heading_rad));
    EXPECT_LE(threat.gradient_W.dot(commanded), 1e-12) << "desired " << k << " deg";
    const double deviation = std::abs(wrap(decision.commanded_heading_rad - desired_rad));
    const double needed = std::max(0.0, std::abs(desired_rad) - kPi / 2.0);
    if (std::abs(desired_rad) < kPi - params.side_hysteresis_rad) {
      EXPECT_NEAR(deviation, needed, 1e-9) << "desired " << k << " deg";
      ++checked;
    } else {
      // Nearly straight into the threat the side is a tie-break; either boundary is admissible.
      EXPECT_NEAR(std::abs(decision.commanded_heading_rad), kPi / 2.0, 1e-9);
    }
  }
  EXPECT_GT(checked, 300);
}

TEST(PtemGuidance, SlowsWhenHeadingIntoTheThreat) {
  const GaussianField field({0.0, 0.0}, 0.1, 0.3);
  PtemGuidanceParams params;
  // Facing the threat with the target right behind it: no forward speed beyond clearance / horizon.
  const PtemGuidanceDecision decision = decide_with_desired(params, Pose2{0.5, 0.0, kPi}, kPi, field);
  EXPECT_NEAR(decision.clearance_m, 0.2, 1e-9);
  EXPECT_EQ(decision.state, BehaviourState::kAvoid);
  EXPECT_NEAR(decision.max_admissible_speed_mps, decision.clearance_m / params.speed_horizon_s, 1e-9);
  EXPECT_LE(decision.linear_mps, decision.max_admissible_speed_mps);
  EXPECT_NE(decision.angular_radps, 0.0);
}

TEST(PtemGuidance, EscapesFromInsideTheRestrictedRegion) {
  const GaussianField field({0.0, 0.0}, 0.1, 0.3);
  const PtemGuidanceParams params;
  // Inside, 0.2 m from the centre toward +x+y, the target on the far side.
  const Pose2 pose{0.2 * std::cos(0.5), 0.2 * std::sin(0.5), 0.0};
  const PtemGuidanceDecision decision = decide_with_desired(params, pose, 0.5 + kPi, field);
  EXPECT_EQ(decision.state, BehaviourState::kEscape);
  EXPECT_LT(decision.clearance_m, 0.0);
  EXPECT_NEAR(decision.admissible_centre_rad, 0.5, 1e-9);
  EXPECT_NEAR(decision.admissible_half_width_rad, params.escape_half_angle_rad, 1e-12);
  EXPECT_LE(std::abs(wrap(decision.commanded_heading_rad - 0.5)), params.escape_half_angle_rad + 1e-9);
}

TEST(PtemGuidance, AvoidsAFixedClusterOnTheLineAndReachesTheWaypoint) {
  // The seed's cone (r = 0.15 m) 1.75 m ahead, seen once from the start: the PTEM stays as that scan made it.
  const std::vector<Disc> discs{{{1.75, 0.0}, 0.15}};
  mapping::PtemModel model(mapping::PtemParams{});
  insert_scan(model, Pose2{0.0, 0.0, 0.0}, 0.0, discs);
  ASSERT_GE(model.cluster_count(), 1U);
  ASSERT_TRUE(model.snapshot()->restricted({1.6, 0.0}));  // the straight line is blocked
  PtemGuidanceParams params;
  params.body_radius_m = 0.19;  // the seed's UGV is 0.381 m wide
  PtemGuidance guidance(params, {{3.5, 0.0}});
  const RunResult run = run_closed_loop(
      guidance, [&](double) { return discs; }, false, model, 90.0);
  EXPECT_TRUE(run.reached);
  EXPECT_FALSE(run.entered_restricted);
  EXPECT_GT(run.min_obstacle_gap_m, 0.0);
  EXPECT_GT(run.avoid_decisions, 0);
  // It went round: some pose well off the line.
  double widest_m = 0.0;
  for (const Pose2& pose : run.poses) widest_m = std::max(widest_m, std::abs(pose.y));
  EXPECT_GT(widest_m, 0.3);
}

TEST(PtemGuidance, AvoidsTheSeedObstaclesWithLiveScans) {
  // Seed 004 §5.1: the thin obstacle and the cone at 1.75 m on the line, the PTEM rebuilt from every scan
  // (single-scan construction), the vehicle driving its own commands.
  for (const double obstacle_radius_m : {0.055, 0.15}) {
    SCOPED_TRACE("obstacle radius " + std::to_string(obstacle_radius_m));
    const std::vector<Disc> discs{{{1.75, 0.0}, obstacle_radius_m}};
    mapping::PtemModel model(mapping::PtemParams{});
    PtemGuidanceParams params;
    params.body_radius_m = 0.19;
    PtemGuidance guidance(params, {{3.5, 0.0}, {3.5, 1.0}});
    const RunResult run = run_closed_loop(
        guidance, [&](double) { return discs; }, true, model, 120.0);
    EXPECT_TRUE(run.reached);
    EXPECT_FALSE(run.entered_restricted);
    EXPECT_GT(run.min_obstacle_gap_m, 0.0);
    EXPECT_LT(run.time_s, 60.0);
  }
}

TEST(PtemGuidance, AvoidsTheSeedMovingObstacles) {
  // Seed 004 §6: the cone moving at 0.1 m/s toward the vehicle from (3.3, 0), and crossing at 0.2 m/s from (1.75, -1)
  // to (1.75, 1); single-scan PTEM from the vehicle's scans.
  const std::vector<std::function<std::vector<Disc>(double)>> worlds{
      [](double t) {
        return std::vector<Disc>{{{3.3 - 0.1 * t, 0.0}, 0.15}};
      },
      [](double t) {
        return std::vector<Disc>{{{1.75, -1.0 + std::min(2.0, 0.2 * t)}, 0.15}};
      },
  };
  for (std::size_t i = 0; i < worlds.size(); ++i) {
    SCOPED_TRACE("world " + std::to_string(i));
    mapping::PtemModel model(mapping::PtemParams{});
    PtemGuidanceParams params;
    params.body_radius_m = 0.19;
    PtemGuidance guidance(params, {{3.5, 0.0}});
    const RunResult run = run_closed_loop(guidance, worlds[i], true, model, 90.0);
    EXPECT_TRUE(run.reached);
    EXPECT_FALSE(run.entered_restricted);
    EXPECT_GT(run.min_obstacle_gap_m, 0.1);
  }
}

TEST(PtemGuidance, RejectsBadInputNamingTheField) {
  PtemGuidanceParams params;
  params.max_speed_mps = 0.1;  // below the target's speed
  try {
    PtemGuidance guidance(params, {{1.0, 0.0}});
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("max_speed_mps"), std::string::npos) << error.what();
  }
  try {
    PtemGuidance guidance(PtemGuidanceParams{}, {});
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("waypoints"), std::string::npos) << error.what();
  }
  try {
    PtemGuidance guidance(PtemGuidanceParams{}, {{1.0, 0.0}, {std::nan(""), 0.0}});
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("waypoints[1]"), std::string::npos) << error.what();
  }
  PtemGuidance guidance(PtemGuidanceParams{}, {{1.0, 0.0}});
  const EmptyField field;
  guidance.decide(Pose2{}, 1.0, field);
  try {
    guidance.decide(Pose2{}, 0.5, field);
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("time_s"), std::string::npos) << error.what();
  }
  try {
    guidance.decide(Pose2{0.0, std::numeric_limits<double>::infinity(), 0.0}, 2.0, field);
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("pose.y"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace occgeo::service::control
