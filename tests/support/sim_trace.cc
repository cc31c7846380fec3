#include "sim_trace.h"

#include <algorithm>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <stdexcept>

namespace occgeo::testing {

std::vector<Eigen::Vector4d> read_sim_trace(const std::filesystem::path& file) {
  std::vector<Eigen::Vector4d> rows;
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream fields(line);
    Eigen::Vector4d row;
    if (fields >> row(0) >> row(1) >> row(2) >> row(3)) rows.push_back(row);
  }
  return rows;
}

double longest_standstill_s(const std::vector<Eigen::Vector4d>& trace) {
  double longest = 0.0;
  double since = trace.empty() ? 0.0 : trace.front()(0);
  for (std::size_t i = 1; i < trace.size(); ++i) {
    const Eigen::Vector4d& a = trace[i - 1];
    const Eigen::Vector4d& b = trace[i];
    if ((b.tail<3>() - a.tail<3>()).cwiseAbs().maxCoeff() > 1e-6) {
      since = b(0);
    } else {
      longest = std::max(longest, b(0) - since);
    }
  }
  return longest;
}

std::vector<std::string> seeded_start_poses(const WorldTruth& truth, std::uint32_t seed, int count, double length_m,
                                            double width_m, double margin_m) {
  const std::vector<std::pair<int, int>> free(truth.free_cells().begin(), truth.free_cells().end());
  if (free.empty()) throw std::invalid_argument("seeded_start_poses: the world has no free cell");
  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::size_t> cell(0, free.size() - 1);
  std::uniform_real_distribution<double> heading(-std::numbers::pi, std::numbers::pi);
  std::vector<std::string> poses;
  // Bounded: a world with hardly any room for the footprint ends the search rather than looping.
  for (int attempt = 0; attempt < 100000 && static_cast<int>(poses.size()) < count; ++attempt) {
    const auto [ix, iy] = free[cell(rng)];
    const double x = (ix + 0.5) * truth.cell_size();
    const double y = (iy + 0.5) * truth.cell_size();
    const double theta = heading(rng);
    if (truth.box_distance(x, y, theta, length_m, width_m, 0.0) < margin_m) continue;
    std::ostringstream pose;
    pose.precision(3);
    pose << std::fixed << x << ',' << y << ',' << theta;
    poses.push_back(pose.str());
  }
  if (static_cast<int>(poses.size()) < count) throw std::runtime_error("seeded_start_poses: too few free poses");
  return poses;
}

}  // namespace occgeo::testing
