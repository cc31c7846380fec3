#include "occgeo/mapping/distance_field.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "occgeo/geometry/convex_polygon.h"

// Distances in the brushfire are integers: the squared distance from a cell's centre to an occupied cell's square in
// units of (cell_size / 2)^2, which for index offsets (dx, dy) is (2|dx| - 1)+^2 + (2|dy| - 1)+^2. Being exact
// integers, ties and comparisons are the same on every run, so an incremental update ends in the same state as a
// build from scratch whenever both pick the same nearest cell among equals.

namespace occgeo::mapping {
namespace {

using geometry::CellIndex;

constexpr std::int32_t kInfiniteSquared = std::numeric_limits<std::int32_t>::max();

// Largest field distance and side, in cells: distances need (2 * 2000)^2 < 2^31 buckets-worth of integers and the
// references are int16.
constexpr double kMaxDistanceCells = 2000.0;
constexpr double kMaxExtentCells = 32000.0;

std::int32_t squared_half_cells(std::int32_t dx, std::int32_t dy) {
  const std::int32_t ax = std::max(2 * std::abs(dx) - 1, 0);
  const std::int32_t ay = std::max(2 * std::abs(dy) - 1, 0);
  return ax * ax + ay * ay;
}

void require(bool ok, const char* field, const char* rule, double value) {
  if (!ok) {
    throw std::invalid_argument(std::string("DistanceFieldParams.") + field + " must be " + rule + ", got " +
                                std::to_string(value));
  }
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

// One axis of the box the field is built over: the tiles' range [lo, hi] grown by margin, cut to max_cells around
// focus when longer.
std::pair<std::int64_t, std::int64_t> field_range(std::int64_t lo, std::int64_t hi, std::int64_t focus,
                                                  std::int64_t margin, std::int64_t max_cells) {
  const std::int64_t padded_lo = lo - margin;
  const std::int64_t padded_hi = hi + margin;
  if (padded_hi - padded_lo + 1 <= max_cells) return {padded_lo, padded_hi};
  const std::int64_t start = std::clamp(focus - max_cells / 2, padded_lo, padded_hi - max_cells + 1);
  return {start, start + max_cells - 1};
}

// One axis of the part of the tiles the field must cover: all of them when they fit, else those near focus. Smaller
// than field_range's cut by the margin, so that the focus can move that far before the field is rebuilt.
std::pair<std::int64_t, std::int64_t> required_range(std::int64_t lo, std::int64_t hi, std::int64_t focus,
                                                     std::int64_t margin, std::int64_t max_cells) {
  const std::int64_t reach = max_cells / 2 - margin - 1;
  return {std::max(lo, focus - reach), std::min(hi, focus + reach)};
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

  // Distance from p_W to the footprint, metres; 0 inside.
  [[nodiscard]] double distance_to_point(const Eigen::Vector2d& p_W) const {
    if (is_polygon) return (geometry::closest_point_in_convex_polygon(vertices_W, p_W) - p_W).norm();
    const Eigen::Vector2d offset = p_W - center_W;
    if (is_box) {
      const double out_x = std::max(std::abs(offset.dot(axis_x_W)) - half_extents.x(), 0.0);
      const double out_y = std::max(std::abs(offset.dot(axis_y_W)) - half_extents.y(), 0.0);
      return std::hypot(out_x, out_y);
    }
    return std::max(offset.norm() - radius, 0.0);
  }

  // Exact distance to the closed axis-aligned square (centre, half side), metres, and the square's point where it is
  // attained; 0 and the square's point nearest the footprint's centre when they overlap.
  [[nodiscard]] std::pair<double, Eigen::Vector2d> distance_to_square(const Eigen::Vector2d& square_center_W,
                                                                      double half) const {
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
  require(std::isfinite(max_distance_m) && max_distance_m > 0.0, "max_distance_m", "finite and > 0", max_distance_m);
  require(std::isfinite(growth_margin_m) && growth_margin_m >= 0.0, "growth_margin_m", "finite and >= 0",
          growth_margin_m);
  require(std::isfinite(max_extent_m) && max_extent_m > 2.0 * growth_margin_m, "max_extent_m",
          "finite and > 2 * growth_margin_m", max_extent_m);
}

// The incremental brushfire of Lau, Sprunk & Burgard (2013), 2D, without the Voronoi part: cells hold a reference to
// their nearest occupied cell; a new obstacle starts a lowering wavefront, a removed one a raising wavefront that
// invalidates the cells referring to it and hands them back to the lowering wavefronts of the obstacles around.
class DistanceField::Brushfire {
 public:
  Brushfire(const CellBox& box, std::int32_t max_squared)
      : box_(box),
        width_(box.max.ix - box.min.ix + 1),
        height_(box.max.iy - box.min.iy + 1),
        cells_(static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_)),
        blocks_x_((width_ + kBlockCells - 1) >> kBlockShift),
        blocks_y_((height_ + kBlockCells - 1) >> kBlockShift),
        dirty_blocks_(static_cast<std::size_t>(blocks_x_) * static_cast<std::size_t>(blocks_y_), 1),
        published_(dirty_blocks_.size()),
        buckets_(static_cast<std::size_t>(max_squared) + 1),
        max_squared_(max_squared) {}

  [[nodiscard]] const CellBox& box() const { return box_; }
  [[nodiscard]] std::int32_t width() const { return width_; }
  [[nodiscard]] std::int32_t height() const { return height_; }

  [[nodiscard]] bool is_obstacle(std::int32_t x, std::int32_t y) const {
    const Cell& c = at(x, y);
    return c.ref_x == x && c.ref_y == y;
  }

  void set_obstacle(std::int32_t x, std::int32_t y) {
    Cell& c = at(x, y);
    if (c.ref_x == x && c.ref_y == y) return;
    c.ref_x = static_cast<std::int16_t>(x);
    c.ref_y = static_cast<std::int16_t>(y);
    c.squared = 0;
    c.raise = false;
    c.state = State::kLowerQueued;
    push(0, x, y);
  }

  void remove_obstacle(std::int32_t x, std::int32_t y) {
    Cell& c = at(x, y);
    if (!(c.ref_x == x && c.ref_y == y)) return;
    c.raise = true;
    c.ref_x = c.ref_y = DistanceFieldSnapshot::kNone;
    c.squared = kInfiniteSquared;
    c.state = State::kRaiseQueued;
    push(0, x, y);
  }

  // Runs the wavefronts until the queue is empty; returns the number of cells taken off it.
  std::size_t propagate() {
    std::size_t processed = 0;
    while (queued_ > 0) {
      while (buckets_[next_bucket_].empty()) ++next_bucket_;
      const std::int32_t packed = buckets_[next_bucket_].back();
      buckets_[next_bucket_].pop_back();
      --queued_;
      ++processed;
      const std::int32_t x = packed % width_;
      const std::int32_t y = packed / width_;
      Cell& c = at(x, y);
      if (c.state == State::kLowerDone) continue;
      if (c.raise) {
        raise(x, y);
        c.raise = false;
        c.state = State::kRaiseDone;
      } else if (c.ref_x != DistanceFieldSnapshot::kNone && is_obstacle(c.ref_x, c.ref_y)) {
        c.state = State::kLowerDone;
        lower(x, y, c);
      }
    }
    next_bucket_ = 0;
    return processed;
  }

  // The references in blocks (row-major from box().min): the blocks unchanged since the previous call are the same
  // shared ones, only those a wavefront touched are copied out of the cells.
  [[nodiscard]] DistanceFieldSnapshot::RefBlocks references() {
    for (std::int32_t by = 0; by < blocks_y_; ++by) {
      for (std::int32_t bx = 0; bx < blocks_x_; ++bx) {
        const std::size_t b = static_cast<std::size_t>(by) * blocks_x_ + bx;
        if (dirty_blocks_[b] == 0) continue;
        dirty_blocks_[b] = 0;
        auto block = std::make_shared<DistanceFieldSnapshot::RefBlock>();
        for (std::int32_t ly = 0; ly < kBlockCells; ++ly) {
          const std::int32_t y = (by << kBlockShift) + ly;
          for (std::int32_t lx = 0; lx < kBlockCells; ++lx) {
            const std::int32_t x = (bx << kBlockShift) + lx;
            DistanceFieldSnapshot::Ref& ref = block->refs[static_cast<std::size_t>(ly) * kBlockCells + lx];
            if (x < width_ && y < height_) {
              const Cell& c = at(x, y);
              ref = {c.ref_x, c.ref_y};
            } else {
              ref = {DistanceFieldSnapshot::kNone, DistanceFieldSnapshot::kNone};
            }
          }
        }
        published_[b] = std::move(block);
      }
    }
    return published_;
  }

 private:
  enum class State : std::uint8_t { kIdle, kLowerQueued, kLowerDone, kRaiseQueued, kRaiseDone };
  struct Cell {
    std::int16_t ref_x = DistanceFieldSnapshot::kNone;
    std::int16_t ref_y = DistanceFieldSnapshot::kNone;
    std::int32_t squared = kInfiniteSquared;  // To the referred cell's square, in (cell_size / 2)^2.
    State state = State::kIdle;
    bool raise = false;
  };

  Cell& at(std::int32_t x, std::int32_t y) { return cells_[static_cast<std::size_t>(y) * width_ + x]; }
  [[nodiscard]] const Cell& at(std::int32_t x, std::int32_t y) const {
    return cells_[static_cast<std::size_t>(y) * width_ + x];
  }

  // Every change of a cell's reference goes with a push of that cell, so this is where its block becomes dirty.
  void push(std::int32_t squared, std::int32_t x, std::int32_t y) {
    dirty_blocks_[static_cast<std::size_t>(y >> kBlockShift) * blocks_x_ + (x >> kBlockShift)] = 1;
    buckets_[static_cast<std::size_t>(squared)].push_back(y * width_ + x);
    next_bucket_ = std::min(next_bucket_, static_cast<std::size_t>(squared));
    ++queued_;
  }

  template <typename Visit>
  void for_neighbours(std::int32_t x, std::int32_t y, Visit&& visit) {
    for (std::int32_t ny = std::max(y - 1, 0); ny <= std::min(y + 1, height_ - 1); ++ny) {
      for (std::int32_t nx = std::max(x - 1, 0); nx <= std::min(x + 1, width_ - 1); ++nx) {
        if (nx != x || ny != y) visit(nx, ny, at(nx, ny));
      }
    }
  }

  // Invalidates the neighbours that refer to a removed obstacle, and queues those that refer to a live one so that
  // their wavefront refills the invalidated cells.
  void raise(std::int32_t x, std::int32_t y) {
    for_neighbours(x, y, [this](std::int32_t nx, std::int32_t ny, Cell& n) {
      if (n.ref_x == DistanceFieldSnapshot::kNone || n.raise) return;
      if (!is_obstacle(n.ref_x, n.ref_y)) {
        push(n.squared, nx, ny);
        n.state = State::kLowerQueued;
        n.raise = true;
        n.ref_x = n.ref_y = DistanceFieldSnapshot::kNone;
        n.squared = kInfiniteSquared;
      } else if (n.state != State::kLowerQueued) {
        push(n.squared, nx, ny);
        n.state = State::kLowerQueued;
      }
    });
  }

  // Offers c's obstacle to the neighbours; they take it when it is nearer than theirs (or as near, and theirs is gone).
  void lower(std::int32_t x, std::int32_t y, const Cell& c) {
    const std::int32_t ref_x = c.ref_x;
    const std::int32_t ref_y = c.ref_y;
    for_neighbours(x, y, [this, ref_x, ref_y](std::int32_t nx, std::int32_t ny, Cell& n) {
      if (n.raise) return;
      const std::int32_t squared = squared_half_cells(nx - ref_x, ny - ref_y);
      if (squared > max_squared_) return;
      const bool overwrite =
          squared < n.squared ||
          (squared == n.squared && (n.ref_x == DistanceFieldSnapshot::kNone || !is_obstacle(n.ref_x, n.ref_y)));
      if (!overwrite) return;
      push(squared, nx, ny);
      n.state = State::kLowerQueued;
      n.squared = squared;
      n.ref_x = static_cast<std::int16_t>(ref_x);
      n.ref_y = static_cast<std::int16_t>(ref_y);
    });
  }

  static constexpr std::int32_t kBlockShift = DistanceFieldSnapshot::kBlockShift;
  static constexpr std::int32_t kBlockCells = DistanceFieldSnapshot::kBlockCells;

  CellBox box_;
  std::int32_t width_;
  std::int32_t height_;
  std::vector<Cell> cells_;
  std::int32_t blocks_x_;
  std::int32_t blocks_y_;
  std::vector<std::uint8_t> dirty_blocks_;         // Per block: a reference changed since the last references().
  DistanceFieldSnapshot::RefBlocks published_;     // The blocks the last references() returned.
  // Bucketed priority queue keyed by squared distance (the keys are small integers): cells as y * width + x.
  std::vector<std::vector<std::int32_t>> buckets_;
  std::size_t next_bucket_ = 0;
  std::size_t queued_ = 0;
  std::int32_t max_squared_;
};

DistanceField::DistanceField(const DistanceFieldParams& params) : params_(params) { params_.validate(); }

DistanceField::~DistanceField() = default;

bool DistanceField::prepare(std::shared_ptr<const GridSnapshot>& grid, std::optional<Eigen::Vector2d> focus_W,
                            DistanceFieldUpdate& result) {
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
  if (params_.max_extent_m / cell_size > kMaxExtentCells) {
    throw std::invalid_argument("DistanceFieldParams.max_extent_m must be at most 32000 cells, got " +
                                std::to_string(params_.max_extent_m / cell_size) + " cells");
  }
  if (focus_W && !focus_W->allFinite()) throw std::invalid_argument("DistanceField::update: focus_W must be finite");

  const std::optional<CellBox> tiles = grid->tile_bounds();
  if (!tiles) {
    brushfire_.reset();
    snapshot_.reset(new DistanceFieldSnapshot(std::move(grid), std::nullopt, {}, params_.max_distance_m));
    return false;
  }

  const auto margin = static_cast<std::int64_t>(std::ceil(params_.growth_margin_m / cell_size));
  const auto max_cells = static_cast<std::int64_t>(std::floor(params_.max_extent_m / cell_size));
  std::array<std::int64_t, 2> focus{(static_cast<std::int64_t>(tiles->min.ix) + tiles->max.ix) / 2,
                                    (static_cast<std::int64_t>(tiles->min.iy) + tiles->max.iy) / 2};
  if (focus_W) {
    const Eigen::Vector2d focus_cells = (*focus_W / cell_size).array().floor();
    focus = {static_cast<std::int64_t>(std::clamp<double>(focus_cells.x(), tiles->min.ix, tiles->max.ix)),
             static_cast<std::int64_t>(std::clamp<double>(focus_cells.y(), tiles->min.iy, tiles->max.iy))};
  }
  const auto [need_x0, need_x1] = required_range(tiles->min.ix, tiles->max.ix, focus[0], margin, max_cells);
  const auto [need_y0, need_y1] = required_range(tiles->min.iy, tiles->max.iy, focus[1], margin, max_cells);
  const CellBox required{{static_cast<std::int32_t>(need_x0), static_cast<std::int32_t>(need_y0)},
                         {static_cast<std::int32_t>(need_x1), static_cast<std::int32_t>(need_y1)}};
  if (brushfire_ && contains(brushfire_->box(), required)) return true;

  const auto [x0, x1] = field_range(tiles->min.ix, tiles->max.ix, focus[0], margin, max_cells);
  const auto [y0, y1] = field_range(tiles->min.iy, tiles->max.iy, focus[1], margin, max_cells);
  constexpr std::int64_t kLowest = std::numeric_limits<std::int32_t>::min();
  constexpr std::int64_t kHighest = std::numeric_limits<std::int32_t>::max();
  const CellBox box{
      {static_cast<std::int32_t>(std::max(x0, kLowest)), static_cast<std::int32_t>(std::max(y0, kLowest))},
      {static_cast<std::int32_t>(std::min(x1, kHighest)), static_cast<std::int32_t>(std::min(y1, kHighest))}};
  const double max_half_cells = 2.0 * params_.max_distance_m / cell_size;
  brushfire_ = std::make_unique<Brushfire>(box, static_cast<std::int32_t>(std::floor(max_half_cells * max_half_cells)));
  Brushfire& brushfire = *brushfire_;
  grid->for_each_occupied(box.min, box.max, [&brushfire, &box](const CellIndex& c) {
    brushfire.set_obstacle(c.ix - box.min.ix, c.iy - box.min.iy);
    return true;
  });
  result.rebuilt = true;
  result.processed_cells = brushfire.propagate();
  take_snapshot(std::move(grid));
  return false;
}

void DistanceField::take_snapshot(std::shared_ptr<const GridSnapshot> grid) {
  snapshot_.reset(
      new DistanceFieldSnapshot(std::move(grid), brushfire_->box(), brushfire_->references(), params_.max_distance_m));
}

DistanceFieldUpdate DistanceField::update(std::shared_ptr<const GridSnapshot> grid, std::optional<CellBox> touched,
                                          std::optional<Eigen::Vector2d> focus_W) {
  DistanceFieldUpdate result;
  if (!prepare(grid, focus_W, result)) return result;
  Brushfire& brushfire = *brushfire_;
  const CellBox& box = brushfire.box();
  if (const std::optional<CellBox> region = touched ? intersect(*touched, box) : std::optional<CellBox>(box)) {
    const std::int32_t width = region->max.ix - region->min.ix + 1;
    const std::int32_t height = region->max.iy - region->min.iy + 1;
    const std::vector<std::uint8_t> values = grid->window(region->min, width, height);
    const int threshold = grid->occupied_threshold();
    for (std::int32_t row = 0; row < height; ++row) {
      const std::int32_t y = region->min.iy - box.min.iy + row;
      for (std::int32_t col = 0; col < width; ++col) {
        const std::uint8_t value = values[static_cast<std::size_t>(row) * width + col];
        const bool occupied = value != kUnobserved && value >= threshold;
        const std::int32_t x = region->min.ix - box.min.ix + col;
        if (occupied == brushfire.is_obstacle(x, y)) continue;
        ++result.changed_cells;
        if (occupied) {
          brushfire.set_obstacle(x, y);
        } else {
          brushfire.remove_obstacle(x, y);
        }
      }
    }
    result.processed_cells = brushfire.propagate();
  }
  take_snapshot(std::move(grid));
  return result;
}

DistanceFieldUpdate DistanceField::update(std::shared_ptr<const GridSnapshot> grid,
                                          std::span<const geometry::CellIndex> changed,
                                          std::optional<Eigen::Vector2d> focus_W) {
  DistanceFieldUpdate result;
  if (!prepare(grid, focus_W, result)) return result;
  Brushfire& brushfire = *brushfire_;
  const CellBox& box = brushfire.box();
  for (const CellIndex& c : changed) {
    if (c.ix < box.min.ix || c.iy < box.min.iy || c.ix > box.max.ix || c.iy > box.max.iy) continue;
    const bool occupied = grid->occupied(c);
    const std::int32_t x = c.ix - box.min.ix;
    const std::int32_t y = c.iy - box.min.iy;
    if (occupied == brushfire.is_obstacle(x, y)) continue;
    ++result.changed_cells;
    if (occupied) {
      brushfire.set_obstacle(x, y);
    } else {
      brushfire.remove_obstacle(x, y);
    }
  }
  result.processed_cells = brushfire.propagate();
  take_snapshot(std::move(grid));
  return result;
}

DistanceFieldSnapshot::DistanceFieldSnapshot(std::shared_ptr<const GridSnapshot> grid, std::optional<CellBox> bounds,
                                             RefBlocks blocks, double max_distance_m)
    : grid_(std::move(grid)),
      bounds_(bounds),
      blocks_x_(bounds ? (bounds->max.ix - bounds->min.ix + kBlockCells) >> kBlockShift : 0),
      blocks_(std::move(blocks)),
      max_distance_m_(max_distance_m) {}

const DistanceFieldSnapshot::Ref* DistanceFieldSnapshot::ref_of(const CellIndex& c) const {
  if (!bounds_ || c.ix < bounds_->min.ix || c.iy < bounds_->min.iy || c.ix > bounds_->max.ix ||
      c.iy > bounds_->max.iy) {
    return nullptr;
  }
  const Ref& ref = ref_at(c.ix - bounds_->min.ix, c.iy - bounds_->min.iy);
  return ref.x == kNone ? nullptr : &ref;
}

double DistanceFieldSnapshot::distance(const CellIndex& c) const {
  const Ref* ref = ref_of(c);
  if (ref == nullptr) return max_distance_m_;
  const std::int32_t squared = squared_half_cells(c.ix - bounds_->min.ix - ref->x, c.iy - bounds_->min.iy - ref->y);
  return std::sqrt(static_cast<double>(squared)) * cell_size() / 2.0;
}

std::optional<CellIndex> DistanceFieldSnapshot::nearest_occupied(const CellIndex& c) const {
  const Ref* ref = ref_of(c);
  if (ref == nullptr) return std::nullopt;
  return CellIndex{bounds_->min.ix + ref->x, bounds_->min.iy + ref->y};
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
  double lower = std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
  Ref best_ref{kNone, kNone};
  Eigen::Vector2d best_point = Eigen::Vector2d::Zero();
  Ref last_ref{kNone, kNone};
  for (std::int32_t iy = near.min.iy; iy <= near.max.iy; ++iy) {
    for (std::int32_t ix = near.min.ix; ix <= near.max.ix; ++ix) {
      const Eigen::Vector2d center_W((ix + 0.5) * cell_size, (iy + 0.5) * cell_size);
      if (placed.distance_to_point(center_W) > half_diagonal) continue;
      const Ref& ref = ref_at(ix - bounds_->min.ix, iy - bounds_->min.iy);
      if (ref.x == kNone) {
        lower = std::min(lower, max_distance_m_ - half_diagonal);
        continue;
      }
      const std::int32_t x = ix - bounds_->min.ix;
      const std::int32_t y = iy - bounds_->min.iy;
      const double distance = std::sqrt(static_cast<double>(squared_half_cells(x - ref.x, y - ref.y))) * scale;
      lower = std::min(lower, distance - half_diagonal);
      // The exact distance to a cell referred to from farther away than the best so far is unlikely to beat it.
      if (distance - half_diagonal >= upper || (ref.x == last_ref.x && ref.y == last_ref.y)) continue;
      last_ref = ref;
      const Eigen::Vector2d square_W((bounds_->min.ix + ref.x + 0.5) * cell_size,
                                     (bounds_->min.iy + ref.y + 0.5) * cell_size);
      const auto [exact_distance, point_W] = placed.distance_to_square(square_W, half_cell);
      if (exact_distance < upper) {
        upper = exact_distance;
        best_ref = ref;
        best_point = point_W;
      }
    }
  }
  // The exact clearance, capped at limit, lies in [lower, upper] (both capped likewise).
  const double capped_lower = std::clamp(lower, 0.0, limit);
  const double capped_upper = std::min(upper, limit);
  if (capped_upper - capped_lower > cell_size) {
    // The lower bound is loose by up to 1.2 cells even when the upper one is exact (a cell centre half a cell off the
    // footprint's edge, minus half a diagonal), so settle it: any cell nearer than capped_upper - cell_size lies in
    // the footprint's box grown by that much; the exact distances to those cells make the answer within one cell.
    fallbacks_.fetch_add(1, std::memory_order_relaxed);
    const double radius = capped_upper - cell_size;
    const geometry::GridGeometry cells(cell_size);
    struct Best {
      const PlacedFootprint& placed;
      const geometry::GridGeometry& cells;
      double distance;
      CellIndex cell;
      Eigen::Vector2d point_W;
    } best{placed, cells, upper, {}, best_point};
    if (best_ref.x != kNone) best.cell = {bounds_->min.ix + best_ref.x, bounds_->min.iy + best_ref.y};
    grid_->for_each_occupied(cells.cell_of(lo - Eigen::Vector2d::Constant(radius)),
                             cells.cell_of(hi + Eigen::Vector2d::Constant(radius)), [&best](const CellIndex& c) {
                               const auto [distance, point_W] =
                                   best.placed.distance_to_square(best.cells.center_of(c), best.cells.cell_size() / 2);
                               if (distance < best.distance) {
                                 best.distance = distance;
                                 best.cell = c;
                                 best.point_W = point_W;
                               }
                               return true;
                             });
    upper = best.distance;
    best_point = best.point_W;
    best_ref = {static_cast<std::int16_t>(best.cell.ix - bounds_->min.ix),
                static_cast<std::int16_t>(best.cell.iy - bounds_->min.iy)};
  }
  Answer answer{{}, placed};
  if (upper <= limit) {
    answer.result.found = true;
    answer.result.clearance_m = upper;
    answer.result.nearest_cell = CellIndex{bounds_->min.ix + best_ref.x, bounds_->min.iy + best_ref.y};
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
