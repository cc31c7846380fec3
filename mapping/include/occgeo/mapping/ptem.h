#pragma once

// PTEM, the probabilistic threat exposure map of seed 004 (Rajashekaraiah 2014, §4.1–4.3): the obstacle points of each
// laser scan are clustered into circles, each circle becomes an isotropic 2D Gaussian PDF whose value on the circle is
// the threshold f_r, and the threat at a point is the sum of those PDFs (eq 4.1). Where the threat reaches f_r the
// region is restricted. CGAL does the enclosing-circle work inside ptem.cc only, so this header stays light.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace occgeo::mapping {

// How clusters carry over from one scan to the next.
enum class PtemConstruction {
  // Seed §4.2.2 (the prior method): every cluster is kept and later points may grow it, so a moving obstacle leaves a
  // growing restricted region behind.
  kCumulative,
  // Seed §4.2.3–4.2.5 (the thesis' method): clusters are rebuilt from each scan, and "all the previous information of
  // obstacle is retained only if they fall outside the LRF limits" (§4.2.5): when an obstacle is no longer in the
  // scanning range, its last seen cluster is kept (Fig 4.4). Read here as: an older cluster is kept, unchanged,
  // unless (a) its circle lies wholly inside the scanned sector, so the scan would have seen the obstacle had it
  // still been there (a moving obstacle leaves no trail, §4.2.4), or (b) a cluster of the current scan overlaps its
  // circle, i.e. the scan re-observed it and the new cluster supersedes it. A cluster only partly outside the sector
  // is therefore kept, as it must be for an obstacle the robot drives past, which leaves the field of view sideways
  // and is last seen by the edge beams; (b) is needed because the scan re-clusters the part still inside, and
  // keeping the old copy too would pile up copies along the sector's edges. See PtemModel::insert_scan.
  kSingleScan,
};

// Parameters of a PtemModel; defaults are the seed's values where it gives one, and say where they come from.
struct PtemParams {
  // Which construction the model runs.
  PtemConstruction construction = PtemConstruction::kSingleScan;
  // C_r, metres; finite, >= 0. A point farther than this from every cluster's boundary starts a new cluster. Default:
  // the width of the seed's UGV, 15 in = 0.381 m (§3.1), because "the UGV cannot go between two obstacles if the
  // distance between them is less than the UGV width" (§4.2.1). Set it to your robot's width.
  double cluster_distance_m = 0.381;
  // Radius a new cluster starts with, metres; finite, > 0. The seed calls it "a predefined radius" without a value. A
  // scan sees only an obstacle's near side and a cluster starts at a point on that side, so this radius is how deep
  // behind its first return a cluster reaches. Default 0.25 m: the seed's thin obstacle and cone (0.11 m and 0.30 m
  // across) are then restricted (100 % and >= 96 % of their discs) from a single viewpoint, and a lone return costs
  // a 0.5 m disc. At 0.02 m (the URG-04LX's accuracy) only 52-87 % of the obstacles' discs were restricted.
  double initial_cluster_radius_m = 0.25;
  // Largest radius a cluster's circle grows to, metres; finite, and either 0 (unbounded: the seed's clusters, which
  // grow as far as their points reach, §4.2.2) or >= initial_cluster_radius_m. A point that would grow
  // its nearest cluster past it starts a new cluster instead, so a wall becomes a chain of bounded clusters rather than
  // one circle around its whole length (whose disc, and the restricted region around it, would cover the free floor in
  // front of it). Default 0.5 m: a person, a cart's end or the seed's obstacles (at most 0.30 m across) fit one
  // cluster, and a wall's restricted region reaches at most about this far out from the wall.
  double max_cluster_radius_m = 0.5;
  // f_r, the threat density (1/m², a 2D PDF value) from which a point is restricted; finite, > 0. Default 0.04, the
  // seed's value (§4.3). Ignored when first_cluster_sigma_m is set.
  double restricted_threshold = 0.04;
  // The σ "pre-specified for the first cluster", metres; finite and > 0 when set. When set, f_r is not taken from
  // restricted_threshold but computed once, by eq 4.1 at the first cluster's radius, after the first scan that creates
  // a cluster, and stays fixed (§4.3).
  std::optional<double> first_cluster_sigma_m;

  // Throws std::invalid_argument naming the first field that breaks its documented range.
  void validate() const;
};

// One laser scan, already in the world frame, together with the area it covered (for the single-scan rule).
struct PtemScan {
  // Time the scan was taken, seconds; finite and not before the previous scan's.
  double stamp_s = 0.0;
  // Position of the sensor in the world frame, metres; finite.
  Eigen::Vector2d p_WS = Eigen::Vector2d::Zero();
  // Heading of the sensor's x axis in the world frame, radians counter-clockwise; finite.
  double yaw_WS = 0.0;
  // Angular width of the scan, radians, centred on the sensor's x axis; in (0, 2π]. URG-04LX: 240° (§3.2.1).
  double field_of_view_rad = 0.0;
  // Largest range the sensor measures, metres; finite, > 0. URG-04LX: 4 m (§3.2.1).
  double max_range_m = 0.0;
  // The returns (obstacle points) in the world frame, metres, all finite; beams without a return are left out.
  std::span<const Eigen::Vector2d> points_W;
};

