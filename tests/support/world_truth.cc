#include "world_truth.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace occgeo::testing {

namespace {

using Vec = Eigen::Vector2d;

double point_segment_distance(const Vec& p, const Vec& a, const Vec& b) {
  const Vec ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (a + t * ab - p).norm();
}

bool point_in_convex(const Vec& p, const std::array<Vec, 4>& poly) {
  bool positive = false;
  bool negative = false;
  for (std::size_t i = 0; i < 4; ++i) {
    const Vec e = poly[(i + 1) % 4] - poly[i];
    const Vec d = p - poly[i];
    const double cross = e.x() * d.y() - e.y() * d.x();
    if (cross > 0) positive = true;
    if (cross < 0) negative = true;
  }
  return !(positive && negative);
}

bool segments_intersect(const Vec& a, const Vec& b, const Vec& c, const Vec& d) {
  const auto orient = [](const Vec& p, const Vec& q, const Vec& r) {
    return (q.x() - p.x()) * (r.y() - p.y()) - (q.y() - p.y()) * (r.x() - p.x());
  };
  const double d1 = orient(c, d, a), d2 = orient(c, d, b), d3 = orient(a, b, c), d4 = orient(a, b, d);
  return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0));
}

// Distance between two convex quadrilaterals; 0 when they overlap or touch.
double polygon_distance(const std::array<Vec, 4>& p, const std::array<Vec, 4>& q) {
  for (const Vec& v : p) {
    if (point_in_convex(v, q)) return 0.0;
  }
  for (const Vec& v : q) {
    if (point_in_convex(v, p)) return 0.0;
  }
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < 4; ++i) {
    for (std::size_t j = 0; j < 4; ++j) {
      if (segments_intersect(p[i], p[(i + 1) % 4], q[j], q[(j + 1) % 4])) return 0.0;
      best = std::min({best, point_segment_distance(p[i], q[j], q[(j + 1) % 4]),
                       point_segment_distance(q[j], p[i], p[(i + 1) % 4])});
    }
  }
  return best;
}

}  // namespace

WorldTruth::WorldTruth(const mapfile::OccupancyImage& image)
    : cell_size_(image.resolution), origin_x_(image.origin_x), origin_y_(image.origin_y), height_(image.height) {
  for (std::uint32_t row = 0; row < image.height; ++row) {
    for (std::uint32_t col = 0; col < image.width; ++col) {
      const auto state = image.state(col, row);
      if (state == mapfile::OccupancyImage::CellState::occupied) obstacles_.insert(cell_of_pixel(col, row));
      if (state == mapfile::OccupancyImage::CellState::free) free_.insert(cell_of_pixel(col, row));
    }
  }
}

std::pair<int, int> WorldTruth::cell_of_pixel(std::uint32_t col, std::uint32_t row) const {
  const double center_x = origin_x_ + (col + 0.5) * cell_size_;
  const double center_y = origin_y_ + (height_ - 1 - row + 0.5) * cell_size_;
  return {static_cast<int>(std::floor(center_x / cell_size_)), static_cast<int>(std::floor(center_y / cell_size_))};
}

double WorldTruth::box_distance(double x, double y, double theta, double length, double width, double center_x) const {
  const double c = std::cos(theta), s = std::sin(theta);
  std::array<Vec, 4> box;
  const std::array<Vec, 4> local = {Vec(center_x - length / 2, -width / 2), Vec(center_x + length / 2, -width / 2),
                                    Vec(center_x + length / 2, width / 2), Vec(center_x - length / 2, width / 2)};
  for (std::size_t i = 0; i < 4; ++i)
    box[i] = Vec(x + c * local[i].x() - s * local[i].y(), y + s * local[i].x() + c * local[i].y());
  double best = std::numeric_limits<double>::infinity();
  for (const auto& [ix, iy] : obstacles_) {
    const Vec lo(ix * cell_size_, iy * cell_size_);
    const Vec center = lo + Vec(cell_size_ / 2, cell_size_ / 2);
    // Cheap bound: skip cells that cannot beat the best distance found so far.
    if ((center - Vec(x, y)).norm() - std::hypot(length, width) - cell_size_ > best) continue;
    const std::array<Vec, 4> cell = {lo, lo + Vec(cell_size_, 0), lo + Vec(cell_size_, cell_size_),
                                     lo + Vec(0, cell_size_)};
    best = std::min(best, polygon_distance(box, cell));
    if (best == 0.0) return 0.0;
  }
  return best;
}

std::set<std::pair<int, int>> occupied_cells(const mapfile::OccupancyImage& image) {
  WorldTruth truth(image);
  return truth.obstacles();
}

std::set<std::pair<int, int>> observed_cells(const mapfile::OccupancyImage& image) {
  WorldTruth truth(image);
  std::set<std::pair<int, int>> cells = truth.obstacles();
  cells.insert(truth.free_cells().begin(), truth.free_cells().end());
  return cells;
}

}  // namespace occgeo::testing
