#include "occgeo/mapping/distance_field.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "occgeo/geometry/checks.h"
#include "occgeo/geometry/convex_polygon.h"

// Distances in the brushfire are integers: the squared distance from a cell's centre to an occupied cell's square in
// units of (cell_size / 2)^2, which for index offsets (dx, dy) is (2|dx| - 1)+^2 + (2|dy| - 1)+^2. Being exact
// integers, ties and comparisons are the same on every run, so an incremental update ends in the same state as a
// build from scratch whenever both pick the same nearest cell among equals.

namespace occgeo::mapping {
namespace {

using geometry::CellIndex;

constexpr std::int32_t kInfiniteSquared = std::numeric_limits<std::int32_t>::max();

// Largest field distance, in cells: distances need (2 * 2000)^2 < 2^31 buckets-worth of integers and the references
// (offsets) are int16.
constexpr double kMaxDistanceCells = 2000.0;

inline std::int32_t squared_half_cells(std::int32_t dx, std::int32_t dy) {
  const std::int32_t ax = std::max(2 * std::abs(dx) - 1, 0);
  const std::int32_t ay = std::max(2 * std::abs(dy) - 1, 0);
  return ax * ax + ay * ay;
}

// The brushfire's reach, max_distance_m, as a squared distance in half cells: no cell keeps a reference beyond it.
std::int32_t reach_squared_half_cells(double max_distance_m, double cell_size) {
  const double reach_half_cells = 2.0 * max_distance_m / cell_size;
  return static_cast<std::int32_t>(std::floor(reach_half_cells * reach_half_cells));
}

// What a line or quarter of cells without a reference reads as its smallest squared distance: the reach, which they
// are beyond, saturated like every stored smallest distance.
std::uint16_t unreached_min_squared(std::int32_t reach_squared) {
  return static_cast<std::uint16_t>(std::min<std::int32_t>(reach_squared, std::numeric_limits<std::uint16_t>::max()));
}

std::optional<CellBox> intersect(const CellBox& a, const CellBox& b) {
  const CellBox box{{std::max(a.min.ix, b.min.ix), std::max(a.min.iy, b.min.iy)},
                    {std::min(a.max.ix, b.max.ix), std::min(a.max.iy, b.max.iy)}};
  if (box.min.ix > box.max.ix || box.min.iy > box.max.iy) return std::nullopt;
  return box;
}

bool contains(const CellBox& outer, const CellBox& inner) {
  return inner.min.ix >= outer.min.ix && inner.min.iy >= outer.min.iy && inner.max.ix <= outer.max.ix &&
         inner.max.iy <= outer.max.iy;
}

// A footprint placed in the world, in 2D.
struct PlacedFootprint {
  bool is_box = true;
  bool is_polygon = false;
  Eigen::Vector2d center_W;  // Box centre, disc centre or polygon's vertex centroid.
  Eigen::Vector2d axis_x_W = Eigen::Vector2d::UnitX();
  Eigen::Vector2d axis_y_W = Eigen::Vector2d::UnitY();
  Eigen::Vector2d half_extents = Eigen::Vector2d::Zero();  // Box only.
  double radius = 0.0;                                     // Disc only.
  std::vector<Eigen::Vector2d> vertices_W;                 // Polygon only, counter-clockwise.
  Eigen::Vector2d aabb_half_extents_W;

  PlacedFootprint(const geometry::Footprint& footprint, const geometry::Pose2& X_WB) {
    if (const auto* box = std::get_if<geometry::BoxFootprint>(&footprint)) {
      axis_x_W = {std::cos(X_WB.theta), std::sin(X_WB.theta)};
      axis_y_W = {-axis_x_W.y(), axis_x_W.x()};
      center_W = X_WB.position() + box->center_x * axis_x_W;
      half_extents = {box->length / 2.0, box->width / 2.0};
      const double abs_cos = std::abs(axis_x_W.x());
      const double abs_sin = std::abs(axis_x_W.y());
      aabb_half_extents_W = {half_extents.x() * abs_cos + half_extents.y() * abs_sin,
                             half_extents.x() * abs_sin + half_extents.y() * abs_cos};
      return;
    }
    is_box = false;
    if (const auto* polygon = std::get_if<geometry::ConvexPolygonFootprint>(&footprint)) {
      is_polygon = true;
      vertices_W = geometry::placed_vertices(*polygon, X_WB);
      center_W = geometry::vertex_centroid(vertices_W);
      aabb_half_extents_W = Eigen::Vector2d::Zero();
      for (const Eigen::Vector2d& vertex_W : vertices_W) {
        aabb_half_extents_W = aabb_half_extents_W.cwiseMax((vertex_W - center_W).cwiseAbs());
      }
      return;
    }
    radius = std::get<geometry::CylinderFootprint>(footprint).radius;
    center_W = X_WB.position();
    aabb_half_extents_W = Eigen::Vector2d::Constant(radius);
  }

  // The point of the footprint closest to p_W (p_W itself when inside).
  [[nodiscard]] Eigen::Vector2d closest_point(const Eigen::Vector2d& p_W) const {
    if (is_polygon) return geometry::closest_point_in_convex_polygon(vertices_W, p_W);
    const Eigen::Vector2d offset = p_W - center_W;
    if (is_box) {
      const double along = std::clamp(offset.dot(axis_x_W), -half_extents.x(), half_extents.x());
      const double across = std::clamp(offset.dot(axis_y_W), -half_extents.y(), half_extents.y());
      return center_W + along * axis_x_W + across * axis_y_W;
    }
    const double norm = offset.norm();
    return norm <= radius ? p_W : Eigen::Vector2d(center_W + offset * (radius / norm));
  }

  // Squared distance from p_W to the footprint, square metres; 0 inside. Squared, so that the test every cell of a
  // clearance lookup goes through takes no square root.
  [[nodiscard]] double squared_distance_to_point(const Eigen::Vector2d& p_W) const {
    if (is_polygon) return (geometry::closest_point_in_convex_polygon(vertices_W, p_W) - p_W).squaredNorm();
    const Eigen::Vector2d offset = p_W - center_W;
    if (is_box) {
      const double out_x = std::max(std::abs(offset.dot(axis_x_W)) - half_extents.x(), 0.0);
      const double out_y = std::max(std::abs(offset.dot(axis_y_W)) - half_extents.y(), 0.0);
      return out_x * out_x + out_y * out_y;
    }
    const double out = std::max(offset.norm() - radius, 0.0);
    return out * out;
  }

  // Squared distance from p_W to the footprint (as squared_distance_to_point) and whether p_W lies inside it by more
  // than margin (as deep_inside): the two tests a clearance lookup puts every cell it reads through, in one pass.
  struct Placement {
    double squared_distance;
    bool deep;
  };
  [[nodiscard]] [[gnu::always_inline]] Placement place(const Eigen::Vector2d& p_W, double margin) const {
    if (is_box) {
      const Eigen::Vector2d offset = p_W - center_W;
      const double out_x = std::abs(offset.dot(axis_x_W)) - half_extents.x();
      const double out_y = std::abs(offset.dot(axis_y_W)) - half_extents.y();
      const double clamped_x = std::max(out_x, 0.0);
      const double clamped_y = std::max(out_y, 0.0);
      return {clamped_x * clamped_x + clamped_y * clamped_y, out_x < -margin && out_y < -margin};
    }
    const double squared = squared_distance_to_point(p_W);
    return {squared, squared == 0.0 && deep_inside(p_W, margin)};
  }

