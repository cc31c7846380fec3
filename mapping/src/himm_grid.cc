#include "occgeo/mapping/himm_grid.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_set>
#include <utility>
#include <vector>

#include "himm_tile_writer.h"
#include "occgeo/geometry/checks.h"
#include "occgeo/geometry/grid_ray.h"

namespace occgeo::mapping {

namespace {

const HimmParams& validated(const HimmParams& params) {
  params.validate();
  return params;
}

bool is_finite(const geometry::Pose2& pose) {
  return std::isfinite(pose.x) && std::isfinite(pose.y) && std::isfinite(pose.theta);
}

}  // namespace

HimmGrid::HimmGrid(const HimmParams& params)
    : params_(validated(params)), geometry_(params.cell_size_m), layout_(params.tile_cells) {}

void HimmGrid::insert_ray(const Eigen::Vector2d& sensor_origin_W, const Eigen::Vector2d& hit_point_W, bool is_hit) {
  if (!geometry::is_traversable_point(geometry_, sensor_origin_W)) {
    throw std::invalid_argument("insert_ray: sensor_origin_W is not finite or too far from the origin");
  }
  if (!geometry::is_traversable_point(geometry_, hit_point_W)) {
    throw std::invalid_argument("insert_ray: hit_point_W is not finite or too far from the origin");
  }
  ++version_;
  TileWriter writer(*this);
  writer.trace_beam(sensor_origin_W, hit_point_W, is_hit);
}

void HimmGrid::insert_scan(const geometry::Pose2& X_WS, float angle_min, float angle_increment,
                           std::span<const float> ranges, float range_max, const BeamLimits& limits,
                           std::span<const std::uint8_t> ended_on_moving) {
  if (!is_finite(X_WS)) throw std::invalid_argument("insert_scan: X_WS is not finite");
  if (!std::isfinite(angle_min)) throw std::invalid_argument("insert_scan: angle_min is not finite");
  if (!std::isfinite(angle_increment)) throw std::invalid_argument("insert_scan: angle_increment is not finite");
  if (!std::isfinite(range_max) || range_max <= 0.0F) {
    throw std::invalid_argument("insert_scan: range_max must be finite and > 0, got " +
                                geometry::number_text(static_cast<double>(range_max)));
  }
  const double max_range = static_cast<double>(range_max);
  // Every beam end lies within max_range of the sensor on both axes.
  if (!geometry::is_traversable_point(geometry_, {std::abs(X_WS.x) + max_range, std::abs(X_WS.y) + max_range})) {
    throw std::invalid_argument("insert_scan: X_WS is too far from the origin");
  }
  if (!ended_on_moving.empty() && ended_on_moving.size() != ranges.size()) {
    throw std::invalid_argument("insert_scan: ended_on_moving has " + std::to_string(ended_on_moving.size()) +
                                " flags for " + std::to_string(ranges.size()) + " readings");
  }
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    if (std::isnan(ranges[i]) || ranges[i] < 0.0F) {
      throw std::invalid_argument("insert_scan: ranges[" + std::to_string(i) + "] is NaN or negative (" +
                                  geometry::number_text(static_cast<double>(ranges[i])) + ")");
    }
  }

