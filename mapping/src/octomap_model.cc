#include "occgeo/mapping/octomap_model.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "octomap_internal.h"

namespace occgeo::mapping {

namespace {

octomap::point3d to_octo(const Eigen::Vector3d& p) {
  return {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())};
}

Eigen::Vector3d to_eigen(const octomap::point3d& p) { return {p.x(), p.y(), p.z()}; }

bool finite_pose(const geometry::Pose3& X) { return X.transform.matrix().allFinite(); }

void require_finite_pose(const geometry::Pose3& X_WS, const char* what) {
  if (!finite_pose(X_WS)) throw std::invalid_argument(std::string(what) + ": X_WS must be finite");
}

void apply_params(octomap::OcTree& tree, const OctoMapParams& params) {
  tree.setProbHit(params.prob_hit);
  tree.setProbMiss(params.prob_miss);
  tree.setClampingThresMin(params.clamping_min);
  tree.setClampingThresMax(params.clamping_max);
  tree.setOccupancyThres(params.occupancy_threshold);
}

OctoVoxel voxel_of(const octomap::OcTree::leaf_iterator& it) {
  return {to_eigen(it.getCoordinate()), it.getSize(), it->getOccupancy()};
}

// The box [min_W, max_W] clamped to the coordinates OctoMap keys can address at resolution, so that the bounding-box
// iterator never sees an out-of-range corner.
std::pair<octomap::point3d, octomap::point3d> clamped_box(const octomap::OcTree& tree, const Eigen::Vector3d& min_W,
                                                          const Eigen::Vector3d& max_W) {
  const double limit = (32767.0 - 1.0) * tree.getResolution();
  const Eigen::Vector3d lo = min_W.cwiseMax(-limit).cwiseMin(limit);
  const Eigen::Vector3d hi = max_W.cwiseMax(-limit).cwiseMin(limit);
  return {to_octo(lo), to_octo(hi)};
}

std::optional<double> occupancy_in(const octomap::OcTree& tree, const Eigen::Vector3d& p_W) {
  if (!p_W.allFinite()) return std::nullopt;
  octomap::OcTreeKey key;
  // Checked first: OcTree::search(point3d) prints an error for coordinates beyond the key range.
  if (!tree.coordToKeyChecked(to_octo(p_W), key)) return std::nullopt;
  const octomap::OcTreeNode* node = tree.search(key);
  if (node == nullptr) return std::nullopt;
  return node->getOccupancy();
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------------
// Snapshot

OctoMapSnapshot::OctoMapSnapshot(std::unique_ptr<Impl> impl, std::uint64_t version)
    : impl_(std::move(impl)), version_(version) {}

OctoMapSnapshot::~OctoMapSnapshot() = default;

std::optional<double> OctoMapSnapshot::occupancy(const Eigen::Vector3d& p_W) const {
  return occupancy_in(*impl_->tree, p_W);
}

bool OctoMapSnapshot::occupied(const Eigen::Vector3d& p_W) const {
  const std::optional<double> p = occupancy(p_W);
  return p.has_value() && *p >= impl_->tree->getOccupancyThres();
}

void OctoMapSnapshot::for_each_occupied(const Eigen::Vector3d& min_W, const Eigen::Vector3d& max_W,
                                        const std::function<bool(const OctoVoxel&)>& visit) const {
  const octomap::OcTree& tree = *impl_->tree;
  if (tree.getRoot() == nullptr || !min_W.allFinite() || !max_W.allFinite()) return;
  if ((min_W.array() > max_W.array()).any()) return;
  const auto [lo, hi] = clamped_box(tree, min_W, max_W);
  for (auto it = tree.begin_leafs_bbx(lo, hi), end = tree.end_leafs_bbx(); it != end; ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    if (!visit({to_eigen(it.getCoordinate()), it.getSize(), it->getOccupancy()})) return;
  }
}

std::vector<OctoVoxel> OctoMapSnapshot::occupied_in_box(const Eigen::Vector3d& min_W,
                                                        const Eigen::Vector3d& max_W) const {
  std::vector<OctoVoxel> voxels;
  for_each_occupied(min_W, max_W, [&](const OctoVoxel& v) {
    voxels.push_back(v);
    return true;
  });
  return voxels;
}

void OctoMapSnapshot::for_each_leaf(const std::function<void(const OctoVoxel&)>& visit) const {
  const octomap::OcTree& tree = *impl_->tree;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) visit(voxel_of(it));
}

std::optional<OctoRayHit> OctoMapSnapshot::cast_ray(const Eigen::Vector3d& origin_W, const Eigen::Vector3d& direction_W,
                                                    double max_range_m) const {
  if (!direction_W.allFinite() || direction_W.norm() == 0.0) {
    throw std::invalid_argument("cast_ray: direction_W must be finite and non-zero");
  }
  if (!origin_W.allFinite() || !std::isfinite(max_range_m) || max_range_m <= 0.0) {
    throw std::invalid_argument("cast_ray: origin_W and max_range_m must be finite, max_range_m > 0");
  }
  const octomap::OcTree& tree = *impl_->tree;
  octomap::OcTreeKey key;
  // castRay prints an error (and fails) when the origin lies beyond the key range; say "no hit" quietly instead.
  if (tree.getRoot() == nullptr || !tree.coordToKeyChecked(to_octo(origin_W), key)) return std::nullopt;
  octomap::point3d end;
  if (!tree.castRay(to_octo(origin_W), to_octo(direction_W), end, /*ignoreUnknownCells=*/true, max_range_m)) {
    return std::nullopt;
  }
  const Eigen::Vector3d center = to_eigen(end);
  return OctoRayHit{center, (center - origin_W).norm()};
}

OctoCollision OctoMapSnapshot::collide(const geometry::Footprint& footprint, const geometry::Pose3& X_WB) const {
  return collide_footprint(*impl_->fcl_view, footprint, X_WB);
}

double OctoMapSnapshot::resolution() const { return impl_->tree->getResolution(); }
std::size_t OctoMapSnapshot::leaf_count() const { return impl_->tree->getNumLeafNodes(); }
std::size_t OctoMapSnapshot::node_count() const { return impl_->tree->size(); }

// ---------------------------------------------------------------------------------------------------------------------
// Model

struct OctoMapModel::Impl {
  explicit Impl(const OctoMapParams& params) : tree(std::make_unique<octomap::OcTree>(params.resolution_m)) {
    apply_params(*tree, params);
  }