// One cluster of the map: a circle and the Gaussian PDF that represents it.
struct PtemCluster {
  // Centre of the circle = mean μ_i of the PDF in eq 4.1, world frame, metres.
  Eigen::Vector2d centre_W = Eigen::Vector2d::Zero();
  // Radius of the circle, metres.
  double radius_m = 0.0;
  // Standard deviation σ of the PDF on both axes (K_i = σ² I), metres.
  double sigma_m = 0.0;
  // The returns the cluster gathered, world frame, metres, thinned so that no two lie within kPtemExtentSpacing_m:
  // the matter the laser saw, which collision and clearance answer against (the circle, and the restricted region
  // around it, reach into free floor behind and beside them). All lie inside the circle.
  std::vector<Eigen::Vector2d> extent_W;
  // False when the radius exceeds max_cluster_radius(f_r), so that no σ puts f_r on the circle; σ is then
  // radius / √2 and restricted() counts the whole circle as restricted (see sigma_for_radius).
  bool threshold_reachable = true;
  // Index of the scan that created the cluster (the model's first scan is 0).
  std::uint64_t first_seen_scan = 0;
  // Stamp of the scan that created the cluster, seconds.
  double first_seen_stamp_s = 0.0;
  // Scans taken since the cluster was created, as of the snapshot that returned it (0: created by the latest scan).
  std::uint64_t age_scans = 0;
  // Seconds since the cluster was created, as of the latest scan of the snapshot that returned it.
  double age_s = 0.0;
};

// Spacing below which a cluster keeps only one of two returns in its extent, metres: the extent is then within this of
// the returns themselves, and a wall of a dense scan costs a point per 2 cm rather than one per beam.
inline constexpr double kPtemExtentSpacing_m = 0.02;

// Eq 4.1 for one cluster's isotropic term at squared distance distance_sq (m²) from its mean:
// exp(−d²/(2σ²)) / (2πσ²), 1/m².
double ptem_term_density(double distance_sq, double sigma_m);

// Threat density and its gradient at one point.
struct PtemThreat {
  // f(r) of eq 4.1, 1/m².
  double value = 0.0;
  // ∇f(r), 1/m³, world frame.
  Eigen::Vector2d gradient_W = Eigen::Vector2d::Zero();
};

// The smallest circle enclosing the circle (centre_W, radius_m) and the point p_W, as CGAL's Min_sphere_of_spheres_d
// computes it; the circle itself when it already contains p_W. Radius in metres; requires radius_m >= 0.
struct PtemCircle {
  Eigen::Vector2d centre_W = Eigen::Vector2d::Zero();
  double radius_m = 0.0;
};
[[nodiscard]] PtemCircle enclose_circle_and_point(const PtemCircle& circle, const Eigen::Vector2d& p_W);

// The largest cluster radius (metres) for which some σ puts the value f_r on the circle: 1 / √(π e f_r); 1.711 m for
// f_r = 0.04. Requires f_r > 0.
[[nodiscard]] double max_cluster_radius(double f_r);

// The σ (metres) of the isotropic 2D Gaussian whose value at distance radius_m from its mean equals f_r, on the branch
// where σ grows with the radius: σ = radius / √(2u), u = −W₋₁(−π radius² f_r) (W₋₁: the lower branch of Lambert's W);
// nullopt when radius_m > max_cluster_radius(f_r). Requires radius_m > 0 and f_r > 0.
[[nodiscard]] std::optional<double> sigma_for_radius(double radius_m, double f_r);

// An immutable view of a PtemModel after one scan: any number of threads may query it, without locks, while the model
// goes on ingesting. Queries cost O(number of clusters).
class PtemSnapshot {
 public:
  // f at p_W (eq 4.1), 1/m²; 0 when there are no clusters.
  [[nodiscard]] double threat(const Eigen::Vector2d& p_W) const;
  // f and its analytic gradient at p_W.
  [[nodiscard]] PtemThreat threat_and_gradient(const Eigen::Vector2d& p_W) const;
  // True when p_W is in the restricted region: f(p_W) >= f_r, which holds on every cluster's circle (also for a
  // cluster whose threshold is unreachable, PtemCluster::threshold_reachable). False while f_r is not yet fixed.
  [[nodiscard]] bool restricted(const Eigen::Vector2d& p_W) const;

