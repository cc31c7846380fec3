// The Bearcat III behaviour of seed 000 (§4.2–4.3 and the appendix source) on synthetic LMS200 scans, ray-cast
// against simple scenes in the sensor frame (x forward, y left, metres).
#include "occgeo/service/control/bearcat.h"

#include <gtest/gtest.h>

#include "../support/error_message.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <functional>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

namespace occgeo::service::control {
namespace {

// Bearings come from angle_min + i * increment in double: they are exact to far better than this, degrees.
constexpr double kBearingTolerance_deg = 1e-9;
// Speeds are a few double operations on values near 1 m/s.
constexpr double kSpeedTolerance_mps = 1e-12;
// steerCAR's wheel speed in m/s per Galil count: base_speed 15000 counts is 0.5 m/s.
constexpr double kMpsPerCount = 0.5 / 15000.0;

double radians(double degrees) { return degrees * std::numbers::pi / 180.0; }
double degrees(double radians) { return radians * 180.0 / std::numbers::pi; }

struct Circle {
  double x_m;
  double y_m;
  double radius_m;
};

struct Segment {
  double x0_m;
  double y0_m;
  double x1_m;
  double y1_m;
};

struct Scene {
  std::vector<Circle> circles;
  std::vector<Segment> segments;
};

struct BeamLayout {
  double angle_min_rad;
  double angle_increment_rad;
  std::size_t beam_count;
  double range_max_m;
};

// The Bearcat's SICK LMS200: 181 beams from -90 to +90 degrees at 1 degree, set to 8 m (§3.2.3).
const BeamLayout kLms200{radians(-90.0), radians(1.0), 181, 8.0};
// A Hokuyo URG-like 240 degree scan at 0.35 degrees; no beam shares a bearing with the LMS200's.
const BeamLayout kHokuyo240{radians(-120.0), radians(0.35), 686, 5.6};

// Distance along the unit ray (dx, dy) from the origin to the circle, or +inf when it misses.
double ray_distance(double dx, double dy, const Circle& circle) {
  const double along = circle.x_m * dx + circle.y_m * dy;
  const double off_axis_squared = circle.x_m * circle.x_m + circle.y_m * circle.y_m - along * along;
  const double radius_squared = circle.radius_m * circle.radius_m;
  if (off_axis_squared > radius_squared) return std::numeric_limits<double>::infinity();
  const double entry = along - std::sqrt(radius_squared - off_axis_squared);
  return entry > 0.0 ? entry : std::numeric_limits<double>::infinity();
}

// Distance along the unit ray (dx, dy) from the origin to the segment, or +inf when it misses.
double ray_distance(double dx, double dy, const Segment& segment) {
  const double ex = segment.x1_m - segment.x0_m;
  const double ey = segment.y1_m - segment.y0_m;
  const double denominator = dx * ey - dy * ex;
  if (denominator == 0.0) return std::numeric_limits<double>::infinity();
  const double along_ray = (segment.x0_m * ey - segment.y0_m * ex) / denominator;
  const double along_segment = (segment.x0_m * dy - segment.y0_m * dx) / denominator;
  if (along_ray <= 0.0 || along_segment < 0.0 || along_segment > 1.0) return std::numeric_limits<double>::infinity();
  return along_ray;
}

// A ray-cast scan that owns its ranges.
struct SyntheticScan {
  BeamLayout layout;
  std::vector<float> ranges_m;

  ScanView view() const {
    return ScanView{layout.angle_min_rad, layout.angle_increment_rad, ranges_m, layout.range_max_m};
  }

