#pragma once

#include <Eigen/Core>
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "occgeo/geometry/cell.h"
#include "occgeo/geometry/collision.h"
#include "occgeo/mapping/grid_snapshot.h"
#include "occgeo/mapping/tiles.h"

namespace occgeo::mapping {

// Parameters of a DistanceField.
struct DistanceFieldParams {
  // Distances are exact up to this and read "at least this" beyond it, metres; finite, > 0, and at most 2000 cells of
  // the grid. It bounds the work per changed cell (the wavefront stops there), so keep it near the largest clearance
  // queries ask for.
  double max_distance_m = 3.0;

  // Throws std::invalid_argument naming the first field that breaks its documented range.
  void validate() const;
};

// The distance field of one grid version: for each cell, the nearest occupied cell within max_distance() and the
// distance from the cell's centre to that cell's square. Immutable; any number of threads may read it without locks.
class DistanceFieldSnapshot {
 public:
  // The grid snapshot this field matches (same version).
  [[nodiscard]] const GridSnapshot& grid() const { return *grid_; }
  // The grid version the field matches.
  [[nodiscard]] std::uint64_t version() const { return grid_->version(); }
  // The cells near enough to the grid's tiles to have an occupied cell within max_distance() (the tiles grown by it);
  // every cell beyond is at max_distance(). nullopt while the grid is empty.
  [[nodiscard]] std::optional<CellBox> bounds() const { return bounds_; }
  // Side of a cell, metres.
  [[nodiscard]] double cell_size() const { return grid_->cell_size(); }
  // DistanceFieldParams::max_distance_m of the field.
  [[nodiscard]] double max_distance() const { return max_distance_m_; }

  // Distance from the centre of cell c to the nearest occupied cell's square, metres (0 for an occupied cell);
  // max_distance() when there is none within max_distance(). A directory look-up and an array read.
  [[nodiscard]] double distance(const geometry::CellIndex& c) const;
  // The occupied cell nearest to the centre of cell c, when one lies within max_distance().
  [[nodiscard]] std::optional<geometry::CellIndex> nearest_occupied(const geometry::CellIndex& c) const;

  // The clearance of request.footprint at request.pose, from the field: never below the exact clearance
  // (geometry::compute_clearance on grid()) and at most one cell_size() above it. The cells along the footprint's
  // edge (centres within half a cell diagonal of it and not deeper inside) give an upper bound (the exact distance to
  // the occupied cells they refer to; equal to the exact clearance in most queries) and a lower bound (their smallest
  // distance minus half a cell diagonal, the distance being 1-Lipschitz); the cells deeper inside only have to be
  // free. The field is read a line (4x4 cells, one cache line) at a time, each line's and each quarter's smallest
  // distance kept beside it: the nearest line along the edge is read first, and a line or quarter whose smallest
  // distance cannot bring the lower bound within a cell of the upper one is settled by that one number, so a lookup
  // costs the lines along the edge plus the cells of the few near an obstacle. When the bounds are still more than a
  // cell apart (up to 1.2 cells even for an exact upper bound), the occupied cells in the thin shell around the
  // footprint where a nearer one could hide are measured, the lines without one passed over. When the footprint grown
  // by request.max_distance_m reaches beyond bounds(), or request.max_distance_m > max_distance(),
  // geometry::compute_clearance answers. Throws std::invalid_argument naming the field like
  // geometry::compute_clearance.
  [[nodiscard]] geometry::ClearanceResult compute_clearance(const geometry::ClearanceRequest& request) const;

  // The direction in which moving the footprint (translation only, world frame) increases its clearance fastest: the
  // unit vector from the nearest occupied point to the footprint's nearest point; in contact, from the nearest
  // cell's centre to the footprint's centre. Zero when no occupied cell lies within request.max_distance_m or the
  // direction is undefined. Throws like compute_clearance.
  [[nodiscard]] Eigen::Vector2d clearance_gradient(const geometry::ClearanceRequest& request) const;