  // The clusters, ages as of the latest scan.
  [[nodiscard]] std::span<const PtemCluster> clusters() const { return clusters_; }
  // f_r in use, 1/m²; nullopt only while PtemParams::first_cluster_sigma_m is set and no cluster has been made yet.
  [[nodiscard]] std::optional<double> restricted_threshold() const { return f_r_; }
  // Number of scans the model had taken when the snapshot was made.
  [[nodiscard]] std::uint64_t scan_count() const { return scan_count_; }
  // Heap bytes of its clusters (with their extents) and their threat terms.
  [[nodiscard]] std::size_t memory_bytes() const;
  // Stamp of the latest scan, seconds; nullopt before the first scan.
  [[nodiscard]] std::optional<double> latest_stamp_s() const { return latest_stamp_s_; }

 private:
  friend class PtemModel;
  // Per-cluster constants of eq 4.1 so that a query does one exp per cluster.
  struct Term {
    Eigen::Vector2d mean_W;
    double peak;              // 1 / (2π σ²), 1/m²
    double inv_two_sigma_sq;  // 1 / (2σ²), 1/m²
  };

  PtemSnapshot(std::vector<PtemCluster> clusters, std::optional<double> f_r, std::uint64_t scan_count,
               std::optional<double> latest_stamp_s);

  std::vector<PtemCluster> clusters_;
  std::vector<Term> terms_;
  std::optional<double> f_r_;
  std::uint64_t scan_count_;
  std::optional<double> latest_stamp_s_;
};

// Builds the PTEM from scans (seed 004 §4.2–4.3) with the construction params choose. Not thread-safe: one thread
// inserts scans and takes snapshots, which any thread may then read.
class PtemModel {
 public:
  // An empty map; throws std::invalid_argument naming the bad field of params.
  explicit PtemModel(const PtemParams& params);

  // Clusters the scan's points in order (§4.2.1): a point whose distance to the nearest cluster boundary,
  // |p − c| − radius, exceeds C_r starts a new cluster of the initial radius centred on it; otherwise that nearest
  // cluster becomes enclose_circle_and_point(cluster, p), unless that circle's radius would exceed
  // max_cluster_radius_m, when the point starts a new cluster too. Every point joins the extent of the cluster it
  // went to (thinned, see PtemCluster::extent_W). Cumulative: all existing clusters take part and persist.
  // Single-scan: the scan's points are clustered from scratch, and an older cluster is kept, unchanged, unless its
  // circle lies wholly inside the scanned sector (apex p_WS, half-angle field_of_view_rad / 2 about yaw_WS, radius
  // max_range_m; the circle's centre lies at least its radius inside the sector's boundary), or the circle of one of
  // the scan's new clusters intersects it (closed discs; touching counts), which then replaces it. Kept clusters come
  // first, in their old order, then the new ones. Then σ is solved for every new or grown cluster. Throws
  // std::invalid_argument naming the bad field (points by index), changing nothing.
  void insert_scan(const PtemScan& scan);

  // An immutable view of the map as it is now. Built once per insert_scan (one copy of the cluster list), so a server
  // publishing after every sensor message does not copy the clusters for messages that did not change them.
  [[nodiscard]] std::shared_ptr<const PtemSnapshot> snapshot() const { return snapshot_; }

  // The model's whole state (parameters, clusters, f_r, scan count, latest stamp) as bytes, doubles bit for bit, for a
  // server's snapshot: restore() of them followed by the same later scans gives exactly the clusters this model would
  // have had. Layout: "OCCGEOP2", then the fields in the host's byte order, then a 64-bit FNV-1a checksum of them.
  [[nodiscard]] std::string serialize() const;

  // Replaces the state by one serialize() wrote. Returns false, changing nothing, when the bytes were written under
  // other parameters (their clusters would not be the ones these parameters build) or in the earlier layout
  // "OCCGEOP1", which kept no extents. Throws std::invalid_argument,
  // changing nothing, when the bytes are damaged (truncated, failing the checksum, or holding impossible values).
  bool restore(std::string_view bytes);

  // Number of insert_scan calls applied so far.
  [[nodiscard]] std::uint64_t scan_count() const { return scan_count_; }
  // Number of clusters in the map.
  [[nodiscard]] std::size_t cluster_count() const { return clusters_.size(); }
  // The parameters the model was made with.
  [[nodiscard]] const PtemParams& params() const { return params_; }

 private:
  // Clusters points into clusters (which may already hold clusters that take part), marking grown ones in grown.
  void cluster_points(std::span<const Eigen::Vector2d> points_W, double stamp_s, std::vector<PtemCluster>& clusters,
                      std::vector<bool>& grown) const;

  [[nodiscard]] std::shared_ptr<const PtemSnapshot> make_snapshot() const;

  PtemParams params_;
  std::vector<PtemCluster> clusters_;
  std::optional<double> f_r_;
  std::uint64_t scan_count_ = 0;
  std::optional<double> latest_stamp_s_;
  std::shared_ptr<const PtemSnapshot> snapshot_;
};

}  // namespace occgeo::mapping
