#pragma once

#include <Eigen/Core>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <vector>

#include "occgeo/geometry/cell.h"
#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/mapping/beam_limits.h"
#include "occgeo/mapping/terrain_params.h"

// A 3D occupancy octree (OctoMap) per world. OctoMap, FCL and PCL stay inside octomap_*.cc: this header names none of
// their types, so users of the model do not pay for their headers.

namespace occgeo::mapping {

// Parameters of an OctoMapModel. Probabilities are OctoMap's sensor model (Hornung et al. 2013); the defaults are
// OctoMap's own.
struct OctoMapParams {
  // Edge of a leaf voxel, metres; finite, in [0.001, 10].
  double resolution_m = 0.05;
  // Probability that a voxel holding a reading's end point is occupied; in (0.5, 1).
  double prob_hit = 0.7;
  // Probability that a voxel a beam passes through is occupied; in (0, 0.5).
  double prob_miss = 0.4;
  // Lower clamp of a voxel's occupancy probability, so that it can change again quickly; in (0, prob_miss].
  double clamping_min = 0.1192;
  // Upper clamp of a voxel's occupancy probability; in [prob_hit, 1).
  double clamping_max = 0.971;
  // Probability from which a voxel counts as occupied; in (clamping_min, clamping_max).
  double occupancy_threshold = 0.5;
  // Longest beam inserted, metres; a reading beyond it only clears its beam up to this length. Finite, > 0.
  double max_range_m = 10.0;
  // A laser scan (insert_scan) that sees through an occupied voxel, a beam passing it with none ending within 0.2 m
  // of it, caps the voxel's log-odds at the occupancy threshold's plus half a miss after the miss: the
  // next such scan leaves it free, so a person who walked on is gone after two scans instead of after up to
  // log-odds(clamping_max) / |log-odds(prob_miss)| (9 by default). Voxels near a hit are spared so that a wall that
  // beams graze keeps its voxels. Off: plain OctoMap.
  bool laser_see_through_clears = true;
  // Snap cloud end points to voxel centres before ray casting (OctoMap's computeDiscreteUpdate). Faster on dense
  // clouds but NOT the same map: the free rays end at voxel centres, so they cross other voxels
  // (octomap_insert_test measures how many differ). Off by default.
  bool discretize_endpoints = false;
  // PCL voxel-grid downsampling of point clouds before insertion (one centroid per leaf).
  bool voxel_filter_enabled = true;
  // Leaf edge of the voxel-grid filter, metres; 0 means resolution_m, else finite, in [0.001, 10].
  double voxel_leaf_m = 0.0;
  // PCL statistical outlier removal of point clouds (after the voxel grid): a point whose mean distance to its
  // outlier_mean_k nearest neighbours exceeds the cloud's mean by outlier_stddev_mul standard deviations is dropped.
  bool outlier_filter_enabled = true;
  // Neighbours per point of the outlier filter; in [1, 1000].
  int outlier_mean_k = 20;
  // Threshold of the outlier filter, standard deviations; finite, > 0.
  double outlier_stddev_mul = 1.0;
  // Shortest time between two snapshots taken by OctoMapModel::maybe_publish, seconds; finite, >= 0. A snapshot
  // copies the tiles that changed since the previous one (see OctoMapModel::publish), so this bounds that cost per
  // second of ingest.
  double min_publish_interval_s = 0.2;
  // How the octree's readers tell the floor and drivable surfaces from obstacles (config section `terrain:`): every
  // snapshot carries it, so footprint queries, the guard and the planner of one world all apply the same rule.
  TerrainParams terrain;

