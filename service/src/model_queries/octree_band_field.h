#pragma once

#include <algorithm>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "occgeo/mapping/distance_field.h"
#include "occgeo/mapping/himm_grid.h"
#include "occgeo/mapping/octomap_model.h"

// The octree's clearance from a maintained field instead of a walk over its leaves: for one height band (the octree's
// ground band up to a footprint's height) a 2D projection of the occupied voxels, a cell per voxel column, occupied
// exactly where OctoMapColumns would report a column, and a DistanceField over it. Kept in step from octree snapshot
// to octree snapshot by looking only at the columns of the tiles each publish rebuilt.

namespace occgeo::service {

// What a query reads: the band's top and the field of one octree version.
struct OctreeBandSnapshot {
  double top_m = 0.0;
  std::uint64_t octree_version = 0;
  std::shared_ptr<const mapping::DistanceFieldSnapshot> field;
};

// Footprint heights queries wanted a band for and found none (thread-safe); the octree's lane makes bands for them.
class OctreeBandRequests {
 public:
  void want(double top_m) {
    const std::lock_guard lock(mutex_);
    if (std::find(wanted_.begin(), wanted_.end(), top_m) == wanted_.end() && wanted_.size() < 16) {
      wanted_.push_back(top_m);
    }
  }
  [[nodiscard]] std::vector<double> take() {
    const std::lock_guard lock(mutex_);
    return std::exchange(wanted_, {});
  }

 private:
  std::mutex mutex_;
  std::vector<double> wanted_;
};

// The band of octree_bands whose top is top_m, or nullptr.
inline const OctreeBandSnapshot* find_octree_band(const std::vector<OctreeBandSnapshot>* bands, double top_m) {
  if (bands == nullptr) return nullptr;
  for (const OctreeBandSnapshot& band : *bands) {
    if (band.top_m == top_m && band.field) return &band;
  }
  return nullptr;
}

class OctreeBandField {
 public:
  // top_m: the band's top (a footprint's height), metres; the band starts at octomap_ground_band_m.
  OctreeBandField(double top_m, const mapping::DistanceFieldParams& params);

  // Brings the projection to octree: first from every tile, then (snapshot after snapshot of one model, none skipped)
  // only from the columns each changed. Not thread-safe: the octree's lane calls it.
  void update(const mapping::OctoMapSnapshot& octree);
  [[nodiscard]] double top_m() const { return top_m_; }
  // The latest band and field; nullptr field before the first update.
  [[nodiscard]] OctreeBandSnapshot snapshot() const { return published_; }

 private:
  // Writes the band's columns in range into the projection.
  void project(const mapping::OctoMapSnapshot& octree, const mapping::OctoColumnRange& range);

  double top_m_;
  mapping::DistanceFieldParams params_;
  std::unique_ptr<mapping::HimmGrid> projection_;  // at the octree's resolution, made anew by a full update
  std::unique_ptr<mapping::DistanceField> field_;
  std::uint64_t octree_version_ = 0;   // of the snapshot published_ was made from
  std::vector<std::uint8_t> scratch_;  // one tile's columns, occupied or not
  OctreeBandSnapshot published_;
};

}  // namespace occgeo::service
