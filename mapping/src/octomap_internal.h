#pragma once

// Private to the occgeo_octomap library: the pieces of OctoMapModel / OctoMapSnapshot that name OctoMap types, and the
// seams to the PCL and FCL translation units (each heavy header is included by one .cc only).

#include <octomap/OcTree.h>

#include <Eigen/Core>
#include <filesystem>
#include <memory>
#include <vector>

#include "occgeo/mapping/octomap_model.h"

namespace occgeo::mapping {

// An FCL octree wrapping a snapshot's tree; defined in octomap_collide.cc so that FCL stays there.
struct FclOctreeView;

// Wraps tree for FCL (~10 µs, the first one in a process ~5 ms); tree must outlive nothing: the view shares it.
std::shared_ptr<const FclOctreeView> make_fcl_view(const std::shared_ptr<const octomap::OcTree>& tree);

// Collides footprint at X_WB with the occupied voxels of view's tree. Throws std::invalid_argument for a footprint
// dimension that is not finite and positive.
OctoCollision collide_footprint(const FclOctreeView& view, const geometry::Footprint& footprint,
                                const geometry::Pose3& X_WB);

struct OctoMapSnapshot::Impl {
  std::shared_ptr<const octomap::OcTree> tree;
  std::shared_ptr<const FclOctreeView> fcl_view;
};

// Runs the PCL filters params enables over points_W (all finite), in that order: voxel grid, then statistical outlier
// removal; defined in octomap_filters.cc.
std::vector<Eigen::Vector3f> filter_cloud(const std::vector<Eigen::Vector3f>& points_W, const OctoMapParams& params);

}  // namespace occgeo::mapping
