#include <cmath>
#include <stdexcept>
#include <string>

#include "format_number.h"
#include "occgeo/mapping/octomap_model.h"

namespace occgeo::mapping {

namespace {

void require(bool condition, const std::string& field, const std::string& rule, const std::string& value) {
  if (!condition) throw std::invalid_argument("OctoMapParams." + field + " must be " + rule + ", got " + value);
}

void require(bool condition, const std::string& field, const std::string& rule, double value) {
  require(condition, field, rule, format_number(value));
}

}  // namespace

void OctoMapParams::validate() const {
  // OctoMap keys are 16 bits per axis, so the resolution also bounds the mapped extent (±32768 voxels).
  require(std::isfinite(resolution_m) && resolution_m >= 0.001 && resolution_m <= 10.0, "resolution_m",
          "a finite number in [0.001, 10]", resolution_m);
  require(std::isfinite(prob_hit) && prob_hit > 0.5 && prob_hit < 1.0, "prob_hit", "in (0.5, 1)", prob_hit);
  require(std::isfinite(prob_miss) && prob_miss > 0.0 && prob_miss < 0.5, "prob_miss", "in (0, 0.5)", prob_miss);
  require(std::isfinite(clamping_min) && clamping_min > 0.0 && clamping_min <= prob_miss, "clamping_min",
          "in (0, prob_miss]", clamping_min);
  require(std::isfinite(clamping_max) && clamping_max >= prob_hit && clamping_max < 1.0, "clamping_max",
          "in [prob_hit, 1)", clamping_max);
  require(
      std::isfinite(occupancy_threshold) && occupancy_threshold > clamping_min && occupancy_threshold < clamping_max,
      "occupancy_threshold", "in (clamping_min, clamping_max)", occupancy_threshold);
  require(std::isfinite(max_range_m) && max_range_m > 0.0, "max_range_m", "a finite number > 0", max_range_m);
  require(voxel_leaf_m == 0.0 || (std::isfinite(voxel_leaf_m) && voxel_leaf_m >= 0.001 && voxel_leaf_m <= 10.0),
          "voxel_leaf_m", "0 or a finite number in [0.001, 10]", voxel_leaf_m);
  require(outlier_mean_k >= 1 && outlier_mean_k <= 1000, "outlier_mean_k", "in [1, 1000]",
          std::to_string(outlier_mean_k));
  require(std::isfinite(outlier_stddev_mul) && outlier_stddev_mul > 0.0, "outlier_stddev_mul", "a finite number > 0",
          outlier_stddev_mul);
  require(std::isfinite(min_publish_interval_s) && min_publish_interval_s >= 0.0, "min_publish_interval_s",
          "a finite number >= 0", min_publish_interval_s);
  terrain.validate();
}

}  // namespace occgeo::mapping