  // The recorded range of the LMS200 beam at a whole-degree bearing.
  double lms200_range_at(int bearing_deg) const {
    return static_cast<double>(ranges_m.at(static_cast<std::size_t>(bearing_deg + 90)));
  }
};

SyntheticScan cast(const Scene& scene, const BeamLayout& layout = kLms200) {
  SyntheticScan scan{layout, {}};
  for (std::size_t beam = 0; beam < layout.beam_count; ++beam) {
    const double bearing = layout.angle_min_rad + static_cast<double>(beam) * layout.angle_increment_rad;
    const double dx = std::cos(bearing);
    const double dy = std::sin(bearing);
    double range = layout.range_max_m;
    for (const Circle& circle : scene.circles) range = std::min(range, ray_distance(dx, dy, circle));
    for (const Segment& segment : scene.segments) range = std::min(range, ray_distance(dx, dy, segment));
    scan.ranges_m.push_back(static_cast<float>(range));
  }
  return scan;
}

BearcatDecision decide_on(const SyntheticScan& scan) { return decide(scan.view(), BearcatParams{}); }

// Posts of 0.15 m radius 1 m ahead and 0.6 m to either side: inside the rectangle, bearings +-24..38 degrees.
const Circle kRightPost{1.0, -0.6, 0.15};
const Circle kLeftPost{1.0, 0.6, 0.15};
// A box face 1.5 m ahead across the middle zone, offset to the right (bearings -11..+7 degrees) or left.
const Segment kBoxAheadRightOfCentre{1.5, -0.3, 1.5, 0.2};
const Segment kBoxAheadLeftOfCentre{1.5, -0.2, 1.5, 0.3};
// A 0.3 m radius barrel 1.5 m ahead, 0.1 m left of the centre line (bearings -7.7..+15.3 degrees).
const Circle kBarrelAheadSlightlyLeft{1.5, 0.1, 0.3};
const Circle kBarrelAheadSlightlyRight{1.5, -0.1, 0.3};

// A room 2.1 m deep and 4.1 m wide around the robot, all of it closer than gap_range_m (its far corners are 2.94 m
// away) and outside the rectangle, with a doorway in the front wall from y = door_right_m to y = door_left_m.
std::vector<Segment> room_with_front_door(double door_right_m, double door_left_m) {
  return {{-0.1, -2.05, 2.1, -2.05},
          {-0.1, 2.05, 2.1, 2.05},
          {2.1, -2.05, 2.1, door_right_m},
          {2.1, door_left_m, 2.1, 2.05}};
}

void expect_wheels_from_counts(const BearcatDecision& decision, double left_counts, double right_counts) {
  EXPECT_NEAR(decision.left_wheel_mps, left_counts * kMpsPerCount, kSpeedTolerance_mps);
  EXPECT_NEAR(decision.right_wheel_mps, right_counts * kMpsPerCount, kSpeedTolerance_mps);
}

TEST(BearcatZonesTest, EmptyFieldIsClearAndDrivesStraightAtBaseSpeed) {
  const BearcatDecision decision = decide_on(cast(Scene{}));
  EXPECT_EQ(decision.ob_factor, 0);
  EXPECT_EQ(decision.state, BehaviourState::kClear);
  EXPECT_EQ(decision.steer_deg, 0.0);
  EXPECT_FALSE(decision.stop);
  EXPECT_EQ(decision.left_wheel_mps, 0.5);
  EXPECT_EQ(decision.right_wheel_mps, 0.5);
  EXPECT_EQ(decision.linear_mps, 0.5);
  EXPECT_EQ(decision.angular_radps, 0.0);
  for (const ZoneObservation& zone : decision.zones) EXPECT_FALSE(zone.obstacle_present);
}

TEST(BearcatZonesTest, ObstacleOnlyOnTheRightIsCase1AndTurnsLeftBy10Degrees) {
  const BearcatDecision decision = decide_on(cast(Scene{{kRightPost}, {}}));
  EXPECT_EQ(decision.ob_factor, 1);
  EXPECT_EQ(decision.state, BehaviourState::kAvoidRightObstacle);
  EXPECT_EQ(decision.steer_deg, 10.0);
  // steerCAR(10): 15000 -+ 134.5 * 10 counts.
  expect_wheels_from_counts(decision, 13655.0, 16345.0);
  EXPECT_GT(decision.right_wheel_mps, decision.left_wheel_mps);
  EXPECT_NEAR(decision.angular_radps, 2690.0 * kMpsPerCount / 0.7, kSpeedTolerance_mps);
}

TEST(BearcatZonesTest, ObstaclesRightAndMiddleAreCase12AndTurnLeftBy15Degrees) {
  const BearcatDecision decision = decide_on(cast(Scene{{kRightPost}, {kBoxAheadRightOfCentre}}));
  EXPECT_EQ(decision.ob_factor, 12);
  EXPECT_EQ(decision.state, BehaviourState::kAvoidRightObstacle);
  EXPECT_EQ(decision.steer_deg, 15.0);
  expect_wheels_from_counts(decision, 12982.5, 17017.5);
}

TEST(BearcatZonesTest, ObstaclesMiddleAndLeftAreCase23AndTurnRightBy15Degrees) {
  const BearcatDecision decision = decide_on(cast(Scene{{kLeftPost}, {kBoxAheadLeftOfCentre}}));
  EXPECT_EQ(decision.ob_factor, 23);
  EXPECT_EQ(decision.state, BehaviourState::kAvoidLeftObstacle);
  EXPECT_EQ(decision.steer_deg, -15.0);
  expect_wheels_from_counts(decision, 17017.5, 12982.5);
}

TEST(BearcatZonesTest, ObstacleOnlyOnTheLeftIsCase3AndTurnsRightBy15Degrees) {
  const BearcatDecision decision = decide_on(cast(Scene{{kLeftPost}, {}}));
  EXPECT_EQ(decision.ob_factor, 3);
  EXPECT_EQ(decision.state, BehaviourState::kAvoidLeftObstacle);
  EXPECT_EQ(decision.steer_deg, -15.0);
  EXPECT_LT(decision.angular_radps, 0.0);
}

TEST(BearcatZonesTest, PostsEitherSideWithClearMiddleAreCase13AndPassBetweenStraight) {
  const BearcatDecision decision = decide_on(cast(Scene{{kRightPost, kLeftPost}, {}}));
  EXPECT_EQ(decision.ob_factor, 13);
  EXPECT_EQ(decision.state, BehaviourState::kPassBetween);
  EXPECT_EQ(decision.steer_deg, 0.0);
  EXPECT_EQ(decision.left_wheel_mps, 0.5);
  EXPECT_EQ(decision.right_wheel_mps, 0.5);
}

TEST(BearcatZonesTest, WallAcrossTheFrontIsCase123AndStopsInDeadlock) {
  const BearcatDecision decision = decide_on(cast(Scene{{}, {{1.0, -3.0, 1.0, 3.0}}}));
  EXPECT_EQ(decision.ob_factor, 123);
  EXPECT_EQ(decision.state, BehaviourState::kDeadlock);
  EXPECT_TRUE(decision.stop);
  EXPECT_EQ(decision.left_wheel_mps, 0.0);
  EXPECT_EQ(decision.right_wheel_mps, 0.0);
  EXPECT_EQ(decision.linear_mps, 0.0);
  EXPECT_EQ(decision.angular_radps, 0.0);
}

// Walls along both long sides and across the front of the 1.6 m x 1.98 m rectangle, offset outward or inward.
Scene walls_around_rectangle(double half_width_m, double depth_m) {
  return Scene{{},
               {{-0.1, -half_width_m, depth_m, -half_width_m},
                {-0.1, half_width_m, depth_m, half_width_m},
                {depth_m, -half_width_m, depth_m, half_width_m}}};
}

TEST(BearcatZonesTest, WallsJustOutsideTheRectangleAreNotObstacles) {
  // 0.81 m to either side and 2.0 m ahead: 1 cm and 2 cm outside.
  EXPECT_EQ(decide_on(cast(walls_around_rectangle(0.81, 2.0))).ob_factor, 0);
}

TEST(BearcatZonesTest, WallsJustInsideTheRectangleAreObstaclesInEveryZone) {
  EXPECT_EQ(decide_on(cast(walls_around_rectangle(0.79, 1.96))).ob_factor, 123);
}

TEST(BearcatZonesTest, ObstaclesInZones1And2RecordObRightObLeftAndObNearAsInFigure4_7) {
  const SyntheticScan scan = cast(Scene{{kRightPost}, {kBoxAheadRightOfCentre}});
  const BearcatDecision decision = decide_on(scan);
  ASSERT_EQ(decision.ob_factor, 12);

  // Zone 1, the post: beams -38..-24 degrees hit it; the beam at -31 degrees passes 0.04 degrees from its centre.
  const ZoneObservation& right = decision.zones[0];
  ASSERT_TRUE(right.obstacle_present);
  EXPECT_NEAR(degrees(right.ob_right.bearing_rad), -38.0, kBearingTolerance_deg);
  EXPECT_EQ(right.ob_right.range_m, scan.lms200_range_at(-38));
  EXPECT_NEAR(degrees(right.ob_left.bearing_rad), -24.0, kBearingTolerance_deg);
  EXPECT_EQ(right.ob_left.range_m, scan.lms200_range_at(-24));
  EXPECT_NEAR(degrees(right.ob_near.bearing_rad), -31.0, kBearingTolerance_deg);
  EXPECT_EQ(right.ob_near.range_m, scan.lms200_range_at(-31));
  // Centre distance minus radius; 1e-5 m covers the 0.04 degree offset and the float ranges.
  EXPECT_NEAR(right.ob_near.range_m, std::hypot(1.0, 0.6) - 0.15, 1e-5);

  // Zone 2, the box face at x = 1.5 m: beams -11..+7 degrees, nearest straight ahead.
  const ZoneObservation& middle = decision.zones[1];
  ASSERT_TRUE(middle.obstacle_present);
  // Float ranges are good to about 1e-7 m at 1.5 m.
  constexpr double kFloatRangeTolerance_m = 1e-6;
  EXPECT_NEAR(degrees(middle.ob_right.bearing_rad), -11.0, kBearingTolerance_deg);
  EXPECT_NEAR(middle.ob_right.range_m, 1.5 / std::cos(radians(11.0)), kFloatRangeTolerance_m);
  EXPECT_NEAR(degrees(middle.ob_left.bearing_rad), 7.0, kBearingTolerance_deg);
  EXPECT_NEAR(middle.ob_left.range_m, 1.5 / std::cos(radians(7.0)), kFloatRangeTolerance_m);
  EXPECT_NEAR(degrees(middle.ob_near.bearing_rad), 0.0, kBearingTolerance_deg);
  EXPECT_NEAR(middle.ob_near.range_m, 1.5, kFloatRangeTolerance_m);

  EXPECT_FALSE(decision.zones[2].obstacle_present);
}

TEST(BearcatGapsTest, ObstacleDeadAheadIsCase2AndSteersToTheCentreOfTheWideOpeningOnTheLeft) {
  // A 1.7 m doorway from y = 0.35 m to the room's left corner; the barrel hides the beams up to 15 degrees.
  const BearcatDecision decision = decide_on(cast(Scene{{kBarrelAheadSlightlyLeft}, room_with_front_door(0.35, 2.05)}));
  EXPECT_EQ(decision.ob_factor, 2);
  EXPECT_EQ(decision.state, BehaviourState::kSteerGap);
  ASSERT_TRUE(decision.widest_gap.has_value());
  // Open beams 16..44 degrees; the chord between their neighbours (barrel at 15, side wall at 45) is the smaller.
  EXPECT_NEAR(degrees(decision.widest_gap->right_edge_bearing_rad), 15.0, kBearingTolerance_deg);
  EXPECT_NEAR(degrees(decision.widest_gap->left_edge_bearing_rad), 45.0, kBearingTolerance_deg);
  EXPECT_NEAR(degrees(decision.widest_gap->center_bearing_rad), 30.0, kBearingTolerance_deg);
  EXPECT_GE(decision.widest_gap->width_m, 1.6);
  EXPECT_LT(decision.widest_gap->width_m, 2.0);
  EXPECT_NEAR(decision.steer_deg, 30.0, kBearingTolerance_deg);
  EXPECT_GT(decision.right_wheel_mps, decision.left_wheel_mps);
}

TEST(BearcatGapsTest, GapReachingTheEndOfTheScanCounts) {
  // The right side and the front up to 21.8 degrees are walled in 1 m to the right and 2.5 m ahead; everything
  // left of that is open out to the last beam at +90 degrees. The original never closed this run and steered to
  // its uninitialised (0 + 0) / 2 - 90 = -90 degrees, into the wall.
  const Scene scene{{kBarrelAheadSlightlyLeft}, {{-0.1, -1.0, 2.5, -1.0}, {2.5, -1.0, 2.5, 1.0}}};
  const BearcatDecision decision = decide_on(cast(scene));
  EXPECT_EQ(decision.ob_factor, 2);
  EXPECT_EQ(decision.state, BehaviourState::kSteerGap);
  ASSERT_TRUE(decision.widest_gap.has_value());
  // Open beams 22..90 degrees, extended by the wall beam at 21 on the right only.
  EXPECT_NEAR(degrees(decision.widest_gap->right_edge_bearing_rad), 21.0, kBearingTolerance_deg);
  EXPECT_NEAR(degrees(decision.widest_gap->left_edge_bearing_rad), 90.0, kBearingTolerance_deg);
  EXPECT_NEAR(decision.steer_deg, 55.5, kBearingTolerance_deg);
}

TEST(BearcatGapsTest, OpeningNarrowerThanMinimumIsIgnoredAndTurnsAwayFromTheNearerSide) {
  // A 0.6 m doorway: too narrow. The barrel sits left of centre, so the left half's nearest return is nearer.
  const BearcatDecision decision = decide_on(cast(Scene{{kBarrelAheadSlightlyLeft}, room_with_front_door(0.35, 0.95)}));
  EXPECT_EQ(decision.ob_factor, 2);
  EXPECT_FALSE(decision.widest_gap.has_value());
  EXPECT_EQ(decision.state, BehaviourState::kNoGap);
  EXPECT_EQ(decision.steer_deg, -15.0);
}

TEST(BearcatGapsTest, WithoutAGapABarrelRightOfCentreTurnsLeft) {
  const BearcatDecision decision =
      decide_on(cast(Scene{{kBarrelAheadSlightlyRight}, room_with_front_door(0.35, 0.95)}));
  EXPECT_EQ(decision.state, BehaviourState::kNoGap);
  EXPECT_EQ(decision.steer_deg, 15.0);
}

TEST(BearcatLayoutTest, Hokuyo240ScanGivesTheSameObFactorAsTheLms200) {
  // A post behind the robot on its left (bearing 112 degrees, 0.5 m to the side) is seen only by the 240 degree
  // scanner and must not count for the left zone.
  const Circle post_behind{-0.2, 0.5, 0.1};
  const std::vector<Scene> scenes{
      Scene{},
      Scene{{kRightPost}, {}},
      Scene{{kRightPost}, {kBoxAheadRightOfCentre}},
      Scene{{kLeftPost}, {kBoxAheadLeftOfCentre}},
      Scene{{kLeftPost}, {}},
      Scene{{kRightPost, kLeftPost}, {}},
      Scene{{}, {{1.0, -3.0, 1.0, 3.0}}},
      walls_around_rectangle(0.81, 2.0),
      walls_around_rectangle(0.79, 1.96),
      Scene{{kBarrelAheadSlightlyLeft}, room_with_front_door(0.35, 2.05)},
  };
  for (std::size_t index = 0; index < scenes.size(); ++index) {
    Scene with_post_behind = scenes[index];
    with_post_behind.circles.push_back(post_behind);
    EXPECT_EQ(decide_on(cast(with_post_behind, kHokuyo240)).ob_factor, decide_on(cast(scenes[index])).ob_factor)
        << "scene " << index;
  }
}

using occgeo::testing::invalid_argument_message;

TEST(BearcatParamsTest, DefaultsAreValid) { EXPECT_NO_THROW(BearcatParams{}.validate()); }

TEST(BearcatParamsTest, ValidationMessageNamesTheField) {
  BearcatParams negative_width;
  negative_width.zone_width_m = -1.0;
  EXPECT_NE(invalid_argument_message([&] { negative_width.validate(); }).find("zone_width_m"), std::string::npos);

  BearcatParams nan_gap;
  nan_gap.gap_min_width_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(invalid_argument_message([&] { nan_gap.validate(); }).find("gap_min_width_m"), std::string::npos);

  BearcatParams too_fast;
  too_fast.base_speed_mps = 2.0;
  EXPECT_NE(invalid_argument_message([&] { too_fast.validate(); }).find("base_speed_mps"), std::string::npos);

  BearcatParams no_turn;
  no_turn.turn_large_deg = 0.0;
  EXPECT_NE(invalid_argument_message([&] { static_cast<void>(BearcatBehaviour{no_turn}); }).find("turn_large_deg"),
            std::string::npos);
}

TEST(BearcatScanTest, MalformedScanMessageNamesTheField) {
  SyntheticScan scan = cast(Scene{});
  ScanView zero_increment = scan.view();
  zero_increment.angle_increment_rad = 0.0;
  EXPECT_NE(invalid_argument_message([&] { decide(zero_increment, BearcatParams{}); }).find("angle_increment_rad"),
            std::string::npos);

  scan.ranges_m[90] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_NE(invalid_argument_message([&] { decide(scan.view(), BearcatParams{}); }).find("ScanView.ranges_m"),
            std::string::npos);

  const std::vector<float> ranges_behind(10, 5.0F);
  const ScanView only_behind{radians(100.0), radians(1.0), ranges_behind, 8.0};
  EXPECT_NE(invalid_argument_message([&] { decide(only_behind, BearcatParams{}); }).find("ScanView.ranges_m"),
            std::string::npos);
}

TEST(BearcatSteerCarTest, WheelSpeedsFollowSteerCarIncludingDeadbandAndClamp) {
  struct Row {
    double steer_deg;
    double left_counts;   // the original's spdx
    double right_counts;  // the original's spdy
  };
  // base_speed 15000 counts, 134.5 counts per degree outside the 5 degree deadband, clamped to +-36000 counts.
  const Row table[] = {
      {0.0, 15000.0, 15000.0},     // straight
      {4.9, 15000.0, 15000.0},     // inside the deadband
      {5.0, 14327.5, 15672.5},     // at the deadband (the original truncated to whole counts)
      {10.0, 13655.0, 16345.0},    // case 1
      {15.0, 12982.5, 17017.5},    // case 12
      {90.0, 2895.0, 27105.0},     // the largest steer decide() commands: inside the clamp
      {-90.0, 27105.0, 2895.0},    // mirrored
      {180.0, -9210.0, 36000.0},   // 39210 counts clamped
      {-180.0, 36000.0, -9210.0},  // mirrored
  };
  const BearcatParams params;
  for (const Row& row : table) {
    const WheelCommand command = wheel_command_for_steer(row.steer_deg, params);
    EXPECT_NEAR(command.left_wheel_mps, row.left_counts * kMpsPerCount, kSpeedTolerance_mps) << row.steer_deg;
    EXPECT_NEAR(command.right_wheel_mps, row.right_counts * kMpsPerCount, kSpeedTolerance_mps) << row.steer_deg;
    EXPECT_NEAR(command.linear_mps, (row.left_counts + row.right_counts) / 2.0 * kMpsPerCount, kSpeedTolerance_mps)
        << row.steer_deg;
    EXPECT_NEAR(command.angular_radps, (row.right_counts - row.left_counts) * kMpsPerCount / 0.7, kSpeedTolerance_mps)
        << row.steer_deg;
  }
}

TEST(BearcatBehaviourTest, HoldsItsParamsAndDecidesLikeTheFreeFunction) {
  BearcatParams params;
  params.turn_small_deg = 20.0;
  const BearcatBehaviour behaviour(params);
  EXPECT_EQ(behaviour.params().turn_small_deg, 20.0);
  const SyntheticScan scan = cast(Scene{{kRightPost}, {}});
  EXPECT_EQ(behaviour.decide(scan.view()).steer_deg, 20.0);
  EXPECT_EQ(behaviour.decide(scan.view()).left_wheel_mps, decide(scan.view(), params).left_wheel_mps);
}

}  // namespace
}  // namespace occgeo::service::control