  // Throws std::invalid_argument naming the first field that breaks its documented range.
  void validate() const;
};

// The x, y, z of every point of a .pcd file (any fields including x, y, z; ascii, binary and binary_compressed), read
// with PCL's reader, in the file's order; NaNs are kept (an organized cloud's invalid pixels). Throws
// std::runtime_error when the file cannot be read.
std::vector<Eigen::Vector3f> read_pcd_points(const std::filesystem::path& path);

// A leaf voxel of an octree: a pruned leaf (all eight children equal) is one bigger voxel.
struct OctoVoxel {
  // Centre in the world frame, metres.
  Eigen::Vector3d center_W = Eigen::Vector3d::Zero();
  // Edge length, metres: the resolution, or a power-of-two multiple of it for a pruned leaf.
  double size_m = 0.0;
  // Occupancy probability in [clamping_min, clamping_max].
  double probability = 0.0;
};

// A range of x-y columns of the tree: cell indices at the octree's resolution (cell i spans [i r, (i + 1) r) metres,
// as the voxel keys do), both corners included.
struct OctoColumnRange {
  geometry::CellIndex min;
  geometry::CellIndex max;
};

// Result of OctoMapSnapshot::cast_ray.
struct OctoRayHit {
  // Centre of the first occupied voxel along the ray, world frame, metres.
  Eigen::Vector3d voxel_center_W = Eigen::Vector3d::Zero();
  // Distance from the ray's origin to voxel_center_W, metres.
  double distance_m = 0.0;
};

// Result of OctoMapSnapshot::collide.
struct OctoCollision {
  // True when the footprint overlaps an occupied voxel (unknown space counts as free, as in FCL).
  bool hit = false;
  // A point of the overlap, world frame, metres; meaningful only when hit.
  Eigen::Vector3d contact_W = Eigen::Vector3d::Zero();
};

// An immutable copy of an OctoMapModel's tree at one version. Any number of threads may query it at the same time,
// without locks, while the model goes on ingesting; it owns its tree, so holding it never blocks the model.
class OctoMapSnapshot {
 public:
  ~OctoMapSnapshot();
  OctoMapSnapshot(const OctoMapSnapshot&) = delete;
  OctoMapSnapshot& operator=(const OctoMapSnapshot&) = delete;

  // Occupancy probability of the voxel holding p_W; nullopt when it was never observed (or lies outside the tree).
  [[nodiscard]] std::optional<double> occupancy(const Eigen::Vector3d& p_W) const;
  // True when the voxel holding p_W was observed with a probability at or above the occupancy threshold.
  [[nodiscard]] bool occupied(const Eigen::Vector3d& p_W) const;

  // Calls visit on every occupied leaf overlapping the box [min_W, max_W] (world frame, metres), until it returns
  // false. Serves collision checks and 2D projections of a height band (give the band as the box's z range).
  void for_each_occupied(const Eigen::Vector3d& min_W, const Eigen::Vector3d& max_W,
                         const std::function<bool(const OctoVoxel&)>& visit) const;
  // The occupied leaves overlapping the box [min_W, max_W], as above.
  [[nodiscard]] std::vector<OctoVoxel> occupied_in_box(const Eigen::Vector3d& min_W,
                                                       const Eigen::Vector3d& max_W) const;
  // Calls visit on every leaf (free and occupied) in no particular order.
  void for_each_leaf(const std::function<void(const OctoVoxel&)>& visit) const;

  // The first occupied voxel along the ray from origin_W in direction_W (need not be unit length) within max_range_m
  // (metres, > 0), stepping through unknown voxels (OctoMap's castRay with ignoreUnknown); nullopt when none.
  // Throws std::invalid_argument for a zero or non-finite direction.
  [[nodiscard]] std::optional<OctoRayHit> cast_ray(const Eigen::Vector3d& origin_W, const Eigen::Vector3d& direction_W,
                                                   double max_range_m) const;

  // Collides a 3D footprint (a box, a vertical cylinder or an extruded convex polygon standing on base_link's z = 0,
  // see geometry/footprint.h) at pose X_WB with the occupied voxels, using FCL's octree collision; unknown voxels count
  // as free. A pose whose footprint's bounding box misses every occupied column of a coarse x-y summary of the tree
  // (built at publish) is answered "no collision" without FCL; the answer is always the same as collide_fcl_only's.
  [[nodiscard]] OctoCollision collide(const geometry::Footprint& footprint, const geometry::Pose3& X_WB) const;
  // collide without the column summary: FCL's octree walk for every pose. The reference collide is checked against.
  [[nodiscard]] OctoCollision collide_fcl_only(const geometry::Footprint& footprint, const geometry::Pose3& X_WB) const;