  // Heap bytes of the reference blocks this snapshot holds, their chunks and the directory (blocks shared with the
  // previous snapshot counted once here, as the field keeps one copy of each between updates).
  [[nodiscard]] std::size_t memory_bytes() const {
    constexpr std::size_t kControlBlockAndHeader = 32;
    return refs_.chunks.capacity() * sizeof(RefChunks::value_type) +
           refs_.written_chunks * (sizeof(RefChunk) + kControlBlockAndHeader) +
           refs_.written_blocks * (sizeof(RefBlock) + kControlBlockAndHeader);
  }

  // Number of compute_clearance and clearance_gradient calls so far that needed an exact check (the shell around the
  // footprint, or geometry::compute_clearance).
  [[nodiscard]] std::uint64_t exact_fallback_count() const { return fallbacks_.load(std::memory_order_relaxed); }

 private:
  friend class DistanceField;
  // A reference to the nearest occupied cell, as its offset from the cell; x == kNone when there is none in range.
  struct Ref {
    std::int16_t x;
    std::int16_t y;
  };
  static constexpr std::int16_t kNone = -32768;
  // The references come in square blocks shared between successive snapshots, and the blocks in square chunks of
  // blocks, also shared: a snapshot costs one pointer per chunk plus a copy of the chunks and blocks the update
  // changed, not a copy of the whole field (nor of a pointer per block: a 300 m map has thousands).
  static constexpr std::int32_t kBlockShift = 6;
  static constexpr std::int32_t kBlockCells = 1 << kBlockShift;
  static constexpr std::int32_t kChunkShift = 3;  // in blocks
  static constexpr std::int32_t kChunkBlocks = 1 << kChunkShift;
  // Cells per cache line of references: a 4x4 square (see index_in_block), and such squares per block.
  static constexpr std::int32_t kLineShift = 2;
  static constexpr auto kLinesPerBlock =
      static_cast<std::size_t>(kBlockCells >> kLineShift) * (kBlockCells >> kLineShift);
  struct alignas(64) RefBlock {
    std::array<Ref, static_cast<std::size_t>(kBlockCells) * kBlockCells> refs;
    // Per line, the smallest squared distance of its 16 cells, in half cells squared (as the brushfire keeps it),
    // saturated at 65535, a cell without a reference counting as the field's reach: a lookup skips a line whose
    // cells are all too far to matter, and the shell search a line without an occupied cell (0), after one read.
    std::array<std::uint16_t, kLinesPerBlock> line_min_squared;
    // The same per 2x2 quarter of each line (row-major: the quarter of cells (0..1, 0..1) first), for a lookup to
    // read only the quarters of a line that can matter.
    std::array<std::array<std::uint16_t, 4>, kLinesPerBlock> quarter_min_squared;
  };
  // A cell's place in its block: 4x4 cells per 64-byte cache line (the lines row-major), so that a clearance lookup,
  // which reads the cells along a footprint's edge, reads a line per four cells of edge in any direction rather than
  // one per row it crosses.
  static std::size_t index_in_block(std::int32_t x, std::int32_t y) {
    const auto lx = static_cast<std::size_t>(x & (kBlockCells - 1));
    const auto ly = static_cast<std::size_t>(y & (kBlockCells - 1));
    return (((ly >> 2U) * (kBlockCells / 4) + (lx >> 2U)) << 4U) + ((ly & 3U) << 2U) + (lx & 3U);
  }
  // Row-major; nullptr where no reference was ever written (all kNone).
  struct RefChunk {
    std::array<std::shared_ptr<const RefBlock>, static_cast<std::size_t>(kChunkBlocks) * kChunkBlocks> blocks;
  };
  using RefChunks = std::vector<std::shared_ptr<const RefChunk>>;
  // The chunks over a box of chunks (row-major from chunk (chunk_x0, chunk_y0), chunks_x wide); nullptr where no
  // block was written.
  struct RefDirectory {
    std::int32_t chunk_x0 = 0;
    std::int32_t chunk_y0 = 0;
    std::int32_t chunks_x = 0;
    RefChunks chunks;
    std::size_t written_chunks = 0;  // chunks that are not nullptr
    std::size_t written_blocks = 0;  // blocks that are not nullptr, counted as they are written
  };

