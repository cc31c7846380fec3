#include "occgeo/mapping/terrain.h"
#include "occgeo/geometry/checks.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

namespace occgeo::mapping {

namespace {

// The slope is fitted over this many cells on each side.
constexpr int kFitReach = 2;
// A fit needs this many surface heights, and a cell this many seen neighbours within two cells (a depth camera
// samples far ground about every other cell).
constexpr int kMinFitCells = 4;
constexpr int kMinNeighbours = 2;
// How near a drivable or plausible surface an unresolved cell may be hoped to continue it, metres (planning only).
constexpr double kHopeReach_m = 1.5;
// Cells per side the estimate may cover.
constexpr std::int64_t kMaxCells = 4096;
// The octree is read over this z range, metres: every run of a column counts towards its surface.
constexpr double kColumnDepth_m = 1000.0;

// One occupied voxel's z extent in one cell's column.
struct ColumnPiece {
  std::int32_t cell = 0;  // index into the region
  float bottom_m = 0.0F;
  float top_m = 0.0F;
};

}  // namespace

void TerrainParams::validate() const {
  geometry::require(std::isfinite(ground_band_m) && ground_band_m >= 0.0 && ground_band_m <= 0.5, "ground_band_m",
                    "must be in [0, 0.5] metres", ground_band_m);
  geometry::require(std::isfinite(max_slope_rad) && max_slope_rad >= 0.0 && max_slope_rad <= 1.0, "max_slope_rad",
                    "must be in [0, 1] radians", max_slope_rad);
  geometry::require(std::isfinite(max_step_m) && max_step_m >= 0.0 && max_step_m <= 1.0, "max_step_m",
                    "must be in [0, 1] metres", max_step_m);
}

TerrainMap::TerrainMap(const OctoMapSnapshot& octomap, double cell_size_m, geometry::CellIndex min,
                       geometry::CellIndex max, double robot_height_m, const TerrainParams& params,
                       const std::optional<Eigen::Vector2d>& robot_W)
    : params_(params), cell_size_m_(cell_size_m) {
  params.validate();
  geometry::require(std::isfinite(cell_size_m) && cell_size_m >= 0.001 && cell_size_m <= 10.0, "cell_size_m",
                    "must be in [0.001, 10] metres", cell_size_m);
  geometry::require(std::isfinite(robot_height_m) && robot_height_m > 0.0 && robot_height_m <= 100.0, "robot_height_m",
                    "must be in (0, 100] metres", robot_height_m);
  geometry::require(min.ix <= max.ix && min.iy <= max.iy, "min must not exceed max");
  geometry::require(
      static_cast<std::int64_t>(max.ix) - min.ix < kMaxCells && static_cast<std::int64_t>(max.iy) - min.iy < kMaxCells,
      "max must lie within 4096 cells of min");
  if (!params.enabled) return;
  origin_ = {min.ix - kFitReach, min.iy - kFitReach};
  width_ = max.ix - min.ix + 1 + 2 * kFitReach;
  height_ = max.iy - min.iy + 1 + 2 * kFitReach;
  cells_.assign(static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_), TerrainCell{});

  // Every occupied voxel's z extent, per cell whose square its column overlaps.
  const double c = cell_size_m;
  const double r = octomap.resolution();
  voxel_m_ = r;
  std::vector<ColumnPiece> pieces;
  const Eigen::Vector3d box_min(origin_.ix * c, origin_.iy * c, -kColumnDepth_m);
  const Eigen::Vector3d box_max((origin_.ix + width_) * c, (origin_.iy + height_) * c, kColumnDepth_m);
  octomap.for_each_occupied(box_min, box_max, [&](const OctoVoxel& voxel) {
    const double half = voxel.size_m / 2.0;
    // A hair inside the voxel's faces, so a face on a cell boundary does not spill into the next cell.
    const double inset = r * 1e-3;
    const auto first = [&](double centre, std::int32_t origin) {
      return std::max(static_cast<int>(std::floor((centre - half + inset) / c)) - origin, 0);
    };
    const auto last = [&](double centre, std::int32_t origin, int extent) {
      return std::min(static_cast<int>(std::floor((centre + half - inset) / c)) - origin, extent - 1);
    };
    const auto bottom = static_cast<float>(voxel.center_W.z() - half);
    const auto top = static_cast<float>(voxel.center_W.z() + half);
    for (int row = first(voxel.center_W.y(), origin_.iy); row <= last(voxel.center_W.y(), origin_.iy, height_); ++row) {
      for (int col = first(voxel.center_W.x(), origin_.ix); col <= last(voxel.center_W.x(), origin_.ix, width_);
           ++col) {
        pieces.push_back({row * width_ + col, bottom, top});
      }
    }
    return true;
  });
  std::sort(pieces.begin(), pieces.end(), [](const ColumnPiece& a, const ColumnPiece& b) {
    return a.cell != b.cell ? a.cell < b.cell : a.bottom_m < b.bottom_m;
  });