  // Edge of a leaf voxel, metres.
  [[nodiscard]] double resolution() const;
  // The terrain rule the model was made with (OctoMapParams::terrain).
  [[nodiscard]] const TerrainParams& terrain() const { return terrain_; }
  // Number of leaves (pruned leaves count once).
  [[nodiscard]] std::size_t leaf_count() const;
  // Number of nodes of the tree, inner ones included.
  [[nodiscard]] std::size_t node_count() const;
  // The model's version when the snapshot was taken.
  [[nodiscard]] std::uint64_t version() const { return version_; }
  // Heap bytes of the model as of this snapshot, counted from node numbers (each node and each inner node's array of
  // child pointers is an allocation of its own): the snapshot's tiles (trees and column summaries) plus the live tree
  // the model inserts into, whose node count publish records.
  [[nodiscard]] std::size_t memory_bytes() const;
  // The columns of the tiles this snapshot rebuilt since the model's previous snapshot (each tile's x-y extent, once
  // per x-y), or nullopt when it rebuilt every tile (the model's first snapshot, or after a load): what a projection
  // of the tree kept in step from snapshot to snapshot must look at again.
  [[nodiscard]] const std::optional<std::vector<OctoColumnRange>>& changed_columns() const;
  // The version of the model's previous snapshot, which changed_columns is relative to.
  [[nodiscard]] std::uint64_t changed_since_version() const;
  // The columns of every tile of the snapshot, once per x-y: where a projection built from scratch must look.
  [[nodiscard]] std::vector<OctoColumnRange> all_columns() const;

 private:
  friend class OctoMapModel;
  struct Impl;
  OctoMapSnapshot(std::unique_ptr<Impl> impl, std::uint64_t version, const TerrainParams& terrain);

  std::unique_ptr<Impl> impl_;
  std::uint64_t version_;
  TerrainParams terrain_;
};

// A 3D occupancy octree of one world. Not thread-safe for writing: one thread (the world's strand) inserts, saves and
// publishes; readers on any thread take snapshot() and query that.
//
// Insertion follows OctoMap's insertPointCloud exactly (one free update per voxel a beam crosses, one occupied update
// per end voxel, occupied winning within one call) but defers the inner nodes' occupancy (lazy_eval) and brings it up
// to date once, before anything reads the inner nodes (publish, save, inner-node queries): the leaves are identical to
// the plain path's (octomap_insert_test proves it on a real scan), only the pruning differs until prune.
class OctoMapModel {
 public:
  using Clock = std::chrono::steady_clock;

  // An empty tree; throws std::invalid_argument naming the bad field of params.
  explicit OctoMapModel(const OctoMapParams& params);
  ~OctoMapModel();
  OctoMapModel(const OctoMapModel&) = delete;
  OctoMapModel& operator=(const OctoMapModel&) = delete;

  // Applies a planar scan taken by a sensor at the 6-DoF pose X_WS (= X_WB ∘ mount): reading i is a ray along
  // angle angle_min + i * angle_increment (radians, counter-clockwise about the sensor's z axis from its x axis) in the
  // sensor's x-y plane. Readings >= range_max (metres, +inf included) or beyond params.max_range_m clear their beam up
  // to the shorter of the two and mark nothing; a reading of 0 means "no return" and is skipped. Throws
  // std::invalid_argument, changing nothing, for a NaN or negative reading (naming its index), a non-finite pose or
  // angle, or a range_max that is not finite and positive. limits (each capped at params.max_range_m) cut what each
  // reading changes, as beam_use says.
  void insert_scan(const geometry::Pose3& X_WS, float angle_min, float angle_increment, std::span<const float> ranges,
                   float range_max, const BeamLimits& limits = {});

