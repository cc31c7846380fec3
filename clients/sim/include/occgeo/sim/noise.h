#pragma once

#include <cstdint>
#include <optional>
#include <random>

namespace occgeo::sim {

// Zero-mean Gaussian samples with standard deviation sigma, drawn by the Box–Muller transform from a seeded 64-bit
// Mersenne Twister, so a seed gives the same sequence with every compiler and standard library.
class GaussianNoise {
 public:
  // sigma in the unit of the samples (metres for range noise); sigma = 0 gives zeros.
  GaussianNoise(double sigma, std::uint64_t seed);

  // The next sample.
  double sample();

 private:
  // A uniform sample in (0, 1], from the top 53 bits of the generator.
  double uniform_open_closed();

  double sigma_;
  std::mt19937_64 generator_;
  std::optional<double> spare_;  // the second value of the last Box–Muller pair, not yet returned
};

}  // namespace occgeo::sim