  // True when p_W is inside the footprint and more than margin from its edge (never for a polygon).
  [[nodiscard]] bool deep_inside(const Eigen::Vector2d& p_W, double margin) const {
    if (is_polygon) return false;
    const Eigen::Vector2d offset = p_W - center_W;
    if (!is_box) return radius > margin && offset.squaredNorm() < (radius - margin) * (radius - margin);
    return std::abs(offset.dot(axis_x_W)) < half_extents.x() - margin &&
           std::abs(offset.dot(axis_y_W)) < half_extents.y() - margin;
  }

  // Exact distance to the closed axis-aligned square (centre, half side), metres, and the square's point where it is
  // attained; 0 and the square's point nearest the footprint's centre when they overlap.
  [[nodiscard]] std::pair<double, Eigen::Vector2d> distance_to_square(const Eigen::Vector2d& square_center_W,
                                                                      double half) const {
    return distance_to_square_below(square_center_W, half, std::numeric_limits<double>::infinity());
  }
  // The same, or infinity (and no point) when it is not below `bound`. For a box, the gap along the separating axes
  // (a lower bound of the distance) settles most squares without the corner tests: the many wall cells an edge
  // parallel to a wall refers to, all as far as the nearest.
  [[nodiscard]] std::pair<double, Eigen::Vector2d> distance_to_square_below(const Eigen::Vector2d& square_center_W,
                                                                            double half, double bound) const {
    const Eigen::Vector2d lo = square_center_W - Eigen::Vector2d::Constant(half);
    const Eigen::Vector2d hi = square_center_W + Eigen::Vector2d::Constant(half);
    const Eigen::Vector2d nearest_to_center = center_W.cwiseMax(lo).cwiseMin(hi);
    if (is_polygon) {
      const geometry::PolygonSquareDistance d =
          geometry::convex_polygon_square_distance(vertices_W, square_center_W, half);
      if (d.overlap) return {0.0, nearest_to_center};
      return {d.distance_m, d.point_on_square};
    }
    if (!is_box) {
      const double gap = (center_W - nearest_to_center).norm() - radius;
      return {std::max(gap, 0.0), nearest_to_center};
    }
    // Separating axes of a box and a square: the square's (world) axes and the box's.
    const Eigen::Vector2d offset = square_center_W - center_W;
    const double square_on_box_axes = half * (std::abs(axis_x_W.x()) + std::abs(axis_x_W.y()));
    const double gap = std::max({std::abs(offset.x()) - aabb_half_extents_W.x() - half,
                                 std::abs(offset.y()) - aabb_half_extents_W.y() - half,
                                 std::abs(offset.dot(axis_x_W)) - half_extents.x() - square_on_box_axes,
                                 std::abs(offset.dot(axis_y_W)) - half_extents.y() - square_on_box_axes});
    if (gap <= 0.0) return {0.0, nearest_to_center};
    if (gap >= bound) return {std::numeric_limits<double>::infinity(), square_center_W};
    // The closest pair of two disjoint convex polygons includes a vertex of one of them.
    double best = std::numeric_limits<double>::infinity();
    Eigen::Vector2d best_point = square_center_W;
    const Eigen::Vector2d along = half_extents.x() * axis_x_W;
    const Eigen::Vector2d across = half_extents.y() * axis_y_W;
    for (const Eigen::Vector2d& corner :
         {Eigen::Vector2d(center_W + along + across), Eigen::Vector2d(center_W - along + across),
          Eigen::Vector2d(center_W - along - across), Eigen::Vector2d(center_W + along - across)}) {
      const Eigen::Vector2d on_square = corner.cwiseMax(lo).cwiseMin(hi);
      const double squared = (corner - on_square).squaredNorm();
      if (squared < best) {
        best = squared;
        best_point = on_square;
      }
    }
    for (const Eigen::Vector2d& corner : {lo, hi, Eigen::Vector2d(lo.x(), hi.y()), Eigen::Vector2d(hi.x(), lo.y())}) {
      const double squared = (corner - closest_point(corner)).squaredNorm();
      if (squared < best) {
        best = squared;
        best_point = corner;
      }
    }
    return {std::sqrt(best), best_point};
  }
};

// Throws std::invalid_argument naming the field, with the messages of geometry::compute_clearance.
void validate_request(const geometry::ClearanceRequest& request) {
  const auto positive = [](double value, const char* field) {
    if (!(std::isfinite(value) && value > 0.0)) {
      throw std::invalid_argument(std::string("ClearanceRequest.") + field + " must be positive and finite, got " +
                                  std::to_string(value));
    }
  };
  const geometry::Pose2& pose = request.pose;
  if (!(std::isfinite(pose.x) && std::isfinite(pose.y) && std::isfinite(pose.theta))) {
    throw std::invalid_argument("ClearanceRequest.pose must be finite");
  }
  if (const auto* box = std::get_if<geometry::BoxFootprint>(&request.footprint)) {
    positive(box->length, "footprint.length");
    positive(box->width, "footprint.width");
    positive(box->height, "footprint.height");
    if (!std::isfinite(box->center_x))
      throw std::invalid_argument("ClearanceRequest.footprint.center_x must be finite");
  } else if (const auto* polygon = std::get_if<geometry::ConvexPolygonFootprint>(&request.footprint)) {
    positive(polygon->height, "footprint.height");
    const std::string problem =
        geometry::convex_polygon_problem(polygon->vertices_B, geometry::Orientation::counter_clockwise);
    if (!problem.empty()) throw std::invalid_argument("ClearanceRequest.footprint.polygon." + problem);
  } else {
    const auto& cylinder = std::get<geometry::CylinderFootprint>(request.footprint);
    positive(cylinder.radius, "footprint.radius");
    positive(cylinder.height, "footprint.height");
  }
  if (!(std::isfinite(request.max_distance_m) && request.max_distance_m >= 0.0)) {
    throw std::invalid_argument("ClearanceRequest.max_distance_m must be finite and >= 0, got " +
                                std::to_string(request.max_distance_m));
  }
}

// Cells whose index range along one axis covers world interval [lo, hi] (metres), or nullopt when it leaves int32.
std::optional<std::pair<std::int32_t, std::int32_t>> cell_range(double lo, double hi, double cell_size) {
  const double first = std::floor(lo / cell_size);
  const double last = std::floor(hi / cell_size);
  constexpr double kLowest = std::numeric_limits<std::int32_t>::min();
  constexpr double kHighest = std::numeric_limits<std::int32_t>::max();
  if (!(first >= kLowest && last <= kHighest)) return std::nullopt;
  return std::pair{static_cast<std::int32_t>(first), static_cast<std::int32_t>(last)};
}

}  // namespace

void DistanceFieldParams::validate() const {
  geometry::require(std::isfinite(max_distance_m) && max_distance_m > 0.0, "DistanceFieldParams.max_distance_m",
                    "must be finite and > 0", max_distance_m);
}

// The incremental brushfire of Lau, Sprunk & Burgard (2013), 2D, without the Voronoi part: cells hold a reference to
// their nearest occupied cell; a new obstacle starts a lowering wavefront, a removed one a raising wavefront that
// invalidates the cells referring to it and hands them back to the lowering wavefronts of the obstacles around.
//
// The cells live in 64x64 blocks allocated where a wavefront first writes, found through a directory (a dense array of
// block pointers over the blocks' bounding box, grown as needed), so the field has no extent of its own and its memory
// follows the area within max_distance of what the grid has seen. A reference is the nearest cell's offset from the
// cell (|offset| <= 2000 cells fits int16). A block's cells are row-major, so that the neighbours of a cell inside it
// (all but its edge rows and columns) are at fixed offsets and need no directory look-up.
class DistanceField::Brushfire {
 public:
  static constexpr std::int32_t kBlockShift = DistanceFieldSnapshot::kBlockShift;
  static constexpr std::int32_t kBlockCells = DistanceFieldSnapshot::kBlockCells;
  static constexpr std::int32_t kChunkShift = DistanceFieldSnapshot::kChunkShift;
  static constexpr std::int32_t kChunkBlocks = DistanceFieldSnapshot::kChunkBlocks;
  static constexpr std::int16_t kNone = DistanceFieldSnapshot::kNone;

