#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "occgeo/geometry/cell.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/mapfile/map_file.h"
#include "occgeo/mapping/beam_limits.h"
#include "occgeo/mapping/grid_snapshot.h"
#include "occgeo/mapping/himm_params.h"
#include "occgeo/mapping/tiles.h"

namespace occgeo::mapping {

// A HIMM histogram grid (Borenstein & Koren 1991): a certainty in [0, max_certainty] per cell, lowered along each
// beam and raised, then smoothed by the growth-rate operator, where a beam hits. Cells live in tiles allocated on first
// write, so the grid grows in any direction and its memory follows the area seen. Not thread-safe: one thread inserts
// and takes snapshots, which any thread may then read. Copies are cheap: they share tiles until one of them writes.
class HimmGrid {
 public:
  // An empty grid; throws std::invalid_argument naming the bad field of params.
  explicit HimmGrid(const HimmParams& params);

  // Applies one range reading from sensor_origin_W to hit_point_W (world frame, metres): every cell on the beam before
  // the end cell loses params.decrement; the end cell gains params.increment and goes through the growth-rate operator
  // when is_hit, else it loses params.decrement like the rest. Throws std::invalid_argument, changing nothing, for
  // non-finite points or points more than 2^30 cells from the origin.
  void insert_ray(const Eigen::Vector2d& sensor_origin_W, const Eigen::Vector2d& hit_point_W, bool is_hit);

  // Applies a planar scan taken by a sensor at pose X_WS: reading i lies at angle angle_min + i * angle_increment
  // (radians, counter-clockwise from the sensor's x axis) and starts at the sensor's position; readings >= range_max
  // (metres, +inf included) clear their beam up to range_max and mark nothing. Throws std::invalid_argument, changing
  // nothing, for a NaN or negative reading (naming its index), a non-finite pose or angle, a range_max that is not
  // finite and positive, or a pose more than 2^30 cells from the origin. limits cut what each reading changes
  // (beam_use): a return beyond limits.max_insert_range_m is not marked, no beam clears beyond max_free_range_m, a
  // no-return beam clears only up to no_return_clear_m. A beam whose flag in ended_on_moving is non-zero (empty: none)
  // returned from something moving (a person walking): it clears its beam up to one cell short of the return, as a
  // returning beam, and leaves the return's own cell as it was, so that what walks by leaves no trail and a still thing
  // taken for moving is not erased; otherwise it must have as many flags as readings.
  void insert_scan(const geometry::Pose2& X_WS, float angle_min, float angle_increment, std::span<const float> ranges,
                   float range_max, const BeamLimits& limits = {}, std::span<const std::uint8_t> ended_on_moving = {});

  // Certainty of cell c; 0 when c was never observed.
  [[nodiscard]] std::uint8_t certainty(const geometry::CellIndex& c) const;
  // Sets cell c's certainty outright (in [0, max_certainty]), for grids that mirror another model rather than
  // integrate readings (the octree's height-band projection). Logs an occupancy change like insert_ray does and
  // counts as one insert for version(). Throws std::invalid_argument for a certainty above max_certainty.
  void set_certainty(const geometry::CellIndex& c, std::uint8_t certainty);
  // True when a reading has updated cell c.
  [[nodiscard]] bool observed(const geometry::CellIndex& c) const;
  // True when the certainty of cell c is at least params().occupied_threshold.
  [[nodiscard]] bool occupied(const geometry::CellIndex& c) const;

  // Number of insert_ray and insert_scan calls applied so far.
  [[nodiscard]] std::uint64_t version() const { return version_; }
  // Number of allocated tiles.
  [[nodiscard]] std::size_t tile_count() const { return tiles_.size(); }
  // Number of occupied cells.
  [[nodiscard]] std::size_t occupied_cell_count() const { return occupied_cells_; }
  // The box covered by the allocated tiles; nullopt when nothing was observed.
  [[nodiscard]] std::optional<CellBox> tile_bounds() const { return tile_bounds_; }
  // Number of tiles copied so far because a snapshot still shared them when they were written (copy-on-write cost).
  [[nodiscard]] std::uint64_t copied_tile_count() const { return copied_tiles_; }
  // The parameters the grid was made with.
  [[nodiscard]] const HimmParams& params() const { return params_; }
  // Cell <-> metric conversion of this grid.
  [[nodiscard]] const geometry::GridGeometry& grid_geometry() const { return geometry_; }

