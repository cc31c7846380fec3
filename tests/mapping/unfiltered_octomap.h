#pragma once

#include "occgeo/mapping/octomap_model.h"

namespace occgeo::mapping::test_support {

// OctoMap parameters with the voxel and outlier filters off, so every inserted point lands in the tree and a test can
// predict the voxels exactly.
inline OctoMapParams unfiltered() {
  OctoMapParams params;
  params.voxel_filter_enabled = false;
  params.outlier_filter_enabled = false;
  return params;
}

}  // namespace occgeo::mapping::test_support