  // One reading's ray: from the batch's origin to end; end is marked occupied only when hit.
  struct Ray {
    octomap::point3d end;
    bool hit;
  };

  // Applies one batch of rays from origin exactly as OccupancyOcTreeBase::insertPointCloud → computeUpdate does
  // (free keys of every ray, end keys of hits, occupied wins over free, one update per key), but with lazy_eval: the
  // inner nodes are brought up to date once, by refresh_inner(), before anything reads them. Each key gets the same
  // single update as in the plain path, so every leaf ends up with the same log-odds.
  void apply(const octomap::point3d& origin, const std::vector<Ray>& batch) {
    free_cells.clear();
    occupied_cells.clear();
    for (const Ray& ray : batch) {
      if (tree->computeRayKeys(origin, ray.end, key_ray)) free_cells.insert(key_ray.begin(), key_ray.end());
      if (ray.hit) {
        octomap::OcTreeKey key;
        if (tree->coordToKeyChecked(ray.end, key)) occupied_cells.insert(key);
      }
    }
    for (auto it = free_cells.begin(); it != free_cells.end();) {
      it = occupied_cells.count(*it) != 0 ? free_cells.erase(it) : std::next(it);
    }
    for (const octomap::OcTreeKey& key : free_cells) tree->updateNode(key, false, /*lazy_eval=*/true);
    for (const octomap::OcTreeKey& key : occupied_cells) tree->updateNode(key, true, /*lazy_eval=*/true);
    inner_stale = true;
  }

