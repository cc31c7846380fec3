// PCL lives here only: the point-cloud filters and the .pcd reader. PCL's precompiled filter instantiations are used
// (no PCL_NO_PRECOMPILE), which keeps this translation unit at a few seconds.

#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <stdexcept>

#include "octomap_internal.h"

namespace occgeo::mapping {

namespace {

pcl::PointCloud<pcl::PointXYZ>::Ptr to_pcl(const std::vector<Eigen::Vector3f>& points) {
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  cloud->reserve(points.size());
  for (const Eigen::Vector3f& p : points) cloud->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  cloud->is_dense = true;  // the caller dropped non-finite points
  return cloud;
}

}  // namespace

std::vector<Eigen::Vector3f> filter_cloud(const std::vector<Eigen::Vector3f>& points_W, const OctoMapParams& params) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud = to_pcl(points_W);
  if (params.voxel_filter_enabled && !cloud->empty()) {
    const auto leaf = static_cast<float>(params.voxel_leaf_m > 0.0 ? params.voxel_leaf_m : params.resolution_m);
    pcl::VoxelGrid<pcl::PointXYZ> voxel_grid;
    voxel_grid.setInputCloud(cloud);
    voxel_grid.setLeafSize(leaf, leaf, leaf);
    auto out = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
    voxel_grid.filter(*out);
    cloud = out;
  }
  // The outlier filter needs more points than neighbours; a smaller cloud passes unchanged.
  if (params.outlier_filter_enabled && cloud->size() > static_cast<std::size_t>(params.outlier_mean_k)) {
    pcl::StatisticalOutlierRemoval<pcl::PointXYZ> outliers;
    outliers.setInputCloud(cloud);
    outliers.setMeanK(params.outlier_mean_k);
    outliers.setStddevMulThresh(params.outlier_stddev_mul);
    auto out = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
    outliers.filter(*out);
    cloud = out;
  }
  std::vector<Eigen::Vector3f> filtered;
  filtered.reserve(cloud->size());
  for (const pcl::PointXYZ& p : cloud->points) filtered.emplace_back(p.x, p.y, p.z);
  return filtered;
}

std::vector<Eigen::Vector3f> read_pcd_points(const std::filesystem::path& path) {
  pcl::PointCloud<pcl::PointXYZ> cloud;
  if (!std::filesystem::is_regular_file(path) || pcl::io::loadPCDFile(path.string(), cloud) != 0) {
    throw std::runtime_error("cannot read point cloud " + path.string());
  }
  std::vector<Eigen::Vector3f> points;
  points.reserve(cloud.size());
  for (const pcl::PointXYZ& p : cloud.points) points.emplace_back(p.x, p.y, p.z);
  return points;
}

}  // namespace occgeo::mapping
