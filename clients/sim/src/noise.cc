#include "occgeo/sim/noise.h"

#include <cmath>
#include <numbers>

namespace occgeo::sim {

GaussianNoise::GaussianNoise(double sigma, std::uint64_t seed) : sigma_(sigma), generator_(seed) {}

double GaussianNoise::uniform_open_closed() {
  constexpr double kTwoToMinus53 = 1.0 / 9007199254740992.0;
  return static_cast<double>((generator_() >> 11) + 1) * kTwoToMinus53;
}

double GaussianNoise::sample() {
  if (spare_) {
    const double value = *spare_;
    spare_.reset();
    return sigma_ * value;
  }
  const double radius = std::sqrt(-2.0 * std::log(uniform_open_closed()));
  const double angle = 2.0 * std::numbers::pi * uniform_open_closed();
  spare_ = radius * std::sin(angle);
  return sigma_ * radius * std::cos(angle);
}

}  // namespace occgeo::sim