  // Recomputes every inner node's occupancy (the max of its children) after lazy updates, and prunes, leaving the
  // tree as compact as the plain path would: O(nodes), so it runs once per publish or save, not per scan.
  void refresh_inner() {
    if (!inner_stale) return;
    tree->updateInnerOccupancy();
    tree->prune();
    inner_stale = false;
  }

  std::unique_ptr<octomap::OcTree> tree;
  bool inner_stale = false;
  // Reused between batches so that their buckets are allocated once.
  octomap::KeySet free_cells;
  octomap::KeySet occupied_cells;
  octomap::KeyRay key_ray;
  std::vector<Ray> rays;
};

OctoMapModel::OctoMapModel(const OctoMapParams& params) : params_(params) {
  params_.validate();
  impl_ = std::make_unique<Impl>(params_);
  published_at_ = Clock::now();
  publish();
}

OctoMapModel::~OctoMapModel() = default;

void OctoMapModel::insert_scan(const geometry::Pose3& X_WS, float angle_min, float angle_increment,
                               std::span<const float> ranges, float range_max) {
  require_finite_pose(X_WS, "insert_scan");
  if (!std::isfinite(angle_min) || !std::isfinite(angle_increment)) {
    throw std::invalid_argument("insert_scan: angle_min and angle_increment must be finite");
  }
  if (!std::isfinite(range_max) || range_max <= 0.0F) {
    throw std::invalid_argument("insert_scan: range_max must be finite and > 0");
  }
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    if (std::isnan(ranges[i]) || ranges[i] < 0.0F) {
      throw std::invalid_argument("insert_scan: ranges[" + std::to_string(i) + "] must be >= 0 and not NaN");
    }
  }
  const double clear_length = std::min<double>(range_max, params_.max_range_m);
  const octomap::point3d origin = to_octo(X_WS.translation());
  std::vector<Impl::Ray>& rays = impl_->rays;
  rays.clear();
  rays.reserve(ranges.size());
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    const double r = ranges[i];
    if (r == 0.0) continue;  // no return: says nothing about the beam
    const bool hit = r < double{range_max} && r <= params_.max_range_m;
    const double length = hit ? r : clear_length;
    const double angle = double{angle_min} + static_cast<double>(i) * double{angle_increment};
    const Eigen::Vector3d p_S{length * std::cos(angle), length * std::sin(angle), 0.0};
    rays.push_back({to_octo(X_WS.transform * p_S), hit});
  }
  impl_->apply(origin, rays);
  ++version_;
}

void OctoMapModel::insert_ray(const geometry::Pose3& X_WS, double range_m, double range_max_m) {
  require_finite_pose(X_WS, "insert_ray");
  if (!std::isfinite(range_max_m) || range_max_m <= 0.0) {
    throw std::invalid_argument("insert_ray: range_max_m must be finite and > 0");
  }
  if (std::isnan(range_m) || range_m < 0.0) throw std::invalid_argument("insert_ray: range_m must be >= 0");
  if (range_m == 0.0) return;
  const bool hit = range_m < range_max_m && range_m <= params_.max_range_m;
  const double length = hit ? range_m : std::min(range_max_m, params_.max_range_m);
  const Eigen::Vector3d p_S{length, 0.0, 0.0};
  impl_->rays.assign({Impl::Ray{to_octo(X_WS.transform * p_S), hit}});
  impl_->apply(to_octo(X_WS.translation()), impl_->rays);
  ++version_;
}

