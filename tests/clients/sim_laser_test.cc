#include <gtest/gtest.h>

#include <cmath>

#include "occgeo/sim/laser.h"
#include "occgeo/sim/noise.h"
#include "occgeo/sim/presets.h"

namespace occgeo::sim {
namespace {

LaserPreset bearcat_laser(double noise_sigma_m) {
  LaserPreset laser = *find_robot_preset("bearcat")->laser();
  laser.range_noise_sigma_m = noise_sigma_m;
  return laser;
}

// 0.1 m pixels from (-5, -5), 10 m x 10 m; a wall at x 3.0..3.1 from y = -5 to 5.
World wall_ahead() {
  std::vector<std::string> rows(100, std::string(100, '.'));
  for (std::string& row : rows) row[80] = '#';
  return World::from_rows(std::vector<std::string_view>(rows.begin(), rows.end()), 0.1, {-5.0, -5.0});
}

TEST(GaussianNoise, IsTheSameSequenceForTheSameSeed) {
  GaussianNoise a(0.01, 7);
  GaussianNoise b(0.01, 7);
  GaussianNoise other_seed(0.01, 8);
  bool differs_from_other_seed = false;
  for (int i = 0; i < 100; ++i) {
    const double sample = a.sample();
    EXPECT_EQ(sample, b.sample());
    differs_from_other_seed |= sample != other_seed.sample();
  }
  EXPECT_TRUE(differs_from_other_seed);
}

TEST(GaussianNoise, HasZeroMeanAndTheRequestedSpread) {
  GaussianNoise noise(0.01, 1);
  constexpr int kSamples = 100000;
  double sum = 0.0;
  double sum_of_squares = 0.0;
  for (int i = 0; i < kSamples; ++i) {
    const double sample = noise.sample();
    sum += sample;
    sum_of_squares += sample * sample;
  }
  // The standard error of the mean is 0.01/sqrt(1e5) = 3.2e-5 m and of the deviation about 2.2e-5 m: 5 of each.
  EXPECT_NEAR(sum / kSamples, 0.0, 1.6e-4);
  EXPECT_NEAR(std::sqrt(sum_of_squares / kSamples), 0.01, 1.1e-4);
}

TEST(LaserSimulator, MeasuresFromTheMountedSensorWithoutNoise) {
  const World world = wall_ahead();
  LaserSimulator laser(bearcat_laser(0.0), 1);
  const SimulatedScan scan = laser.scan(world, {0.0, 0.05, 0.0});
  ASSERT_EQ(scan.ranges_m.size(), 181U);
  // Beam 90 looks straight ahead from x = 0.45 to the wall at x = 3.0.
  EXPECT_FLOAT_EQ(scan.ranges_m[90], 2.55F);
  // Beam 120 looks 30° left: 2.55 / cos(30°) to the wall.
  EXPECT_FLOAT_EQ(scan.ranges_m[120], static_cast<float>(2.55 / std::cos(M_PI / 6.0)));
  // Beams 0 and 180 look sideways, parallel to the wall, and leave the image: no return.
  EXPECT_EQ(scan.ranges_m[0], 8.0F);
  EXPECT_EQ(scan.ranges_m[180], 8.0F);
  EXPECT_FALSE(scan.hit_pixels.empty());
  for (const Pixel& pixel : scan.hit_pixels) EXPECT_EQ(pixel.col, 80);
}

TEST(LaserSimulator, TurnsWithTheRobot) {
  const World world = wall_ahead();
  LaserSimulator laser(bearcat_laser(0.0), 1);
  // Facing +y, the sensor sits at (0, 0.45) and beam 0, on the robot's right, looks along +x to the wall.
  const SimulatedScan scan = laser.scan(world, {0.0, 0.0, M_PI / 2.0});
  EXPECT_NEAR(scan.ranges_m[0], 3.0, 1e-6);
  EXPECT_EQ(scan.ranges_m[90], 8.0F);
}

TEST(LaserSimulator, NoiseIsSeededAndSparesNoReturnReadings) {
  const World world = wall_ahead();
  LaserSimulator first(bearcat_laser(0.01), 42);
  LaserSimulator second(bearcat_laser(0.01), 42);
  LaserSimulator noise_free(bearcat_laser(0.0), 42);
  const geometry::Pose2 X_WB{0.0, 0.05, 0.0};
  const SimulatedScan a = first.scan(world, X_WB);
  const SimulatedScan b = second.scan(world, X_WB);
  const SimulatedScan truth = noise_free.scan(world, X_WB);
  EXPECT_EQ(a.ranges_m, b.ranges_m);
  EXPECT_EQ(a.hit_pixels, truth.hit_pixels) << "hit pixels come from the noise-free beams";
  int noisy_beams = 0;
  for (std::size_t beam = 0; beam < truth.ranges_m.size(); ++beam) {
    if (truth.ranges_m[beam] == 8.0F) {
      EXPECT_EQ(a.ranges_m[beam], 8.0F) << "beam " << beam;
    } else {
      EXPECT_NEAR(a.ranges_m[beam], truth.ranges_m[beam], 0.06) << "beam " << beam << " beyond 6 sigma";
      noisy_beams += a.ranges_m[beam] != truth.ranges_m[beam] ? 1 : 0;
    }
  }
  EXPECT_GT(noisy_beams, 50);
  // The next sweep draws new noise.
  EXPECT_NE(first.scan(world, X_WB).ranges_m, a.ranges_m);
}

}  // namespace
}  // namespace occgeo::sim
