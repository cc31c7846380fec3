#include "octree_band_field.h"

#include <algorithm>

#include "model_geometry.h"

namespace occgeo::service {

namespace {

constexpr std::uint8_t kOccupied = 1;  // the projection's certainty for an occupied column (threshold 1)

mapping::HimmParams projection_params(double resolution_m) {
  mapping::HimmParams params;
  params.cell_size_m = resolution_m;
  params.max_certainty = 1;
  params.increment = 1;
  params.decrement = 1;
  params.occupied_threshold = 1;
  params.seen_through_decrement = 0;
  return params;
}

}  // namespace

OctreeBandField::OctreeBandField(double top_m, const mapping::DistanceFieldParams& params)
    : top_m_(top_m), params_(params) {}

void OctreeBandField::project(const mapping::OctoMapSnapshot& octree, const mapping::OctoColumnRange& range,
                              std::vector<geometry::CellIndex>& changed) {
  const std::int32_t width = range.max.ix - range.min.ix + 1;
  const std::int32_t height = range.max.iy - range.min.iy + 1;
  scratch_.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), 0);
  const OctoMapColumns columns(octree, top_m_);
  columns.for_each_occupied(range.min, range.max, [&](const geometry::CellIndex& c) {
    scratch_[static_cast<std::size_t>(c.iy - range.min.iy) * static_cast<std::size_t>(width) +
             static_cast<std::size_t>(c.ix - range.min.ix)] = kOccupied;
    return true;
  });
  for (std::int32_t iy = range.min.iy; iy <= range.max.iy; ++iy) {
    for (std::int32_t ix = range.min.ix; ix <= range.max.ix; ++ix) {
      const bool occupied = scratch_[static_cast<std::size_t>(iy - range.min.iy) * static_cast<std::size_t>(width) +
                                     static_cast<std::size_t>(ix - range.min.ix)] != 0;
      const geometry::CellIndex c{ix, iy};
      if (occupied == projection_->occupied(c)) continue;
      // Free columns stay unobserved until they were occupied once: the field needs no cells it would never read.
      projection_->set_certainty(c, occupied ? kOccupied : 0);
      changed.push_back(c);
    }
  }
}

void OctreeBandField::update(const mapping::OctoMapSnapshot& octree) {
  if (built_ && octree.version() == octree_version_) return;
  if (!projection_) {
    projection_ = std::make_unique<mapping::HimmGrid>(projection_params(octree.resolution()));
    field_ = std::make_unique<mapping::DistanceField>(params_);
  }
  std::vector<geometry::CellIndex> changed;
  const auto& changed_columns = octree.changed_columns();
  // Incremental only from the very snapshot this band last saw; a skipped one, a load or the first update: all.
  const bool incremental = built_ && changed_columns && octree.changed_since_version() == octree_version_;
  const std::vector<mapping::OctoColumnRange> ranges = incremental ? *changed_columns : octree.all_columns();
  if (!incremental) {
    // Everything may have changed (first update, a loaded tree): columns no tile covers any more are free too.
    if (projection_->tile_bounds()) {
      projection_ = std::make_unique<mapping::HimmGrid>(projection_params(octree.resolution()));
      field_ = std::make_unique<mapping::DistanceField>(params_);
    }
  }
  for (const mapping::OctoColumnRange& range : ranges) project(octree, range, changed);
  (void)projection_->take_occupancy_changes();
  field_->update(projection_->snapshot(), std::span<const geometry::CellIndex>(changed));
  built_ = true;
  octree_version_ = octree.version();
  published_ = {top_m_, octree_version_, field_->snapshot()};
}

}  // namespace occgeo::service