  ++version_;
  TileWriter writer(*this);
  const Eigen::Vector2d p_WS = X_WS.position();
  const double first_angle = X_WS.theta + static_cast<double>(angle_min);
  // Beam directions by successive rotations: cheaper than a sine and cosine per beam, and after n beams only about
  // n * 1e-16 rad off.
  Eigen::Vector2d direction(std::cos(first_angle), std::sin(first_angle));
  const Eigen::Matrix2d rotation = Eigen::Rotation2Dd(static_cast<double>(angle_increment)).toRotationMatrix();
  const bool see_through = params_.seen_through_decrement > 0;
  // Scratch kept between scans: the cells the scan's returning beams lowered, and the cells its hits fell in.
  std::vector<geometry::CellIndex>& lowered_cells = see_through_lowered_;
  std::unordered_set<geometry::CellIndex, geometry::CellIndexHash>& hit_cells = see_through_hits_;
  lowered_cells.clear();
  hit_cells.clear();
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    const double range = static_cast<double>(ranges[i]);
    const BeamUse use = beam_use(range, max_range, limits);
    // Only a return beyond a cell shows the sensor saw through it (a beam with none may have passed glass or a gap).
    std::vector<geometry::CellIndex>* lowered = see_through && range < max_range ? &lowered_cells : nullptr;
    if (!ended_on_moving.empty() && ended_on_moving[i] != 0) {
      // Not the return's own cell: what a mistaken track covers (a pillar seen from a moving robot) is left as it was.
      const double free_m = std::min(range - params_.cell_size_m, use.free_m);
      if (free_m > 0.0) writer.trace_beam(p_WS, p_WS + free_m * direction, false, lowered);
    } else if (use.hit && use.free_m >= range) {
      const Eigen::Vector2d end_W = p_WS + range * direction;
      writer.trace_beam(p_WS, end_W, true, lowered);
      if (see_through) hit_cells.insert(geometry_.cell_of(end_W));
    } else {
      if (use.free_m > 0.0) writer.trace_beam(p_WS, p_WS + use.free_m * direction, false, lowered);
      if (use.hit) {
        // A beam from the end to itself marks only the end cell.
        const Eigen::Vector2d end_W = p_WS + range * direction;
        writer.trace_beam(end_W, end_W, true);
        if (see_through) hit_cells.insert(geometry_.cell_of(end_W));
      }
    }
    direction = rotation * direction;
  }
  if (!see_through) return;
  // The cells the scan saw through: a returning beam lowered them and none ended within kSeenThroughSpareCells.
  std::sort(lowered_cells.begin(), lowered_cells.end(), [](const geometry::CellIndex& a, const geometry::CellIndex& b) {
    return a.ix != b.ix ? a.ix < b.ix : a.iy < b.iy;
  });
  lowered_cells.erase(std::unique(lowered_cells.begin(), lowered_cells.end(),
                                  [](const geometry::CellIndex& a, const geometry::CellIndex& b) {
                                    return a.ix == b.ix && a.iy == b.iy;
                                  }),
                      lowered_cells.end());
  // Cells within kSeenThroughSpareCells of a hit are spared: where beams graze a wall they cross several of its
  // cells before ending on it further along, and the scan's other beams end close by.
  constexpr std::int32_t kSeenThroughSpareCells = 2;
  const auto near_a_hit = [&hit_cells](const geometry::CellIndex& c) {
    for (std::int32_t dy = -kSeenThroughSpareCells; dy <= kSeenThroughSpareCells; ++dy) {
      for (std::int32_t dx = -kSeenThroughSpareCells; dx <= kSeenThroughSpareCells; ++dx) {
        if (hit_cells.contains({c.ix + dx, c.iy + dy})) return true;
      }
    }
    return false;
  };
  const auto decrement = static_cast<std::uint8_t>(params_.seen_through_decrement);
  for (const geometry::CellIndex& c : lowered_cells) {
    if (!near_a_hit(c)) writer.lower(c, decrement);
  }
}

std::uint8_t HimmGrid::certainty(const geometry::CellIndex& c) const {
  const std::uint8_t value = cell_value(c);
  return value == kUnobserved ? 0 : value;
}

bool HimmGrid::observed(const geometry::CellIndex& c) const { return cell_value(c) != kUnobserved; }

bool HimmGrid::occupied(const geometry::CellIndex& c) const { return certainty(c) >= params_.occupied_threshold; }

std::shared_ptr<const GridSnapshot> HimmGrid::snapshot() const {
  if (!unpublished_tiles_.empty()) {
    // A tile copied twice since (a copy of the grid shared it) is listed twice: apply takes it once.
    std::vector<std::pair<TileIndex, std::shared_ptr<const Tile>>> changes;
    changes.reserve(unpublished_tiles_.size());
    for (const TileIndex& t : unpublished_tiles_) changes.emplace_back(t, tiles_.at(t));
    published_tiles_.apply(std::move(changes));
    unpublished_tiles_.clear();
  }
  return std::shared_ptr<const GridSnapshot>(new GridSnapshot(published_tiles_, layout_, params_.cell_size_m,
                                                              params_.occupied_threshold, params_.max_certainty,
                                                              tile_bounds_, version_, occupied_cells_));
}