  // Surfaces: runs bottom-up, a gap of one voxel or less joins them.
  const double join_gap_m = r * 1.01;
  for (std::size_t begin = 0; begin < pieces.size();) {
    std::size_t end = begin;
    while (end < pieces.size() && pieces[end].cell == pieces[begin].cell) ++end;
    double run_top = static_cast<double>(pieces[begin].top_m);
    std::optional<double> surface;
    for (std::size_t k = begin + 1; k < end && !surface; ++k) {
      const double gap = static_cast<double>(pieces[k].bottom_m) - run_top;
      if (gap <= join_gap_m) {
        run_top = std::max(run_top, static_cast<double>(pieces[k].top_m));
      } else if (gap >= robot_height_m) {
        surface = run_top;  // room for the robot above this run
      } else {
        run_top = static_cast<double>(pieces[k].top_m);  // too low to stand under: the column reads as the higher run
      }
    }
    TerrainCell& cell = cells_[static_cast<std::size_t>(pieces[begin].cell)];
    cell.known = true;
    cell.surface_m = surface.value_or(run_top);
    begin = end;
  }

  // Slope and step of every cell that has neighbours on all sides within the region.
  const double tan_max_slope = std::tan(params.max_slope_rad);
  bool any_drivable = false;
  for (int row = kFitReach; row + kFitReach < height_; ++row) {
    for (int col = kFitReach; col + kFitReach < width_; ++col) {
      TerrainCell& centre = cells_[static_cast<std::size_t>(row * width_ + col)];
      if (!centre.known) continue;
      int neighbours = 0;
      double step = 0.0;
      for (int dy = -kFitReach; dy <= kFitReach; ++dy) {
        for (int dx = -kFitReach; dx <= kFitReach; ++dx) {
          if ((dx == 0 && dy == 0) || row + dy < 0 || row + dy >= height_ || col + dx < 0 || col + dx >= width_) {
            continue;
          }
          const TerrainCell& other = cells_[static_cast<std::size_t>((row + dy) * width_ + col + dx)];
          if (!other.known) continue;
          ++neighbours;
          const double distance = c * std::hypot(dx, dy);
          step = std::max(step, std::abs(other.surface_m - centre.surface_m) - distance * tan_max_slope);
        }
      }
      centre.step_m = std::max(step, 0.0);
      // Least-squares plane z = a + b x + c y through the heights a drivable surface could reach from here.
      double sxx = 0.0, sxy = 0.0, syy = 0.0, sx = 0.0, sy = 0.0, sz = 0.0, sxz = 0.0, syz = 0.0;
      int n = 0;
      for (int dy = -kFitReach; dy <= kFitReach; ++dy) {
        for (int dx = -kFitReach; dx <= kFitReach; ++dx) {
          const int r_row = row + dy;
          const int r_col = col + dx;
          if (r_row < 0 || r_row >= height_ || r_col < 0 || r_col >= width_) continue;
          const TerrainCell& other = cells_[static_cast<std::size_t>(r_row * width_ + r_col)];
          if (!other.known) continue;
          const double x = dx * c;
          const double y = dy * c;
          const double z = other.surface_m - centre.surface_m;
          if (std::abs(z) > params.max_step_m + std::hypot(x, y) * tan_max_slope) continue;
          sxx += x * x;
          sxy += x * y;
          syy += y * y;
          sx += x;
          sy += y;
          sz += z;
          sxz += x * z;
          syz += y * z;
          ++n;
        }
      }
      if (n < kMinFitCells || neighbours < kMinNeighbours) continue;
      // Normal equations of the centred fit.
      const double mean_x = sx / n, mean_y = sy / n, mean_z = sz / n;
      const double cxx = sxx - n * mean_x * mean_x;
      const double cxy = sxy - n * mean_x * mean_y;
      const double cyy = syy - n * mean_y * mean_y;
      const double cxz = sxz - n * mean_x * mean_z;
      const double cyz = syz - n * mean_y * mean_z;
      const double det = cxx * cyy - cxy * cxy;
      if (!(det > 1e-12 * c * c * c * c)) continue;  // the heights lie on a line: no plane
      const double gradient_x = (cxz * cyy - cyz * cxy) / det;
      const double gradient_y = (cyz * cxx - cxz * cxy) / det;
      centre.slope_rad = std::atan(std::hypot(gradient_x, gradient_y));
      centre.drivable = centre.slope_rad <= params.max_slope_rad && centre.step_m <= params.max_step_m;
    }
  }

