#include "occgeo/geometry/track_dynamics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace occgeo::geometry {
namespace {

TEST(FirstOrderLag, StepResponseReaches63PercentAtTheTimeConstant) {
  FirstOrderLag coarse(0.1);
  EXPECT_NEAR(coarse.step(2.0, 0.1), 2.0 * (1.0 - std::exp(-1.0)), 1e-12);
  FirstOrderLag fine(0.1);
  for (int i = 0; i < 100; ++i) fine.step(2.0, 0.001);
  EXPECT_NEAR(fine.value(), 2.0 * (1.0 - std::exp(-1.0)), 1e-12) << "exact for any step length";
}

TEST(FirstOrderLag, ZeroTimeConstantFollowsAtOnce) {
  FirstOrderLag lag(0.0, 1.0);
  EXPECT_EQ(lag.step(-3.0, 0.01), -3.0);
}

TEST(FirstOrderLag, RefusesABadTimeConstant) {
  EXPECT_THROW(FirstOrderLag(-0.1), std::invalid_argument);
  EXPECT_THROW(FirstOrderLag(std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
  EXPECT_THROW(FirstOrderLag(0.1, std::numeric_limits<double>::infinity()), std::invalid_argument);
}

TEST(TrackDynamics, BothTracksLagAndStopAtOnce) {
  TrackDynamics tracks(0.1);
  const WheelSpeeds speeds = tracks.step({1.0, -0.5}, 0.1);
  EXPECT_NEAR(speeds.left_mps, 1.0 - std::exp(-1.0), 1e-12);
  EXPECT_NEAR(speeds.right_mps, -0.5 * (1.0 - std::exp(-1.0)), 1e-12);
  tracks.stop();
  EXPECT_EQ(tracks.speeds().left_mps, 0.0);
  EXPECT_EQ(tracks.speeds().right_mps, 0.0);
}

}  // namespace
}  // namespace occgeo::geometry