  explicit Brushfire(std::int32_t max_squared)
      : buckets_(static_cast<std::size_t>(max_squared) + 1),
        filled_((static_cast<std::size_t>(max_squared) + 64) / 64, 0),
        max_squared_(max_squared) {}

  [[nodiscard]] bool is_obstacle(std::int32_t x, std::int32_t y) const {
    const Cell* c = find(x, y);
    return c != nullptr && c->dx == 0 && c->dy == 0;
  }

  // Makes (x, y) an obstacle or free as the grid says; true when that changed it.
  bool set_occupied(std::int32_t x, std::int32_t y, bool occupied) {
    if (occupied == is_obstacle(x, y)) return false;
    if (occupied) {
      set_obstacle(x, y);
    } else {
      remove_obstacle(x, y);
    }
    return true;
  }

  void set_obstacle(std::int32_t x, std::int32_t y) {
    Block& block = block_at(x, y);
    Cell& c = block.cells[local_index(x, y)];
    if (c.dx == 0 && c.dy == 0) return;
    c.dx = c.dy = 0;
    c.squared = 0;
    c.raise = false;
    c.state = State::kLowerQueued;
    push(0, x, y, block);
  }

  void remove_obstacle(std::int32_t x, std::int32_t y) {
    Block* block = find_block(x, y);
    if (block == nullptr) return;
    Cell& c = block->cells[local_index(x, y)];
    if (!(c.dx == 0 && c.dy == 0)) return;
    c.raise = true;
    c.dx = c.dy = kNone;
    c.squared = kInfiniteSquared;
    c.state = State::kRaiseQueued;
    push(0, x, y, *block);
  }

  // Runs the wavefronts until the queue is empty; returns the number of cells taken off it.
  std::size_t propagate() {
    std::size_t processed = 0;
    while (queued_ > 0) {
      next_bucket_ = next_filled_bucket(next_bucket_);
      std::vector<std::uint64_t>& bucket = buckets_[next_bucket_];
      const std::uint64_t packed = bucket.back();
      bucket.pop_back();
      if (bucket.empty()) filled_[next_bucket_ >> 6U] &= ~(std::uint64_t{1} << (next_bucket_ & 63U));
      --queued_;
      ++processed;
      const auto x = static_cast<std::int32_t>(static_cast<std::uint32_t>(packed));
      const auto y = static_cast<std::int32_t>(static_cast<std::uint32_t>(packed >> 32U));
      Block& block = *find_block(x, y);
      Cell& c = block.cells[local_index(x, y)];
      if (c.state == State::kLowerDone) continue;
      if (c.raise) {
        raise(x, y, block);
        c.raise = false;
        c.state = State::kRaiseDone;
      } else if (c.dx != kNone && refers_to_obstacle(block, x, y, c)) {
        c.state = State::kLowerDone;
        lower(x, y, block, c);
      }
    }
    next_bucket_ = 0;
    return processed;
  }

  // The references in blocks, in chunks over the directory: the blocks and chunks unchanged since the previous call are
  // the same shared ones; the blocks a wavefront wrote are copied out of the cells, into copies of their chunks.
  // Costs what the updates since the previous call wrote, plus a pointer per chunk (64 blocks).
  [[nodiscard]] DistanceFieldSnapshot::RefDirectory references(DistanceFieldUpdate& result) {
    using Snapshot = DistanceFieldSnapshot;
    const std::int32_t unreached_squared = unreached_min_squared(max_squared_);
    result.copied_blocks = dirty_blocks_.size();
    std::vector<std::size_t> dirty_slots;
    dirty_slots.reserve(dirty_blocks_.size());
    for (Block* block : dirty_blocks_) {
      block->dirty = false;
      dirty_slots.push_back(static_cast<std::size_t>(slot(block->bx, block->by)));
    }
    dirty_blocks_.clear();
    const auto chunk_of = [this](std::size_t b) {
      const auto [i, j] = column_row(b);
      return static_cast<std::size_t>(j >> kChunkShift) * static_cast<std::size_t>(chunks_x()) +
             static_cast<std::size_t>(i >> kChunkShift);
    };
    std::sort(dirty_slots.begin(), dirty_slots.end(), [&chunk_of](std::size_t a, std::size_t b) {
      return std::pair(chunk_of(a), a) < std::pair(chunk_of(b), b);
    });
    std::shared_ptr<Snapshot::RefChunk> copy;
    std::size_t copy_slot = 0;
    const auto finish_copy = [&] {
      if (!copy) return;
      if (!published_[copy_slot]) ++published_chunks_;
      published_[copy_slot] = std::move(copy);
      copy.reset();
    };
    for (const std::size_t b : dirty_slots) {
      const std::size_t chunk = chunk_of(b);
      if (!copy || chunk != copy_slot) {
        finish_copy();
        ++result.copied_chunks;
        copy = published_[chunk] ? std::make_shared<Snapshot::RefChunk>(*published_[chunk])
                                 : std::make_shared<Snapshot::RefChunk>();
        copy_slot = chunk;
      }
      auto refs = std::make_shared_for_overwrite<Snapshot::RefBlock>();  // Every reference is written below.
      const Block& block = *blocks_[b];
      refs->line_min_squared.fill(std::numeric_limits<std::uint16_t>::max());
      for (auto& quarters : refs->quarter_min_squared) quarters.fill(std::numeric_limits<std::uint16_t>::max());
      for (std::int32_t ly = 0; ly < kBlockCells; ++ly) {
        for (std::int32_t lx = 0; lx < kBlockCells; ++lx) {
          const Cell& cell = block.cells[local_index(lx, ly)];
          const std::size_t index = DistanceFieldSnapshot::index_in_block(lx, ly);
          refs->refs[index] = {cell.dx, cell.dy};
          const std::int32_t squared = cell.dx == kNone ? unreached_squared : squared_half_cells(cell.dx, cell.dy);
          std::uint16_t& line_min = refs->line_min_squared[index >> 4U];
          line_min = static_cast<std::uint16_t>(std::min<std::int32_t>(line_min, squared));
          // In the line, cell (x, y) is at 4 y + x; its quarter is 2 (y / 2) + x / 2.
          const std::size_t quarter = ((index >> 2U) & 2U) | ((index >> 1U) & 1U);
          std::uint16_t& quarter_min = refs->quarter_min_squared[index >> 4U][quarter];
          quarter_min = static_cast<std::uint16_t>(std::min<std::int32_t>(quarter_min, squared));
        }
      }
      const auto [i, j] = column_row(b);
      auto& in_chunk =
          copy->blocks[static_cast<std::size_t>((j & (kChunkBlocks - 1)) * kChunkBlocks + (i & (kChunkBlocks - 1)))];
      if (!in_chunk) ++published_blocks_;
      in_chunk = std::move(refs);
    }
    finish_copy();
    return {block_x0_ >> kChunkShift, block_y0_ >> kChunkShift, chunks_x(), published_,
            published_chunks_,        published_blocks_};
  }

