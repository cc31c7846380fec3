#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>

namespace occgeo::geometry {

// An integer cell of an unbounded 2D grid anchored at the world origin: cell (ix, iy) covers
// [ix*s, (ix+1)*s) x [iy*s, (iy+1)*s) for cell size s. Keys are not coordinates: convert only
// through GridGeometry.
struct CellIndex {
  std::int32_t ix = 0;
  std::int32_t iy = 0;
  friend bool operator==(const CellIndex&, const CellIndex&) = default;
};

struct CellIndexHash {
  std::size_t operator()(const CellIndex& c) const noexcept {
    return std::hash<std::uint64_t>{}((static_cast<std::uint64_t>(static_cast<std::uint32_t>(c.ix)) << 32) |
                                      static_cast<std::uint32_t>(c.iy));
  }
};

// Conversion between metric points and cells for one cell size (metres).
class GridGeometry {
 public:
  // Cells at or beyond this many from the origin on either axis are outside every map (and near where a cell's index
  // would overflow its int32).
  static constexpr double kMaxCellIndex = 1073741824.0;  // 2^30

  explicit GridGeometry(double cell_size) : cell_size_(cell_size) {}
  [[nodiscard]] double cell_size() const { return cell_size_; }
  // The cell of p, which the caller knows to be finite and within kMaxCellIndex cells of the origin (a checked
  // message's coordinates are); otherwise use checked_cell_of.
  [[nodiscard]] CellIndex cell_of(const Eigen::Vector2d& p) const {
    return {static_cast<std::int32_t>(std::floor(p.x() / cell_size_)),
            static_cast<std::int32_t>(std::floor(p.y() / cell_size_))};
  }
  // The cell of p, or nullopt when p is not finite or lies kMaxCellIndex cells or more from the origin.
  [[nodiscard]] std::optional<CellIndex> checked_cell_of(const Eigen::Vector2d& p) const {
    const double x = std::floor(p.x() / cell_size_);
    const double y = std::floor(p.y() / cell_size_);
    if (!(std::abs(x) < kMaxCellIndex && std::abs(y) < kMaxCellIndex)) return std::nullopt;  // NaN fails too
    return CellIndex{static_cast<std::int32_t>(x), static_cast<std::int32_t>(y)};
  }
  [[nodiscard]] Eigen::Vector2d center_of(const CellIndex& c) const {
    return {(c.ix + 0.5) * cell_size_, (c.iy + 0.5) * cell_size_};
  }
  [[nodiscard]] Eigen::Vector2d min_corner_of(const CellIndex& c) const {
    return {c.ix * cell_size_, c.iy * cell_size_};
  }

 private:
  double cell_size_;
};

}  // namespace occgeo::geometry
