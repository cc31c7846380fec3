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

void OctreeBandField::project(const mapping::OctoMapSnapshot& octree, const mapping::OctoColumnRange& range) {
  const auto width = static_cast<std::size_t>(range.max.ix - range.min.ix + 1);
  const auto height = static_cast<std::size_t>(range.max.iy - range.min.iy + 1);
  const auto index = [&](const geometry::CellIndex& c) {
    return static_cast<std::size_t>(c.iy - range.min.iy) * width + static_cast<std::size_t>(c.ix - range.min.ix);
  };
  scratch_.assign(width * height, 0);
  OctoMapColumns(octree, top_m_).for_each_occupied(range.min, range.max, [&](const geometry::CellIndex& c) {
    scratch_[index(c)] = kOccupied;
    return true;
  });
  for (std::int32_t iy = range.min.iy; iy <= range.max.iy; ++iy) {
    for (std::int32_t ix = range.min.ix; ix <= range.max.ix; ++ix) {
      const geometry::CellIndex c{ix, iy};
      const bool occupied = scratch_[index(c)] != 0;
      // Only flips are written: the grid logs each one for the field (take_occupancy_changes).
      if (occupied != projection_->occupied(c)) projection_->set_certainty(c, occupied ? kOccupied : 0);
    }
  }
}

void OctreeBandField::update(const mapping::OctoMapSnapshot& octree) {
  const bool built = published_.field != nullptr;
  if (built && octree.version() == octree_version_) return;
  const auto& changed_columns = octree.changed_columns();
  // Incremental only from the very snapshot this band last saw; a skipped one, a load or the first update: all.
  const bool incremental = built && changed_columns && octree.changed_since_version() == octree_version_;
  if (!incremental) {
    // Everything may have changed: start from an empty projection, so columns no tile covers any more are free too.
    projection_ = std::make_unique<mapping::HimmGrid>(projection_params(octree.resolution()));
    field_ = std::make_unique<mapping::DistanceField>(params_);
  }
  for (const mapping::OctoColumnRange& range : incremental ? *changed_columns : octree.all_columns()) {
    project(octree, range);
  }
  if (const auto changed = projection_->take_occupancy_changes()) {
    field_->update(projection_->snapshot(), std::span<const geometry::CellIndex>(*changed));
  } else {
    field_->update(projection_->snapshot());  // more flips than the grid logs: compare everything
  }
  octree_version_ = octree.version();
  published_ = {top_m_, octree_version_, field_->snapshot()};
}

}  // namespace occgeo::service