std::optional<std::vector<geometry::CellIndex>> HimmGrid::take_occupancy_changes() {
  if (occupancy_changes_overflowed_) {
    occupancy_changes_overflowed_ = false;
    return std::nullopt;
  }
  return std::exchange(occupancy_changes_, {});
}

const Tile* HimmGrid::find_tile(const TileIndex& t) const {
  const auto it = tiles_.find(t);
  return it == tiles_.end() ? nullptr : it->second.get();
}

std::uint8_t HimmGrid::cell_value(const geometry::CellIndex& c) const {
  const Tile* tile = find_tile(layout_.tile_of(c));
  return tile == nullptr ? kUnobserved : tile->cells[static_cast<std::size_t>(layout_.offset_in_tile(c))];
}

void HimmGrid::set_certainty(const geometry::CellIndex& c, std::uint8_t certainty) {
  if (certainty > params_.max_certainty) {
    throw std::invalid_argument("set_certainty: certainty " + std::to_string(certainty) + " is above max_certainty " +
                                std::to_string(params_.max_certainty));
  }
  const std::uint8_t before = cell_value(c);
  if (before == certainty) return;
  ++version_;
  Tile& tile = writable_tile(layout_.tile_of(c));
  tile.cells[static_cast<std::size_t>(layout_.offset_in_tile(c))] = certainty;
  const bool was_occupied = before != kUnobserved && before >= params_.occupied_threshold;
  const bool now_occupied = certainty >= params_.occupied_threshold;
  if (was_occupied == now_occupied) return;
  const int delta = now_occupied ? 1 : -1;
  tile.occupied_cells += delta;
  occupied_cells_ = static_cast<std::size_t>(static_cast<std::int64_t>(occupied_cells_) + delta);
  note_occupancy_change(c);
}

Tile& HimmGrid::writable_tile(TileIndex t) {
  auto it = tiles_.find(t);
  if (it == tiles_.end()) {
    auto tile = std::make_shared<Tile>(Tile{std::vector<std::uint8_t>(layout_.cells_per_tile(), kUnobserved), 0, 0});
    it = tiles_.emplace(t, std::move(tile)).first;
    unpublished_tiles_.push_back(t);
    const geometry::CellIndex first = layout_.first_cell_of(t);
    const geometry::CellIndex last = {first.ix + layout_.tile_cells() - 1, first.iy + layout_.tile_cells() - 1};
    tile_bounds_ = tile_bounds_
                       ? CellBox{{std::min(tile_bounds_->min.ix, first.ix), std::min(tile_bounds_->min.iy, first.iy)},
                                 {std::max(tile_bounds_->max.ix, last.ix), std::max(tile_bounds_->max.iy, last.iy)}}
                       : CellBox{first, last};
  } else if (it->second.use_count() > 1) {
    // A snapshot (or a copy of this grid) shares the tile: write to a copy of it. A count of 1, on the other hand,
    // cannot go up meanwhile: no one else holds the tile to share it.
    it->second = std::make_shared<Tile>(*it->second);
    ++copied_tiles_;
    unpublished_tiles_.push_back(t);
  } else {
    // The count may have just dropped to 1 as the last snapshot holding the tile let go of it (a release operation);
    // an acquire operation on the count then orders that snapshot's reads before our writes. Copying and dropping
    // the pointer is one (acq_rel increment and decrement); a fence would do too, but thread sanitizers ignore fences.
    const std::shared_ptr<Tile> acquire_count = it->second;
  }
  // One store per tile per insert (TileWriter caches the tiles it writes): the change tracking costs ingest nothing
  // measurable.
  it->second->version = version_;
  return *it->second;
}

}  // namespace occgeo::mapping