  // The cells whose occupied() changed since the previous call (or since the grid was made), each listed at least once
  // (one that flipped back is listed too), and the log emptied: what a distance field kept in step with the grid must
  // look at, in proportion to what changed rather than to the area a scan covers. nullopt when more than
  // kMaxOccupancyChanges changes were logged since (e.g. after from_image): then compare everything.
  [[nodiscard]] std::optional<std::vector<geometry::CellIndex>> take_occupancy_changes();
  static constexpr std::size_t kMaxOccupancyChanges = std::size_t{1} << 20;

  // An immutable view of the grid as it is now, safe to read from any thread; costs one shared pointer copy per tile.
  [[nodiscard]] std::shared_ptr<const GridSnapshot> snapshot() const;

  // The grid an image holds: pixels that match the grey level to_image gives a certainty (for params) take that
  // certainty, other pixels go by the image's trinary reading (occupied -> max_certainty, free -> 0, unknown ->
  // unobserved). Pixels land on the nearest cell boundaries (a shift of at most half a cell). Throws
  // std::invalid_argument when params are invalid, the image's resolution differs from params.cell_size_m or its
  // origin_yaw is not 0.
  [[nodiscard]] static HimmGrid from_image(const mapfile::OccupancyImage& image, const HimmParams& params);
  // The allocated tiles as a map_server image, origin at their south-west corner, one pixel per cell: certainties as
  // grey levels from 254 (0) down to 0 (max_certainty), unobserved cells 205, thresholds chosen so that map_server's
  // trinary reading says occupied exactly where occupied() does and unknown exactly where observed() does not.
  [[nodiscard]] mapfile::OccupancyImage to_image() const;

 private:
  class TileWriter;
  using Tiles = std::unordered_map<TileIndex, std::shared_ptr<Tile>, TileIndexHash>;

  // Tile t, or nullptr when it is not allocated.
  [[nodiscard]] const Tile* find_tile(const TileIndex& t) const;
  // Cell value of c: a certainty or kUnobserved.
  [[nodiscard]] std::uint8_t cell_value(const geometry::CellIndex& c) const;
  // Tile t, allocated if missing and copied first if a snapshot shares it, ready to be written.
  [[nodiscard]] Tile& writable_tile(TileIndex t);
  // Logs that cell c's occupied() changed (see take_occupancy_changes).
  void note_occupancy_change(const geometry::CellIndex& c) {
    if (occupancy_changes_overflowed_) return;
    if (occupancy_changes_.size() < kMaxOccupancyChanges) {
      occupancy_changes_.push_back(c);
      return;
    }
    occupancy_changes_overflowed_ = true;
    occupancy_changes_ = {};
  }

  HimmParams params_;
  geometry::GridGeometry geometry_;
  TileLayout layout_;
  Tiles tiles_;
  std::optional<CellBox> tile_bounds_;
  std::size_t occupied_cells_ = 0;
  std::uint64_t copied_tiles_ = 0;
  // The tiles as of the last snapshot, shared with it chunk by chunk, and the tiles allocated or copied since (each
  // once): snapshot() applies those to these, so that it costs what changed, not a pointer per tile. Mutable:
  // snapshot() is const, and like every member it runs on the grid's writer's thread only.
  mutable GridSnapshot::SharedTiles published_tiles_;
  mutable std::vector<TileIndex> unpublished_tiles_;
  std::uint64_t version_ = 0;
  std::vector<geometry::CellIndex> occupancy_changes_;
  // insert_scan's see-through scratch, reused so that a scan allocates nothing once the buffers have grown.
  std::vector<geometry::CellIndex> see_through_lowered_;
  std::unordered_set<geometry::CellIndex, geometry::CellIndexHash> see_through_hits_;
  bool occupancy_changes_overflowed_ = false;
};

}  // namespace occgeo::mapping
