#include <cmath>
#include <stdexcept>
#include <string>

#include "occgeo/geometry/checks.h"
#include "occgeo/mapping/octomap_model.h"

namespace occgeo::mapping {

namespace {}  // namespace

void OctoMapParams::validate() const {
  // OctoMap keys are 16 bits per axis, so the resolution also bounds the mapped extent (±32768 voxels).
  geometry::require(std::isfinite(resolution_m) && resolution_m >= 0.001 && resolution_m <= 10.0,
                    "OctoMapParams.resolution_m", "must be a finite number in [0.001, 10]", resolution_m);
  geometry::require(std::isfinite(prob_hit) && prob_hit > 0.5 && prob_hit < 1.0, "OctoMapParams.prob_hit",
                    "must be in (0.5, 1)", prob_hit);
  geometry::require(std::isfinite(prob_miss) && prob_miss > 0.0 && prob_miss < 0.5, "OctoMapParams.prob_miss",
                    "must be in (0, 0.5)", prob_miss);
  geometry::require(std::isfinite(clamping_min) && clamping_min > 0.0 && clamping_min <= prob_miss,
                    "OctoMapParams.clamping_min", "must be in (0, prob_miss]", clamping_min);
  geometry::require(std::isfinite(clamping_max) && clamping_max >= prob_hit && clamping_max < 1.0,
                    "OctoMapParams.clamping_max", "must be in [prob_hit, 1)", clamping_max);
  geometry::require(
      std::isfinite(occupancy_threshold) && occupancy_threshold > clamping_min && occupancy_threshold < clamping_max,
      "OctoMapParams.occupancy_threshold", "must be in (clamping_min, clamping_max)", occupancy_threshold);
  geometry::require(std::isfinite(max_range_m) && max_range_m > 0.0, "OctoMapParams.max_range_m",
                    "must be a finite number > 0", max_range_m);
  geometry::require(
      voxel_leaf_m == 0.0 || (std::isfinite(voxel_leaf_m) && voxel_leaf_m >= 0.001 && voxel_leaf_m <= 10.0),
      "OctoMapParams.voxel_leaf_m", "must be 0 or a finite number in [0.001, 10]", voxel_leaf_m);
  geometry::require(outlier_mean_k >= 1 && outlier_mean_k <= 1000, "OctoMapParams.outlier_mean_k",
                    "must be in [1, 1000]", std::to_string(outlier_mean_k));
  geometry::require(std::isfinite(outlier_stddev_mul) && outlier_stddev_mul > 0.0, "OctoMapParams.outlier_stddev_mul",
                    "must be a finite number > 0", outlier_stddev_mul);
  geometry::require(std::isfinite(min_publish_interval_s) && min_publish_interval_s >= 0.0,
                    "OctoMapParams.min_publish_interval_s", "must be a finite number >= 0", min_publish_interval_s);
  terrain.validate();
}

}  // namespace occgeo::mapping