  DistanceFieldSnapshot(std::shared_ptr<const GridSnapshot> grid, std::optional<CellBox> bounds, RefDirectory refs,
                        double max_distance_m);

  struct Answer;
  [[nodiscard]] Answer answer(const geometry::ClearanceRequest& request) const;
  // The reference block (bx, by) (cell index >> kBlockShift); nullptr outside the directory or where none was written.
  [[nodiscard]] const RefBlock* block_at(std::int32_t bx, std::int32_t by) const;

  std::shared_ptr<const GridSnapshot> grid_;
  std::optional<CellBox> bounds_;
  RefDirectory refs_;
  double max_distance_m_;
  mutable std::atomic<std::uint64_t> fallbacks_{0};
};

// What one DistanceField::update did.
struct DistanceFieldUpdate {
  bool rebuilt = false;             // The field was built from scratch (the first update of a non-empty grid).
  std::size_t changed_cells = 0;    // Cells whose occupancy flipped and were fed to the field (0 when rebuilt).
  std::size_t processed_cells = 0;  // Cells taken off the wavefront's queue.
  // What the new snapshot cost: reference blocks (64x64 cells) copied out of the field, and chunks of blocks (8x8)
  // copied to hold them; every other block and chunk is shared with the previous snapshot.
  std::size_t copied_blocks = 0;
  std::size_t copied_chunks = 0;
};

// A 2D Euclidean distance field over a HIMM grid's occupied cells, kept in step with it by an incremental brushfire
// (Lau, Sprunk & Burgard 2013, "Efficient grid-based spatial representations for robot navigation in dynamic
// environments", the algorithm of dynamicEDT): each cell refers to its nearest occupied cell, and only the cells
// whose occupancy flipped start a wavefront, which stops at max_distance_m. Its cells live in 64x64 blocks allocated
// where a wavefront reaches, so it has no extent of its own, is never rebuilt as the grid grows, and a snapshot shares
// the blocks that did not change. Not thread-safe: one thread updates it and publishes snapshots.
class DistanceField {
 public:
  // An empty field; throws std::invalid_argument naming the bad field of params.
  explicit DistanceField(const DistanceFieldParams& params);
  ~DistanceField();
  DistanceField(const DistanceField&) = delete;
  DistanceField& operator=(const DistanceField&) = delete;

  // Brings the field in step with grid, which must come from the same HimmGrid as the previous update's, and publishes
  // a snapshot for it. Only cells inside `touched` are compared with the previous version, so it must hold every cell
  // whose occupancy may have flipped since (for a scan: the sensor's position +- range_max, plus one cell for the
  // growth-rate operator); nullopt compares the whole grid (O(cells of its tiles)). Throws std::invalid_argument when
  // grid is null or its cell size differs from the previous one's.
  DistanceFieldUpdate update(std::shared_ptr<const GridSnapshot> grid, std::optional<CellBox> touched = std::nullopt);
  // As above, but only the cells listed in `changed` are compared with the previous version (for a HimmGrid:
  // take_occupancy_changes()), so the work follows what changed, not the area a scan covers.
  DistanceFieldUpdate update(std::shared_ptr<const GridSnapshot> grid, std::span<const geometry::CellIndex> changed);

  // The field of the last update; nullptr before the first. Costs one shared pointer copy.
  [[nodiscard]] std::shared_ptr<const DistanceFieldSnapshot> snapshot() const { return snapshot_; }
  // The parameters the field was made with.
  [[nodiscard]] const DistanceFieldParams& params() const { return params_; }

 private:
  class Brushfire;

  // Checks grid against the field's parameters and builds the field on the first non-empty grid; true when the caller
  // still has to bring the field in step (false: empty grid, or just built; the snapshot is taken).
  bool prepare(std::shared_ptr<const GridSnapshot>& grid, DistanceFieldUpdate& result);
  void take_snapshot(std::shared_ptr<const GridSnapshot> grid, DistanceFieldUpdate& result);

  DistanceFieldParams params_;
  std::unique_ptr<Brushfire> brushfire_;
  std::shared_ptr<const DistanceFieldSnapshot> snapshot_;
};

}  // namespace occgeo::mapping
