#pragma once

#include <cstdint>
#include <vector>

#include "occgeo/geometry/pose.h"
#include "occgeo/sim/laser.h"
#include "occgeo/sim/noise.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/sim_world.h"

namespace occgeo::sim {

// Simulates a ring or array of sonars (RangeArrayPreset) as SPECULAR reflectors, as real sonar behaves on smooth
// surfaces (Kuc & Siegel 1987; Leonard & Durrant-Whyte, "Directed Sonar Sensing"): a flat surface echoes only from the
// point whose normal points back at the transducer, if that point is inside the beam; met obliquely, the pulse bounces
// away and no echo returns. Each element casts rays_per_beam rays evenly across its cone; a ray's hit echoes only when
// its incidence angle (between the reversed ray and RayHit::normal_W) is at most specular_tolerance_rad. The element
// reports the nearest accepted echo (the first echo to arrive), with seeded Gaussian noise whose σ is proportional to
// the range, or exactly range_max_m when no ray's echo is accepted.
//
// Known simplifications:
//   - Concave corners (two walls meeting at 90° or so) are retroreflectors in reality: the pulse bounces off both
//     walls and returns from any incidence inside the beam, giving the corner's distance. This model ignores that and
//     treats each wall alone, so a corner met obliquely returns nothing. Nor are multiple reflections (a pulse bounced
//     off one wall echoing from another, reading too long) or diffuse echoes from rough surfaces and edges simulated.
//   - In pixel worlds a hit's normal is that of the surface the pixels draw (PixelWorld::cast: the directions to the
//     free pixels within two pixels, summed), so a pillar drawn in pixels echoes towards whichever sonar faces it, as a
//     round one does, and an axis-aligned wall as a flat one; a wall one pixel thin keeps its face's normal (±x or
//     ±y). A disc only a few pixels across has a coarse normal; a shape world circle's is exact.
//   - The cone is sampled by its rays. A flat surface whose normal lies inside the cone is heard through the ray
//     nearest the normal, at that ray's slightly longer distance (the scout's rays are 4.2° apart, so within 0.07% of
//     the perpendicular distance). A curved surface is harsher: a ray passing a circle of radius r at b from its centre
//     meets it at incidence asin(b / r), so it echoes only when a ray passes within r·sin(tolerance) of the centre
//     line -- a 0.3 m pillar 2 m away is heard by a ray within 1.2° of its bearing, which the 4.2° ray spacing often
//     misses, where a real sonar hears a pillar anywhere in its beam. Small objects between rays are missed too.
class RangeArraySimulator {
 public:
  // Throws std::invalid_argument naming the sensor and the field unless rays_per_beam is odd (so one ray is the
  // acoustic axis), the array has elements, the ranges are ordered and specular_tolerance_rad is in (0, π/2].
  RangeArraySimulator(const RangeArrayPreset& array, std::uint64_t seed);

  // Fires every element once from base_link pose X_WB at sim time time_s. ranges_m has one reading per element.
  // hit_pixels holds the obstacle pixels entered by the noise-free acoustic AXIS rays whose own echo is the reading
  // (the specular rule accepts it and no off-axis ray's echo is nearer): what an axis-only sensor model such as HIMM
  // can map from a reading. An axis ray meeting a wall at 40° incidence returns nothing, and one behind a nearer
  // off-axis echo is masked by it (the element reports the nearer range), so the cell it entered is not recorded;
  // off-axis rays never record pixels.
  SimulatedScan fire(const SimWorld& world, const geometry::Pose2& X_WB, double time_s);

  [[nodiscard]] const RangeArrayPreset& preset() const { return array_; }

 private:
  RangeArrayPreset array_;
  GaussianNoise noise_;  // unit σ, scaled by the range
};

// One reading of a servo-swept rangefinder.
struct ServoReading {
  double servo_angle_rad = 0.0;   // servo angle the reading was taken at
  float range_m = 0.0F;           // noisy, clamped range, or exactly range_max for no return
  std::vector<Pixel> hit_pixels;  // obstacle pixels the noise-free beam entered
};

// Simulates a single-beam rangefinder on a servo (ServoRangePreset): reading n is taken at servo angle
// servo_angle_of(n), ping-pong between the limits, with seeded Gaussian noise whose σ depends on the range.
class ServoRangeSimulator {
 public:
  // Throws std::invalid_argument naming the sensor unless the sweep is a positive whole number of steps.
  ServoRangeSimulator(const ServoRangePreset& servo, std::uint64_t seed);

  // Takes the next reading from base_link pose X_WB at sim time time_s and moves the servo on one step.
  ServoReading measure(const SimWorld& world, const geometry::Pose2& X_WB, double time_s);

  // The servo angle of reading n (counting from 0): min, min + step, ..., max, max - step, ..., min, min + step, ...
  [[nodiscard]] double servo_angle_of(std::uint64_t reading) const;
  // Steps from one end of the sweep to the other.
  [[nodiscard]] std::uint64_t steps_per_sweep() const { return steps_per_sweep_; }
  [[nodiscard]] const ServoRangePreset& preset() const { return servo_; }

 private:
  ServoRangePreset servo_;
  std::uint64_t steps_per_sweep_;
  std::uint64_t next_reading_ = 0;
  GaussianNoise noise_;  // unit σ, scaled by the range's σ
};

}  // namespace occgeo::sim