  // Applies single readings (a sonar's acoustic axis, a servo-swept beam): each is a ray along the x axis of its own
  // sensor pose X_WS; a range >= range_max_m clears up to range_max_m (capped at params.max_range_m) and marks
  // nothing. Throws std::invalid_argument, changing nothing, for a NaN or negative range, a non-finite pose, or a
  // range_max_m that is not finite and positive. limits as in insert_scan.
  void insert_ray(const geometry::Pose3& X_WS, double range_m, double range_max_m, const BeamLimits& limits = {});

  // Applies a point cloud given in the frame of a sensor at pose X_WS: non-finite points (organized clouds' NaNs) are
  // dropped, the rest go through the PCL filters the params enable (in the world frame), then each is a ray from the
  // sensor's position. Returns the number of points inserted after filtering. Throws std::invalid_argument, changing
  // nothing, for a non-finite pose. limits as in insert_scan: a point beyond limits.max_insert_range_m only carves its
  // ray up to that distance (clouds have no "no return").
  std::size_t insert_cloud(const geometry::Pose3& X_WS, std::span<const Eigen::Vector3f> points_S,
                           const BeamLimits& limits = {});

  // Reads a .pcd file (any fields including x, y, z; binary_compressed too) with PCL's reader and inserts it as
  // insert_cloud does with the sensor at X_WS. Returns the number of points inserted. Throws std::runtime_error when
  // the file cannot be read.
  std::size_t import_pcd(const std::filesystem::path& path, const geometry::Pose3& X_WS);

  // Writes the tree as an OctoMap binary file (.bt, maximum-likelihood occupancy per leaf, readable by OctoMap's own
  // tools). Throws std::runtime_error when the file cannot be written.
  void save_bt(const std::filesystem::path& path);
  // Replaces the tree by the one in an OctoMap .bt file, adopting the file's resolution (params().resolution_m is
  // updated). Throws std::runtime_error, changing nothing, when the file cannot be read.
  void load_bt(const std::filesystem::path& path);

  // Brings the inner nodes of the changed tiles (3.2 m cubes of 64 voxels a side at the default resolution) and of
  // their ancestors up to date, prunes them, copies each changed tile into a tree of its own (with its FCL view and the
  // occupied-column summary collide uses), and makes a snapshot of those and the unchanged tiles of the previous one,
  // the one snapshot() returns. Costs O(nodes of the changed tiles), ~50-100 ns per node: after a load, or on the first
  // publish, the whole tree; after a scan, the tiles its rays changed (clamped voxels do not change).
  std::shared_ptr<const OctoMapSnapshot> publish();
  // Publishes when the latest snapshot is older than params.min_publish_interval_s (by now) and the tree changed
  // since; returns whether it did.
  bool maybe_publish(Clock::time_point now = Clock::now());
  // The latest published snapshot (an empty tree before the first publish). Safe from any thread.
  [[nodiscard]] std::shared_ptr<const OctoMapSnapshot> snapshot() const;

  // Occupancy probability of the voxel holding p_W in the live tree; nullopt when unobserved. Writer's thread only.
  [[nodiscard]] std::optional<double> occupancy(const Eigen::Vector3d& p_W) const;
  // Calls visit on every leaf of the live tree. Writer's thread only.
  void for_each_leaf(const std::function<void(const OctoVoxel&)>& visit) const;
  // Number of leaves of the live tree.
  [[nodiscard]] std::size_t leaf_count() const;
  // Number of insert and load calls applied so far.
  [[nodiscard]] std::uint64_t version() const { return version_; }
  // The parameters in force.
  [[nodiscard]] const OctoMapParams& params() const { return params_; }

 private:
  struct Impl;

  OctoMapParams params_;
  std::unique_ptr<Impl> impl_;
  std::uint64_t version_ = 0;
  std::uint64_t published_version_ = 0;
  Clock::time_point published_at_{};
  mutable std::mutex snapshot_mutex_;  // guards only the snapshot_ pointer swap, never the tree
  std::shared_ptr<const OctoMapSnapshot> snapshot_;
};

}  // namespace occgeo::mapping