  // Only a surface the robot can get onto counts: the drivable cells connected (within two cells; each one's step check
  // covered the other) to a floor-level drivable cell or to the cell the robot stands on. A wall seen only at a
  // laser's height, or a box's flat top, reads as a level surface but cannot be reached.
  locally_drivable_.assign(cells_.size(), 0);
  for (std::size_t index = 0; index < cells_.size(); ++index) locally_drivable_[index] = cells_[index].drivable ? 1 : 0;
  std::vector<std::uint8_t> reached(cells_.size(), 0);
  std::vector<int> frontier;
  const auto seed = [&](int index) {
    if (cells_[static_cast<std::size_t>(index)].drivable && reached[static_cast<std::size_t>(index)] == 0) {
      reached[static_cast<std::size_t>(index)] = 1;
      frontier.push_back(index);
    }
  };
  for (int index = 0; index < width_ * height_; ++index) {
    if (cells_[static_cast<std::size_t>(index)].surface_m <= params.ground_band_m + r * 1.01) seed(index);
  }
  if (robot_W) {
    const geometry::CellIndex standing = cell_index(*robot_W);
    const std::int64_t col = static_cast<std::int64_t>(standing.ix) - origin_.ix;
    const std::int64_t row = static_cast<std::int64_t>(standing.iy) - origin_.iy;
    if (col >= 0 && row >= 0 && col < width_ && row < height_) seed(static_cast<int>(row * width_ + col));
  }
  while (!frontier.empty()) {
    const int index = frontier.back();
    frontier.pop_back();
    const int row = index / width_;
    const int col = index % width_;
    for (int dy = -kFitReach; dy <= kFitReach; ++dy) {
      for (int dx = -kFitReach; dx <= kFitReach; ++dx) {
        if (row + dy < 0 || row + dy >= height_ || col + dx < 0 || col + dx >= width_) continue;
        seed((row + dy) * width_ + col + dx);
      }
    }
  }
  for (std::size_t index = 0; index < cells_.size(); ++index) {
    TerrainCell& cell = cells_[index];
    cell.drivable = reached[index] != 0;
    if (!cell.drivable) continue;
    lowest_surface_m_ = any_drivable ? std::min(lowest_surface_m_, cell.surface_m) : cell.surface_m;
    highest_surface_m_ = any_drivable ? std::max(highest_surface_m_, cell.surface_m) : cell.surface_m;
    any_drivable = true;
  }
  any_drivable_ = any_drivable;
}

const TerrainCell* TerrainMap::find(geometry::CellIndex index) const {
  const std::int64_t col = static_cast<std::int64_t>(index.ix) - origin_.ix;
  const std::int64_t row = static_cast<std::int64_t>(index.iy) - origin_.iy;
  if (col < 0 || row < 0 || col >= width_ || row >= height_) return nullptr;
  return &cells_[static_cast<std::size_t>(row * width_ + col)];
}

TerrainCell TerrainMap::cell(geometry::CellIndex index) const {
  const TerrainCell* found = find(index);
  return found != nullptr ? *found : TerrainCell{};
}

geometry::CellIndex TerrainMap::cell_index(const Eigen::Vector2d& p_W) const {
  return {static_cast<std::int32_t>(std::floor(p_W.x() / cell_size_m_)),
          static_cast<std::int32_t>(std::floor(p_W.y() / cell_size_m_))};
}

bool TerrainMap::explains_returns(geometry::CellIndex index) const {
  const TerrainCell* found = find(index);
  // The surface's top voxel lies wholly above the ground band (its top is a voxel higher than the band): a return
  // from it was above the band, where the floor's own returns never are.
  return found != nullptr && found->drivable && found->surface_m > params_.ground_band_m + voxel_m_ * 0.99;
}

bool TerrainMap::may_be_surface(geometry::CellIndex index) const {
  const TerrainCell* found = find(index);
  if (found == nullptr) return false;
  if (found->drivable || found->plausible) return true;
  if (found->known && found->step_m > params_.max_step_m) return false;  // a step is a step
  // Unseen, or seen too thinly for a slope: hope when a drivable or plausible surface above the floor is near it.
  const int reach = static_cast<int>(std::ceil(kHopeReach_m / cell_size_m_));
  for (int dy = -reach; dy <= reach; ++dy) {
    for (int dx = -reach; dx <= reach; ++dx) {
      const TerrainCell* other = find({index.ix + dx, index.iy + dy});
      if (other != nullptr && (other->drivable || other->plausible) &&
          other->surface_m > params_.ground_band_m + voxel_m_ * 0.99) {
        return true;
      }
    }
  }
  return false;
}

bool TerrainMap::may_explain_returns(geometry::CellIndex index) const {
  const TerrainCell* found = find(index);
  if (found == nullptr || !may_be_surface(index)) return false;
  return !found->known || found->surface_m > params_.ground_band_m + voxel_m_ * 0.99;
}