 private:
  enum class State : std::uint8_t { kIdle, kLowerQueued, kLowerDone, kRaiseQueued, kRaiseDone };
  struct Cell {
    std::int16_t dx = kNone;  // The nearest occupied cell is (x + dx, y + dy); kNone: none within max_distance.
    std::int16_t dy = kNone;
    std::int32_t squared = kInfiniteSquared;  // To the referred cell's square, in (cell_size / 2)^2.
    State state = State::kIdle;
    bool raise = false;
  };
  struct Block {
    std::array<Cell, static_cast<std::size_t>(kBlockCells) * kBlockCells> cells{};  // Row-major.
    std::int32_t bx = 0, by = 0;                                                    // Where the block lies, in blocks.
    bool dirty = false;  // A reference changed since the last references().
  };

  static std::size_t local_index(std::int32_t x, std::int32_t y) {
    return static_cast<std::size_t>(y & (kBlockCells - 1)) * kBlockCells +
           static_cast<std::size_t>(x & (kBlockCells - 1));
  }

  // The slot of block (bx, by) in the directory, or -1 outside it.
  [[nodiscard]] std::ptrdiff_t slot(std::int32_t bx, std::int32_t by) const {
    const std::int32_t i = bx - block_x0_;
    const std::int32_t j = by - block_y0_;
    if (i < 0 || j < 0 || i >= blocks_x_ || j >= blocks_y_) return -1;
    return static_cast<std::ptrdiff_t>(j) * blocks_x_ + i;
  }

  // The block holding cell (x, y), or nullptr when none was written there.
  [[nodiscard]] Block* find_block(std::int32_t x, std::int32_t y) const {
    const std::ptrdiff_t b = slot(x >> kBlockShift, y >> kBlockShift);
    return b < 0 ? nullptr : blocks_[static_cast<std::size_t>(b)].get();
  }
  [[nodiscard]] const Cell* find(std::int32_t x, std::int32_t y) const {
    const Block* block = find_block(x, y);
    return block == nullptr ? nullptr : &block->cells[local_index(x, y)];
  }

  // The block holding cell (x, y), allocated (and the directory grown) when missing.
  Block& block_at(std::int32_t x, std::int32_t y) {
    const std::int32_t bx = x >> kBlockShift, by = y >> kBlockShift;
    std::ptrdiff_t b = slot(bx, by);
    if (b < 0) {
      grow_directory(bx, by);
      b = slot(bx, by);
    }
    auto& block = blocks_[static_cast<std::size_t>(b)];
    if (!block) {
      block = std::make_unique<Block>();
      block->bx = bx;
      block->by = by;
      mark_dirty(*block);
    }
    return *block;
  }

  // Whether the cell c at (x, y) in block still refers to an occupied cell; without a directory look-up when that cell
  // is in the same block.
  [[nodiscard]] bool refers_to_obstacle(const Block& block, std::int32_t x, std::int32_t y, const Cell& c) const {
    const std::int32_t rx = x + c.dx, ry = y + c.dy;
    const Cell* ref = (rx >> kBlockShift) == block.bx && (ry >> kBlockShift) == block.by
                          ? &block.cells[local_index(rx, ry)]
                          : find(rx, ry);
    return ref != nullptr && ref->dx == 0 && ref->dy == 0;
  }

  // Calls visit(nx, ny, neighbour, its block) for the 8 neighbours of cell (x, y) in block; neighbour is nullptr (and
  // its block too) where no block was written. The neighbours of a cell off its block's edge are at fixed offsets.
  template <typename Visit>
  void for_each_neighbour(std::int32_t x, std::int32_t y, Block& block, Visit&& visit) {
    const std::int32_t lx = x & (kBlockCells - 1), ly = y & (kBlockCells - 1);
    if (lx > 0 && ly > 0 && lx < kBlockCells - 1 && ly < kBlockCells - 1) {
      Cell* centre = &block.cells[local_index(x, y)];
      for (std::int32_t dy = -1; dy <= 1; ++dy) {
        for (std::int32_t dx = -1; dx <= 1; ++dx) {
          if (dx == 0 && dy == 0) continue;
          visit(x + dx, y + dy, centre + (dy * kBlockCells + dx), &block);
        }
      }
      return;
    }
    for (std::int32_t ny = y - 1; ny <= y + 1; ++ny) {
      for (std::int32_t nx = x - 1; nx <= x + 1; ++nx) {
        if (nx == x && ny == y) continue;
        Block* neighbour_block = find_block(nx, ny);
        visit(nx, ny, neighbour_block == nullptr ? nullptr : &neighbour_block->cells[local_index(nx, ny)],
              neighbour_block);
      }
    }
  }

  [[nodiscard]] std::int32_t chunks_x() const { return blocks_x_ >> kChunkShift; }
  // Column and row of slot b in the directory.
  [[nodiscard]] std::pair<std::int32_t, std::int32_t> column_row(std::size_t b) const {
    return {static_cast<std::int32_t>(b % static_cast<std::size_t>(blocks_x_)),
            static_cast<std::int32_t>(b / static_cast<std::size_t>(blocks_x_))};
  }

  void mark_dirty(Block& block) {
    if (block.dirty) return;
    block.dirty = true;
    dirty_blocks_.push_back(&block);
  }

  // Makes the directory cover block (bx, by), with room for 8 more blocks on each side so that it seldom regrows; its
  // edges lie on chunk boundaries, so that the published chunks keep their blocks when it grows.
  void grow_directory(std::int32_t bx, std::int32_t by) {
    constexpr std::int32_t kRoom = 8;
    const bool empty = blocks_x_ == 0;
    const auto chunk_floor = [](std::int32_t v) { return (v >> kChunkShift) << kChunkShift; };
    const std::int32_t x0 = chunk_floor(empty ? bx - kRoom : std::min(block_x0_, bx - kRoom));
    const std::int32_t y0 = chunk_floor(empty ? by - kRoom : std::min(block_y0_, by - kRoom));
    const std::int32_t x1 =
        chunk_floor(empty ? bx + kRoom : std::max(block_x0_ + blocks_x_ - 1, bx + kRoom)) + kChunkBlocks - 1;
    const std::int32_t y1 =
        chunk_floor(empty ? by + kRoom : std::max(block_y0_ + blocks_y_ - 1, by + kRoom)) + kChunkBlocks - 1;
    const std::int32_t width = x1 - x0 + 1, height = y1 - y0 + 1;
    const auto new_slot = [&](std::size_t from) {
      const auto [i, j] = column_row(from);
      return static_cast<std::size_t>(block_y0_ + j - y0) * static_cast<std::size_t>(width) +
             static_cast<std::size_t>(block_x0_ + i - x0);
    };
    const std::size_t count = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    std::vector<std::unique_ptr<Block>> blocks(count);
    for (std::size_t from = 0; from < blocks_.size(); ++from) blocks[new_slot(from)] = std::move(blocks_[from]);
    const std::int32_t new_chunks_x = width >> kChunkShift;
    DistanceFieldSnapshot::RefChunks published(count >> (2 * kChunkShift));
    for (std::size_t from = 0; from < published_.size(); ++from) {
      const auto i = static_cast<std::int32_t>(from % static_cast<std::size_t>(chunks_x()));
      const auto j = static_cast<std::int32_t>(from / static_cast<std::size_t>(chunks_x()));
      published[static_cast<std::size_t>(((block_y0_ - y0) >> kChunkShift) + j) *
                    static_cast<std::size_t>(new_chunks_x) +
                static_cast<std::size_t>(((block_x0_ - x0) >> kChunkShift) + i)] = std::move(published_[from]);
    }
    blocks_ = std::move(blocks);
    published_ = std::move(published);
    block_x0_ = x0;
    block_y0_ = y0;
    blocks_x_ = width;
    blocks_y_ = height;
  }