std::size_t OctoMapModel::insert_cloud(const geometry::Pose3& X_WS, std::span<const Eigen::Vector3f> points_S) {
  require_finite_pose(X_WS, "insert_cloud");
  const Eigen::Isometry3f X_WS_f = X_WS.transform.cast<float>();
  std::vector<Eigen::Vector3f> points_W;
  points_W.reserve(points_S.size());
  for (const Eigen::Vector3f& p_S : points_S) {
    if (p_S.allFinite()) points_W.push_back(X_WS_f * p_S);
  }
  if (params_.voxel_filter_enabled || params_.outlier_filter_enabled) points_W = filter_cloud(points_W, params_);

  const octomap::point3d origin = to_octo(X_WS.translation());
  const octomap::OcTree& tree = *impl_->tree;
  std::vector<Impl::Ray>& rays = impl_->rays;
  rays.clear();
  rays.reserve(points_W.size());
  octomap::KeySet end_keys;  // only for discretize_endpoints
  for (const Eigen::Vector3f& p : points_W) {
    octomap::point3d end{p.x(), p.y(), p.z()};
    if (params_.discretize_endpoints) {
      // As computeDiscreteUpdate: one ray per end voxel, to the voxel's centre.
      octomap::OcTreeKey key;
      if (!tree.coordToKeyChecked(end, key) || !end_keys.insert(key).second) continue;
      end = tree.keyToCoord(key);
    }
    // Same arithmetic (float) as computeUpdate's max-range branch, so that this path and insertPointCloud agree.
    if ((end - origin).norm() <= params_.max_range_m) {
      rays.push_back({end, true});
    } else {
      rays.push_back({origin + (end - origin).normalized() * static_cast<float>(params_.max_range_m), false});
    }
  }
  impl_->apply(origin, rays);
  ++version_;
  return points_W.size();
}

std::size_t OctoMapModel::import_pcd(const std::filesystem::path& path, const geometry::Pose3& X_WS) {
  const std::vector<Eigen::Vector3f> points_S = read_pcd_points(path);
  return insert_cloud(X_WS, points_S);
}

void OctoMapModel::save_bt(const std::filesystem::path& path) {
  impl_->refresh_inner();
  // writeBinaryConst, not writeBinary: the latter turns the live tree itself into its maximum-likelihood version.
  if (!impl_->tree->writeBinaryConst(path.string())) {
    throw std::runtime_error("cannot write OctoMap file " + path.string());
  }
}

void OctoMapModel::load_bt(const std::filesystem::path& path) {
  if (!std::filesystem::is_regular_file(path)) throw std::runtime_error("no OctoMap file " + path.string());
  auto tree = std::make_unique<octomap::OcTree>(params_.resolution_m);
  if (!tree->readBinary(path.string())) throw std::runtime_error("cannot read OctoMap file " + path.string());
  OctoMapParams params = params_;
  params.resolution_m = tree->getResolution();
  params.validate();
  apply_params(*tree, params);
  params_ = params;
  impl_->tree = std::move(tree);
  impl_->inner_stale = false;
  ++version_;
}

std::shared_ptr<const OctoMapSnapshot> OctoMapModel::publish() {
  impl_->refresh_inner();
  auto copy = std::make_shared<const octomap::OcTree>(*impl_->tree);
  auto snapshot_impl = std::make_unique<OctoMapSnapshot::Impl>();
  snapshot_impl->fcl_view = make_fcl_view(copy);
  snapshot_impl->tree = std::move(copy);
  std::shared_ptr<const OctoMapSnapshot> snapshot{new OctoMapSnapshot(std::move(snapshot_impl), version_)};
  {
    const std::lock_guard lock(snapshot_mutex_);
    snapshot_ = snapshot;
  }
  published_version_ = version_;
  published_at_ = Clock::now();
  return snapshot;
}

bool OctoMapModel::maybe_publish(Clock::time_point now) {
  if (version_ == published_version_) return false;
  if (now - published_at_ < std::chrono::duration<double>(params_.min_publish_interval_s)) return false;
  publish();
  return true;
}

std::shared_ptr<const OctoMapSnapshot> OctoMapModel::snapshot() const {
  const std::lock_guard lock(snapshot_mutex_);
  return snapshot_;
}

std::optional<double> OctoMapModel::occupancy(const Eigen::Vector3d& p_W) const {
  return occupancy_in(*impl_->tree, p_W);
}

void OctoMapModel::for_each_leaf(const std::function<void(const OctoVoxel&)>& visit) const {
  const octomap::OcTree& tree = *impl_->tree;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) visit(voxel_of(it));
}

std::size_t OctoMapModel::leaf_count() const { return impl_->tree->getNumLeafNodes(); }

}  // namespace occgeo::mapping