void TerrainMap::bridge_unseen_gaps(double max_gap_m) {
  geometry::require(std::isfinite(max_gap_m) && max_gap_m >= 0.0 && max_gap_m <= 10.0, "max_gap_m",
                    "must be in [0, 10] metres", max_gap_m);
  if (!any_drivable_) return;
  const int reach = static_cast<int>(std::floor(max_gap_m / cell_size_m_)) + 1;
  const double tan_max_slope = std::tan(params_.max_slope_rad);
  const auto at = [&](int col, int row) -> TerrainCell& {
    return cells_[static_cast<std::size_t>(row * width_ + col)];
  };
  // Is every cell strictly between (col0, row0) and (col1, row1) unseen? Sampled every half cell along the line.
  const auto unseen_between = [&](int col0, int row0, int col1, int row1) {
    const int samples = 2 * std::max(std::abs(col1 - col0), std::abs(row1 - row0));
    for (int k = 1; k < samples; ++k) {
      const int col = static_cast<int>(std::lround(col0 + (col1 - col0) * static_cast<double>(k) / samples));
      const int row = static_cast<int>(std::lround(row0 + (row1 - row0) * static_cast<double>(k) / samples));
      if ((col == col0 && row == row0) || (col == col1 && row == row1)) continue;
      if (at(col, row).known) return false;
    }
    return true;
  };
  std::vector<int> frontier;
  // A few passes, so a gap bridged to a patch seen far off can lead on to the next patch.
  constexpr int kPasses = 4;
  for (int pass = 0; pass < kPasses; ++pass) {
    const std::size_t bridged_before = frontier.size();
    for (int row = 0; row < height_; ++row) {
      for (int col = 0; col < width_; ++col) {
        TerrainCell& cell = at(col, row);
        if (cell.drivable || cell.plausible || locally_drivable_[static_cast<std::size_t>(row * width_ + col)] == 0) {
          continue;
        }
        bool bridged = false;
        for (int dy = -reach; dy <= reach && !bridged; ++dy) {
          for (int dx = -reach; dx <= reach && !bridged; ++dx) {
            const int other_col = col + dx;
            const int other_row = row + dy;
            if (other_col < 0 || other_row < 0 || other_col >= width_ || other_row >= height_) continue;
            const TerrainCell& other = at(other_col, other_row);
            const double gap_m = cell_size_m_ * std::hypot(dx, dy);
            if (!(other.drivable || other.plausible) || gap_m > max_gap_m + cell_size_m_) continue;
            if (std::abs(other.surface_m - cell.surface_m) > params_.max_step_m + gap_m * tan_max_slope) continue;
            bridged = unseen_between(other_col, other_row, col, row);
          }
        }
        if (bridged) {
          lowest_surface_m_ = std::min(lowest_surface_m_, cell.surface_m);
          highest_surface_m_ = std::max(highest_surface_m_, cell.surface_m);
          cell.plausible = true;
          frontier.push_back(row * width_ + col);
        }
      }
    }
    if (frontier.size() == bridged_before) break;
    // And whatever drivable-as-seen surface connects to a bridged cell.
    for (std::size_t next_index = bridged_before; next_index < frontier.size(); ++next_index) {
      const int index = frontier[next_index];
      const int row = index / width_;
      const int col = index % width_;
      for (int dy = -kFitReach; dy <= kFitReach; ++dy) {
        for (int dx = -kFitReach; dx <= kFitReach; ++dx) {
          if (row + dy < 0 || row + dy >= height_ || col + dx < 0 || col + dx >= width_) continue;
          const int next = (row + dy) * width_ + col + dx;
          TerrainCell& cell = cells_[static_cast<std::size_t>(next)];
          if (cell.drivable || cell.plausible || locally_drivable_[static_cast<std::size_t>(next)] == 0) continue;
          cell.plausible = true;
          frontier.push_back(next);
          lowest_surface_m_ = std::min(lowest_surface_m_, cell.surface_m);
          highest_surface_m_ = std::max(highest_surface_m_, cell.surface_m);
        }
      }
    }
  }
}

std::pair<double, double> TerrainMap::obstacle_band(geometry::CellIndex index, double floor_band_m, double height_m,
                                                    bool plausible_too) const {
  const TerrainCell* found = find(index);
  if (found == nullptr || !found->known || !(found->drivable || (plausible_too && may_be_surface(index)))) {
    return {floor_band_m, height_m};
  }
  // Just above the surface's run: a voxel touching it would have joined the run.
  constexpr double kAboveSurface_m = 0.01;
  return {found->surface_m + kAboveSurface_m, found->surface_m + height_m};
}

}  // namespace occgeo::mapping