  // Every change of a cell's reference goes with a push of that cell, so this is where its block becomes dirty.
  void push(std::int32_t squared, std::int32_t x, std::int32_t y, Block& block) {
    mark_dirty(block);
    const auto bucket = static_cast<std::size_t>(squared);
    buckets_[bucket].push_back(static_cast<std::uint32_t>(x) | std::uint64_t{static_cast<std::uint32_t>(y)} << 32U);
    filled_[bucket >> 6U] |= std::uint64_t{1} << (bucket & 63U);
    next_bucket_ = std::min(next_bucket_, static_cast<std::size_t>(squared));
    ++queued_;
  }

  // Invalidates the neighbours that refer to a removed obstacle, and queues those that refer to a live one so that
  // their wavefront refills the invalidated cells. Neighbours in blocks never written hold no reference: skipped.
  void raise(std::int32_t x, std::int32_t y, Block& block) {
    for_each_neighbour(x, y, block, [this](std::int32_t nx, std::int32_t ny, Cell* n, Block* n_block) {
      if (n == nullptr || n->dx == kNone || n->raise) return;
      if (!refers_to_obstacle(*n_block, nx, ny, *n)) {
        push(n->squared, nx, ny, *n_block);
        n->state = State::kLowerQueued;
        n->raise = true;
        n->dx = n->dy = kNone;
        n->squared = kInfiniteSquared;
      } else if (n->state != State::kLowerQueued) {
        push(n->squared, nx, ny, *n_block);
        n->state = State::kLowerQueued;
      }
    });
  }

  // Offers c's obstacle to the neighbours; they take it when it is nearer than theirs (or as near, and theirs is gone).
  void lower(std::int32_t x, std::int32_t y, Block& block, const Cell& c) {
    const std::int32_t ref_x = x + c.dx;
    const std::int32_t ref_y = y + c.dy;
    for_each_neighbour(x, y, block, [&](std::int32_t nx, std::int32_t ny, Cell* existing, Block* n_block) {
      const std::int32_t squared = squared_half_cells(nx - ref_x, ny - ref_y);
      if (squared > max_squared_) return;
      if (existing != nullptr) {
        if (existing->raise) return;
        const bool overwrite = squared < existing->squared ||
                               (squared == existing->squared &&
                                (existing->dx == kNone || !refers_to_obstacle(*n_block, nx, ny, *existing)));
        if (!overwrite) return;
      } else {
        n_block = &block_at(nx, ny);
        existing = &n_block->cells[local_index(nx, ny)];
      }
      Cell& n = *existing;
      push(squared, nx, ny, *n_block);
      n.state = State::kLowerQueued;
      n.squared = squared;
      n.dx = static_cast<std::int16_t>(ref_x - nx);
      n.dy = static_cast<std::int16_t>(ref_y - ny);
    });
  }

  std::int32_t block_x0_ = 0, block_y0_ = 0, blocks_x_ = 0, blocks_y_ = 0;
  // The directory, row-major, its edges on chunk boundaries; nullptr: no cell written there.
  std::vector<std::unique_ptr<Block>> blocks_;
  std::vector<Block*> dirty_blocks_;            // The blocks whose dirty is set, for references() to visit only those.
  DistanceFieldSnapshot::RefChunks published_;  // The chunks the last references() returned, row-major.
  std::size_t published_chunks_ = 0;            // Of those, the ones written (not nullptr).
  std::size_t published_blocks_ = 0;            // Blocks in those chunks that are not nullptr.
  // The first non-empty bucket from `from` on; there is one while anything is queued.
  [[nodiscard]] std::size_t next_filled_bucket(std::size_t from) const {
    std::size_t word = from >> 6U;
    std::uint64_t bits = filled_[word] & (~std::uint64_t{0} << (from & 63U));
    while (bits == 0) bits = filled_[++word];
    return (word << 6U) + static_cast<std::size_t>(std::countr_zero(bits));
  }

  // Bucketed priority queue keyed by squared distance (the keys are small integers): cells as x | y << 32. The keys
  // in use are sparse (sums of two odd squares), so a bit per bucket says which are filled.
  std::vector<std::vector<std::uint64_t>> buckets_;
  std::vector<std::uint64_t> filled_;
  std::size_t next_bucket_ = 0;
  std::size_t queued_ = 0;
  std::int32_t max_squared_;
};

DistanceField::DistanceField(const DistanceFieldParams& params) : params_(params) { params_.validate(); }

DistanceField::~DistanceField() = default;

bool DistanceField::prepare(std::shared_ptr<const GridSnapshot>& grid, DistanceFieldUpdate& result) {
  if (!grid) throw std::invalid_argument("DistanceField::update: grid is null");
  const double cell_size = grid->cell_size();
  if (snapshot_ && snapshot_->cell_size() != cell_size) {
    throw std::invalid_argument("DistanceField::update: grid cell size " + std::to_string(cell_size) +
                                " differs from the previous grid's " + std::to_string(snapshot_->cell_size()));
  }
  if (params_.max_distance_m / cell_size > kMaxDistanceCells) {
    throw std::invalid_argument("DistanceFieldParams.max_distance_m must be at most 2000 cells, got " +
                                std::to_string(params_.max_distance_m / cell_size) + " cells");
  }
  if (!grid->tile_bounds()) {
    brushfire_.reset();
    snapshot_.reset(new DistanceFieldSnapshot(std::move(grid), std::nullopt, {}, params_.max_distance_m));
    return false;
  }
  if (brushfire_) return true;

  brushfire_ = std::make_unique<Brushfire>(reach_squared_half_cells(params_.max_distance_m, cell_size));
  Brushfire& brushfire = *brushfire_;
  const CellBox tiles = *grid->tile_bounds();
  grid->for_each_occupied(tiles.min, tiles.max, [&brushfire](const CellIndex& c) {
    brushfire.set_obstacle(c.ix, c.iy);
    return true;
  });
  result.rebuilt = true;
  result.processed_cells = brushfire.propagate();
  take_snapshot(std::move(grid), result);
  return false;
}

void DistanceField::take_snapshot(std::shared_ptr<const GridSnapshot> grid, DistanceFieldUpdate& result) {
  // The field answers for every cell; bounds() says where occupied cells can be near: the grid's tiles grown by the
  // field's reach.
  const auto reach = static_cast<std::int32_t>(std::ceil(params_.max_distance_m / grid->cell_size())) + 1;
  const CellBox tiles = *grid->tile_bounds();
  const CellBox bounds{{tiles.min.ix - reach, tiles.min.iy - reach}, {tiles.max.ix + reach, tiles.max.iy + reach}};
  snapshot_.reset(
      new DistanceFieldSnapshot(std::move(grid), bounds, brushfire_->references(result), params_.max_distance_m));
}

DistanceFieldUpdate DistanceField::update(std::shared_ptr<const GridSnapshot> grid, std::optional<CellBox> touched) {
  DistanceFieldUpdate result;
  if (!prepare(grid, result)) return result;
  Brushfire& brushfire = *brushfire_;
  // Cells outside the grid's tiles are unobserved, hence free: only those inside can have changed.
  const CellBox tiles = *grid->tile_bounds();
  if (const std::optional<CellBox> region = touched ? intersect(*touched, tiles) : std::optional<CellBox>(tiles)) {
    const std::int32_t width = region->max.ix - region->min.ix + 1;
    const std::int32_t height = region->max.iy - region->min.iy + 1;
    const std::vector<std::uint8_t> values = grid->window(region->min, width, height);
    const int threshold = grid->occupied_threshold();
    for (std::int32_t row = 0; row < height; ++row) {
      const std::int32_t y = region->min.iy + row;
      for (std::int32_t col = 0; col < width; ++col) {
        const std::uint8_t value = values[static_cast<std::size_t>(row) * width + col];
        const bool occupied = value != kUnobserved && value >= threshold;
        if (brushfire.set_occupied(region->min.ix + col, y, occupied)) ++result.changed_cells;
      }
    }
    result.processed_cells = brushfire.propagate();
  }
  take_snapshot(std::move(grid), result);
  return result;
}

DistanceFieldUpdate DistanceField::update(std::shared_ptr<const GridSnapshot> grid,
                                          std::span<const geometry::CellIndex> changed) {
  DistanceFieldUpdate result;
  if (!prepare(grid, result)) return result;
  Brushfire& brushfire = *brushfire_;
  for (const CellIndex& c : changed) {
    if (brushfire.set_occupied(c.ix, c.iy, grid->occupied(c))) ++result.changed_cells;
  }
  result.processed_cells = brushfire.propagate();
  take_snapshot(std::move(grid), result);
  return result;
}

DistanceFieldSnapshot::DistanceFieldSnapshot(std::shared_ptr<const GridSnapshot> grid, std::optional<CellBox> bounds,
                                             RefDirectory refs, double max_distance_m)
    : grid_(std::move(grid)), bounds_(bounds), refs_(std::move(refs)), max_distance_m_(max_distance_m) {}

const DistanceFieldSnapshot::RefBlock* DistanceFieldSnapshot::block_at(std::int32_t bx, std::int32_t by) const {
  const std::int32_t i = (bx >> kChunkShift) - refs_.chunk_x0;
  const std::int32_t j = (by >> kChunkShift) - refs_.chunk_y0;
  if (i < 0 || j < 0 || i >= refs_.chunks_x) return nullptr;
  const std::size_t slot = static_cast<std::size_t>(j) * static_cast<std::size_t>(refs_.chunks_x) + i;
  if (slot >= refs_.chunks.size() || !refs_.chunks[slot]) return nullptr;
  return refs_.chunks[slot]
      ->blocks[static_cast<std::size_t>(by & (kChunkBlocks - 1)) * kChunkBlocks +
               static_cast<std::size_t>(bx & (kChunkBlocks - 1))]
      .get();
}

std::optional<CellIndex> DistanceFieldSnapshot::nearest_occupied(const CellIndex& c) const {
  const RefBlock* block = block_at(c.ix >> kBlockShift, c.iy >> kBlockShift);
  if (block == nullptr) return std::nullopt;
  const Ref& ref = block->refs[index_in_block(c.ix, c.iy)];
  if (ref.x == kNone) return std::nullopt;
  return CellIndex{c.ix + ref.x, c.iy + ref.y};
}

double DistanceFieldSnapshot::distance(const CellIndex& c) const {
  const std::optional<CellIndex> nearest = nearest_occupied(c);
  if (!nearest) return max_distance_m_;
  const std::int32_t squared = squared_half_cells(c.ix - nearest->ix, c.iy - nearest->iy);
  return std::sqrt(static_cast<double>(squared)) * cell_size() / 2.0;
}

struct DistanceFieldSnapshot::Answer {
  geometry::ClearanceResult result;
  PlacedFootprint placed;
};

DistanceFieldSnapshot::Answer DistanceFieldSnapshot::answer(const geometry::ClearanceRequest& request) const {
  validate_request(request);
  const double cell_size = this->cell_size();
  const PlacedFootprint placed(request.footprint, request.pose);
  const double limit = request.max_distance_m;
  const auto exact = [&] {
    fallbacks_.fetch_add(1, std::memory_order_relaxed);
    return Answer{geometry::compute_clearance(request, *grid_), placed};
  };
  if (!bounds_ || limit > max_distance_m_) return exact();

  // Cells whose centres lie within half a cell diagonal of the footprint: every footprint point is that close to
  // its own cell's centre.
  const double half_diagonal = cell_size * std::sqrt(0.5);
  const Eigen::Vector2d lo = placed.center_W - placed.aabb_half_extents_W;
  const Eigen::Vector2d hi = placed.center_W + placed.aabb_half_extents_W;
  const auto xs = cell_range(lo.x() - half_diagonal, hi.x() + half_diagonal, cell_size);
  const auto ys = cell_range(lo.y() - half_diagonal, hi.y() + half_diagonal, cell_size);
  // Every occupied cell within `limit` of those centres must be in the field, else its distances are too large.
  const double reach = limit + 2.0 * cell_size;
  const auto reach_xs = cell_range(lo.x() - reach, hi.x() + reach, cell_size);
  const auto reach_ys = cell_range(lo.y() - reach, hi.y() + reach, cell_size);
  if (!xs || !ys || !reach_xs || !reach_ys) return exact();
  const CellBox near{{xs->first, ys->first}, {xs->second, ys->second}};
  const CellBox reached{{reach_xs->first, reach_ys->first}, {reach_xs->second, reach_ys->second}};
  const std::optional<CellBox> reached_tiles = intersect(reached, *grid_->tile_bounds());
  if (!contains(*bounds_, near) || (reached_tiles && !contains(*bounds_, *reached_tiles))) return exact();

  const double half_cell = cell_size / 2.0;
  const double scale = cell_size / 2.0;
  const double squared_scale = scale * scale;
  const double squared_half_diagonal = half_diagonal * half_diagonal;
  const double rounding = 1e-9 * cell_size;

  // The lookup reads the field a line at a time (4x4 cells, one cache line of references): a line's smallest
  // distance bounds all of its cells, so most lines are settled by one read, without looking at their cells.
  constexpr std::int32_t kLineCells = 1 << kLineShift;
  constexpr std::int32_t kLinesPerBlockSide = kBlockCells >> kLineShift;
  // Every cell centre of a line lies within this of the line's centre.
  const double line_half_diagonal = 0.5 * (kLineCells - 1) * cell_size * std::sqrt(2.0);
  const std::uint16_t unreached_squared = unreached_min_squared(reach_squared_half_cells(max_distance_m_, cell_size));
  struct Line {
    const RefBlock* block = nullptr;  // nullptr: no reference written there
    std::size_t index = 0;            // in the block's lines
    std::uint16_t min_squared = 0;
  };
  const auto line_at = [&](std::int32_t gx, std::int32_t gy) {
    Line line;
    line.block = block_at(gx >> (kBlockShift - kLineShift), gy >> (kBlockShift - kLineShift));
    line.index = static_cast<std::size_t>(gy & (kLinesPerBlockSide - 1)) * kLinesPerBlockSide +
                 static_cast<std::size_t>(gx & (kLinesPerBlockSide - 1));
    line.min_squared = line.block == nullptr ? unreached_squared : line.block->line_min_squared[line.index];
    return line;
  };
  const auto ref_in = [](const Line& line, std::int32_t cx, std::int32_t cy) {
    if (line.block == nullptr) return Ref{kNone, 0};
    return line.block->refs[(line.index << 4U) + (static_cast<std::size_t>(cy) << 2U) + static_cast<std::size_t>(cx)];
  };
  const geometry::GridGeometry cells(cell_size);

  // The smallest squared field distance (half cells) of the edge cells visited, and whether one had no occupied cell
  // in range: the lower bound follows from them once the loop is done, with one square root instead of one per cell.
  std::int32_t smallest_squared = kInfiniteSquared;
  bool visited_cell_out_of_range = false;
  double upper = std::numeric_limits<double>::infinity();
  // A cell whose squared field distance (square metres) is at least this cannot improve on `upper`: the footprint is
  // within half a diagonal of its centre, so its referred cell is at least distance - half_diagonal away.
  double squared_distance_to_beat = std::numeric_limits<double>::infinity();
  std::optional<CellIndex> best_cell;
  Eigen::Vector2d best_point = Eigen::Vector2d::Zero();
  std::optional<CellIndex> last_cell;
  // The edge cells read (those with an occupied cell in range), for the shell below to look only near the ones that
  // could hide a nearer obstacle; past the array's size it looks all around.
  struct EdgeCell {
    std::int32_t ix;
    std::int32_t iy;
    std::int32_t squared;
  };
  std::array<EdgeCell, 512> edge_cells;
  std::size_t edge_cell_count = 0;
  // Only the cells along the footprint's edge (centres within half a diagonal of it, and not deeper inside) bound
  // its clearance: the nearest footprint point to any obstacle outside lies on the edge, within half a diagonal of
  // its own cell's centre. The cells deeper inside only have to be free.
  const auto visit_edge_cell = [&](std::int32_t ix, std::int32_t iy, Ref ref) {
    if (ref.x == kNone) {
      visited_cell_out_of_range = true;
      return;
    }
    const std::int32_t squared = squared_half_cells(ref.x, ref.y);
    smallest_squared = std::min(smallest_squared, squared);
    if (edge_cell_count < edge_cells.size()) edge_cells[edge_cell_count] = {ix, iy, squared};
    ++edge_cell_count;
    const CellIndex nearest{ix + ref.x, iy + ref.y};
    if (static_cast<double>(squared) * squared_scale >= squared_distance_to_beat || nearest == last_cell) return;
    last_cell = nearest;
    const auto [exact_distance, point_W] = placed.distance_to_square_below(cells.center_of(nearest), half_cell, upper);
    if (exact_distance < upper) {
      upper = exact_distance;
      squared_distance_to_beat = (upper + half_diagonal) * (upper + half_diagonal);
      best_cell = nearest;
      best_point = point_W;
    }
  };
  // A line (or quarter) whose cells are all at least sqrt(min_squared) half cells off an obstacle cannot bring the
  // lower bound more than a cell below the upper one (nor hold an edge cell the shell below would look around).
  const auto may_matter = [&](std::uint32_t min_squared) {
    if (min_squared == 0) return true;  // an occupied cell: perhaps inside the footprint
    const double settled = std::min(upper, limit) - cell_size + half_diagonal + rounding;
    return settled > 0.0 && static_cast<double>(min_squared) * squared_scale < settled * settled;
  };
  // The smallest squared distance of the quarters not read that hold edge cells: a bound for those cells.
  std::uint32_t skipped_squared = std::numeric_limits<std::uint32_t>::max();
  // Reads line (gx, gy) a quarter (2x2 cells) at a time: a quarter holding no edge cell is passed over, one that
  // cannot matter is counted in skipped_squared, the others' edge cells are visited; a deep cell that is occupied
  // ends the lookup (true, at occupied_inside).
  std::optional<CellIndex> occupied_inside;
  // A quarter's cell centres lie within half a diagonal of its centre.
  const double quarter_reach = 2.0 * half_diagonal;
  const auto visit_line = [&](std::int32_t gx, std::int32_t gy, const Line& line) {
    for (std::uint32_t q = 0; q < 4; ++q) {
      const std::int32_t cx0 = static_cast<std::int32_t>(q & 1U) * 2;
      const std::int32_t cy0 = static_cast<std::int32_t>(q >> 1U) * 2;
      const auto [squared, deep] = placed.place(
          {(gx * kLineCells + cx0 + 1) * cell_size, (gy * kLineCells + cy0 + 1) * cell_size}, quarter_reach);
      if (squared > quarter_reach * quarter_reach) continue;
      const std::uint32_t min_squared =
          line.block == nullptr ? unreached_squared : line.block->quarter_min_squared[line.index][q];
      if (deep && min_squared != 0) continue;  // all its cells deep inside, and free
      if (!may_matter(min_squared)) {
        skipped_squared = std::min(skipped_squared, min_squared);
        continue;
      }
      for (std::int32_t j = 0; j < 4; ++j) {
        const std::int32_t cx = cx0 + (j & 1);
        const std::int32_t cy = cy0 + (j >> 1);
        const std::int32_t ix = gx * kLineCells + cx;
        const std::int32_t iy = gy * kLineCells + cy;
        const auto [cell_squared, cell_deep] = placed.place(cells.center_of({ix, iy}), half_diagonal);
        if (cell_squared > squared_half_diagonal) continue;
        const Ref ref = ref_in(line, cx, cy);
        if (cell_deep) {
          if (ref.x == 0 && ref.y == 0) {
            occupied_inside = CellIndex{ix, iy};
            return true;
          }
          continue;
        }
        visit_edge_cell(ix, iy, ref);
      }
    }
    return false;
  };

  // The lines holding an edge cell, in the order met. A line wholly deeper inside only has to be free: its smallest
  // distance says so. (Prefetching the references of every line that might be read, here, made cold lookups slower:
  // most of those lines are then settled by their smallest distance, unread.)
  struct EdgeLine {
    Line line;
    std::int32_t gx;
    std::int32_t gy;
  };
  const std::int32_t first_gx = near.min.ix >> kLineShift;
  const std::int32_t first_gy = near.min.iy >> kLineShift;
  const std::int32_t last_gx = near.max.ix >> kLineShift;
  const std::int32_t last_gy = near.max.iy >> kLineShift;
  thread_local std::vector<EdgeLine> edge_lines;
  // Grown only: lookups of fields of different cell sizes alternate (an all-model query), and a resize back up
  // would value-initialise the lines again on every lookup.
  const std::size_t box_lines =
      static_cast<std::size_t>(last_gx - first_gx + 1) * static_cast<std::size_t>(last_gy - first_gy + 1);
  if (edge_lines.size() < box_lines) edge_lines.resize(box_lines);
  std::size_t edge_line_count = 0;
  std::size_t nearest_line = 0;
  const double line_reach = line_half_diagonal + half_diagonal;
  for (std::int32_t gy = first_gy; gy <= last_gy && !occupied_inside; ++gy) {
    for (std::int32_t gx = first_gx; gx <= last_gx; ++gx) {
      const Eigen::Vector2d line_center_W((gx * kLineCells + 0.5 * kLineCells) * cell_size,
                                          (gy * kLineCells + 0.5 * kLineCells) * cell_size);
      const auto [squared, deep] = placed.place(line_center_W, line_reach);
      if (squared > line_reach * line_reach) continue;  // no cell centre within half a diagonal of the footprint
      const Line line = line_at(gx, gy);
      if (deep) {
        if (line.min_squared == 0 && visit_line(gx, gy, line)) break;
        continue;
      }
      if (edge_line_count == 0 || line.min_squared < edge_lines[nearest_line].line.min_squared) {
        nearest_line = edge_line_count;
      }
      edge_lines[edge_line_count++] = {line, gx, gy};
    }
  }
  // The nearest line first, which mostly settles `upper`; then every other line that may still matter. The smallest
  // squared distance of the lines not read bounds their edge cells.
  const auto read_or_skip = [&](const EdgeLine& edge_line) {
    if (may_matter(edge_line.line.min_squared)) {
      visit_line(edge_line.gx, edge_line.gy, edge_line.line);
    } else {
      skipped_squared = std::min<std::uint32_t>(skipped_squared, edge_line.line.min_squared);
    }
  };
  if (edge_line_count > 0 && !occupied_inside) read_or_skip(edge_lines[nearest_line]);
  for (std::size_t i = 0; i < edge_line_count && !occupied_inside; ++i) {
    if (i != nearest_line) read_or_skip(edge_lines[i]);
  }
  Answer answer{{}, placed};
  if (occupied_inside) {
    answer.result.found = true;
    answer.result.clearance_m = 0.0;
    answer.result.nearest_cell = occupied_inside;
    answer.result.nearest_point_W = placed.distance_to_square(cells.center_of(*occupied_inside), half_cell).second;
    return answer;
  }
  double lower = std::numeric_limits<double>::infinity();
  std::uint32_t smallest = skipped_squared;
  if (smallest_squared != kInfiniteSquared) smallest = std::min(smallest, static_cast<std::uint32_t>(smallest_squared));
  if (smallest != std::numeric_limits<std::uint32_t>::max()) {
    lower = std::sqrt(static_cast<double>(smallest)) * scale - half_diagonal;
  }
  if (visited_cell_out_of_range) lower = std::min(lower, max_distance_m_ - half_diagonal);
  // The exact clearance, capped at limit, lies in [lower, upper] (both capped likewise).
  const double capped_lower = std::clamp(lower, 0.0, limit);
  const double capped_upper = std::min(upper, limit);
  if (capped_upper - capped_lower > cell_size) {
    // The lower bound is loose by up to 1.2 cells even when the upper one is exact (a cell centre half a cell off the
    // footprint's edge, minus half a diagonal), so settle it: an occupied cell nearer than capped_upper - cell_size
    // has its centre within that plus half a diagonal of the footprint, so only the occupied cells in that shell
    // around the footprint are measured, found a line at a time (a line without one reads 0 nowhere).
    fallbacks_.fetch_add(1, std::memory_order_relaxed);
    const double radius = capped_upper - cell_size;
    const double shell_out = radius + half_diagonal;
    const double squared_shell_out = shell_out * shell_out;
    auto shell_ys = *cell_range(lo.y() - shell_out, hi.y() + shell_out, cell_size);
    auto shell_xs = *cell_range(lo.x() - shell_out, hi.x() + shell_out, cell_size);
    // An occupied cell nearer than radius is nearest to a footprint point p in the square of an edge cell c with
    // d(c) - half_diagonal <= |p - obstacle| < radius, and its centre is within radius + half a diagonal of p, so
    // within radius + a diagonal of c's centre: only the shell around such edge cells is read. The edge cells of the
    // lines not read are farther than that (see above).
    if (edge_cell_count <= edge_cells.size()) {
      const double at_risk_within = radius + half_diagonal + rounding;
      const double squared_at_risk = at_risk_within * at_risk_within / squared_scale;
      CellBox at_risk{{std::numeric_limits<std::int32_t>::max(), std::numeric_limits<std::int32_t>::max()},
                      {std::numeric_limits<std::int32_t>::min(), std::numeric_limits<std::int32_t>::min()}};
      for (std::size_t i = 0; i < edge_cell_count; ++i) {
        const EdgeCell& cell = edge_cells[i];
        if (static_cast<double>(cell.squared) >= squared_at_risk) continue;
        at_risk.min = {std::min(at_risk.min.ix, cell.ix), std::min(at_risk.min.iy, cell.iy)};
        at_risk.max = {std::max(at_risk.max.ix, cell.ix), std::max(at_risk.max.iy, cell.iy)};
      }
      if (at_risk.min.ix <= at_risk.max.ix) {
        const auto grow = static_cast<std::int32_t>(std::ceil((radius + 2.0 * half_diagonal) / cell_size)) + 1;
        shell_xs = {std::max(shell_xs.first, at_risk.min.ix - grow), std::min(shell_xs.second, at_risk.max.ix + grow)};
        shell_ys = {std::max(shell_ys.first, at_risk.min.iy - grow), std::min(shell_ys.second, at_risk.max.iy + grow)};
      }
    }
    // A line is read only when some cell centre of it may lie in the shell: not all farther than shell_out, nor all
    // nearer than `lower` (such cells are free).
    const double line_shell_out = shell_out + line_half_diagonal;
    const double line_shell_in = lower - line_half_diagonal;
    const double squared_line_shell_in = line_shell_in > 0.0 ? line_shell_in * line_shell_in : -1.0;
    for (std::int32_t gy = shell_ys.first >> kLineShift; gy <= shell_ys.second >> kLineShift; ++gy) {
      for (std::int32_t gx = shell_xs.first >> kLineShift; gx <= shell_xs.second >> kLineShift; ++gx) {
        // Most lines hold no occupied cell: one read settles them, before the footprint test.
        const Line line = line_at(gx, gy);
        if (line.min_squared != 0) continue;
        const Eigen::Vector2d line_center_W((gx * kLineCells + 0.5 * kLineCells) * cell_size,
                                            (gy * kLineCells + 0.5 * kLineCells) * cell_size);
        const double squared = placed.place(line_center_W, 0.0).squared_distance;
        if (squared > line_shell_out * line_shell_out || squared < squared_line_shell_in) continue;
        // Any occupied cell's distance is an upper bound; those in the shell can improve on `upper`.
        for (std::int32_t cy = 0; cy < kLineCells; ++cy) {
          for (std::int32_t cx = 0; cx < kLineCells; ++cx) {
            const Ref ref = ref_in(line, cx, cy);
            if (ref.x != 0 || ref.y != 0) continue;
            const CellIndex cell{gx * kLineCells + cx, gy * kLineCells + cy};
            const Eigen::Vector2d square_W = cells.center_of(cell);
            if (placed.squared_distance_to_point(square_W) > squared_shell_out) continue;
            const auto [distance, point_W] = placed.distance_to_square_below(square_W, half_cell, upper);
            if (distance < upper) {
              upper = distance;
              best_cell = cell;
              best_point = point_W;
            }
          }
        }
      }
    }
  }
  if (upper <= limit) {
    answer.result.found = true;
    answer.result.clearance_m = upper;
    answer.result.nearest_cell = best_cell;
    answer.result.nearest_point_W = best_point;
  } else {
    answer.result.clearance_m = limit;
  }
  return answer;
}

geometry::ClearanceResult DistanceFieldSnapshot::compute_clearance(const geometry::ClearanceRequest& request) const {
  return answer(request).result;
}

Eigen::Vector2d DistanceFieldSnapshot::clearance_gradient(const geometry::ClearanceRequest& request) const {
  const Answer a = answer(request);
  if (!a.result.found || !a.result.nearest_cell) return Eigen::Vector2d::Zero();
  Eigen::Vector2d direction = a.placed.closest_point(a.result.nearest_point_W) - a.result.nearest_point_W;
  if (a.result.clearance_m <= 0.0 || direction.norm() == 0.0) {
    direction = a.placed.center_W - geometry::GridGeometry(cell_size()).center_of(*a.result.nearest_cell);
  }
  const double norm = direction.norm();
  return norm > 0.0 ? Eigen::Vector2d(direction / norm) : Eigen::Vector2d::Zero();
}

}  // namespace occgeo::mapping
