#include "occgeo/mapping/ptem.h"
#include "occgeo/geometry/checks.h"
#include "occgeo/geometry/fnv1a.h"

#include <CGAL/Min_sphere_of_spheres_d.h>
#include <CGAL/Min_sphere_of_spheres_d_traits_2.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

namespace occgeo::mapping {

namespace {

using Kernel = CGAL::Simple_cartesian<double>;
// Tag_true: let CGAL take square roots, so the result is a plain double rather than a + b√c.
using MinCircleTraits = CGAL::Min_sphere_of_spheres_d_traits_2<Kernel, double, CGAL::Tag_true>;
using MinCircle = CGAL::Min_sphere_of_spheres_d<MinCircleTraits>;

constexpr double kTwoPi = 2.0 * std::numbers::pi;

std::string format_point(const Eigen::Vector2d& p) {
  return "(" + geometry::number_text(p.x()) + ", " + geometry::number_text(p.y()) + ")";
}

// Distance from q (relative to a segment's start) to the segment of the given length along unit direction u.
double distance_to_segment(const Eigen::Vector2d& q, const Eigen::Vector2d& u, double length) {
  const double t = std::clamp(q.dot(u), 0.0, length);
  return (q - t * u).norm();
}

// Distance from p_W to the closed sector the scan covered: apex p_WS, within field_of_view_rad / 2 of the heading
// yaw_WS and within max_range_m; 0 inside. Outside the wedge the nearest point lies on one of the two bounding
// segments (the arc's points nearest to such a point are its ends), which holds for wedges wider than 180° too (the
// URG-04LX's is 240°).
double distance_to_scanned_sector(const Eigen::Vector2d& p_W, const PtemScan& scan) {
  const Eigen::Vector2d q = p_W - scan.p_WS;
  const double beyond_range = std::max(0.0, q.norm() - scan.max_range_m);
  if (scan.field_of_view_rad >= kTwoPi) return beyond_range;
  const double half = scan.field_of_view_rad / 2.0;
  const Eigen::Vector2d heading(std::cos(scan.yaw_WS), std::sin(scan.yaw_WS));
  const double bearing = std::atan2(heading.x() * q.y() - heading.y() * q.x(), heading.dot(q));
  if (std::abs(bearing) <= half) return beyond_range;
  const Eigen::Vector2d left(std::cos(scan.yaw_WS + half), std::sin(scan.yaw_WS + half));
  const Eigen::Vector2d right(std::cos(scan.yaw_WS - half), std::sin(scan.yaw_WS - half));
  return std::min(distance_to_segment(q, left, scan.max_range_m), distance_to_segment(q, right, scan.max_range_m));
}

// How deep p_W lies inside that sector: its distance to the sector's complement, 0 outside. Inside, the nearest
// point of the complement lies on the sector's boundary: on the arc, straight out along the ray through p_W (which is
// in the wedge), at max_range_m − |q|; or on one of the two bounding segments (none for a full circle).
double depth_in_scanned_sector(const Eigen::Vector2d& p_W, const PtemScan& scan) {
  if (distance_to_scanned_sector(p_W, scan) > 0.0) return 0.0;
  const Eigen::Vector2d q = p_W - scan.p_WS;
  const double to_arc = std::max(0.0, scan.max_range_m - q.norm());
  if (scan.field_of_view_rad >= kTwoPi) return to_arc;
  const double half = scan.field_of_view_rad / 2.0;
  const Eigen::Vector2d left(std::cos(scan.yaw_WS + half), std::sin(scan.yaw_WS + half));
  const Eigen::Vector2d right(std::cos(scan.yaw_WS - half), std::sin(scan.yaw_WS - half));
  return std::min(
      {to_arc, distance_to_segment(q, left, scan.max_range_m), distance_to_segment(q, right, scan.max_range_m)});
}

// Adds p_W to the cluster's extent unless a point already there lies within kPtemExtentSpacing_m of it.
void add_to_extent(PtemCluster& cluster, const Eigen::Vector2d& p_W) {
  constexpr double kSpacingSq = kPtemExtentSpacing_m * kPtemExtentSpacing_m;
  // Newest first: a scan's returns come in beam order, so a near neighbour is usually among the last ones.
  for (auto it = cluster.extent_W.rbegin(); it != cluster.extent_W.rend(); ++it) {
    if ((*it - p_W).squaredNorm() < kSpacingSq) return;
  }
  cluster.extent_W.push_back(p_W);
}

// True when the two clusters' closed discs intersect (touching counts).
bool circles_overlap(const PtemCluster& a, const PtemCluster& b) {
  return (a.centre_W - b.centre_W).norm() <= a.radius_m + b.radius_m;
}

// Checks each field before its value is formatted for the message: a valid scan costs no string work.
void validate_scan(const PtemScan& scan, const std::optional<double>& latest_stamp_s) {
  if (!std::isfinite(scan.stamp_s)) {
    geometry::fail_requirement("PtemScan.stamp_s", "must be finite", geometry::number_text(scan.stamp_s));
  }
  if (latest_stamp_s && !(scan.stamp_s >= *latest_stamp_s)) {
    geometry::fail_requirement("PtemScan.stamp_s",
                               "must be >= the previous scan's stamp " + geometry::number_text(*latest_stamp_s),
                               geometry::number_text(scan.stamp_s));
  }
  if (!scan.p_WS.allFinite()) geometry::fail_requirement("PtemScan.p_WS", "must be finite", format_point(scan.p_WS));
  if (!std::isfinite(scan.yaw_WS)) {
    geometry::fail_requirement("PtemScan.yaw_WS", "must be finite", geometry::number_text(scan.yaw_WS));
  }
  if (!(scan.field_of_view_rad > 0.0 && scan.field_of_view_rad <= kTwoPi)) {
    geometry::fail_requirement("PtemScan.field_of_view_rad", "must be in (0, 2pi]",
                               geometry::number_text(scan.field_of_view_rad));
  }
  if (!(std::isfinite(scan.max_range_m) && scan.max_range_m > 0.0)) {
    geometry::fail_requirement("PtemScan.max_range_m", "must be a finite number > 0",
                               geometry::number_text(scan.max_range_m));
  }
  for (std::size_t i = 0; i < scan.points_W.size(); ++i) {
    if (!scan.points_W[i].allFinite()) {
      geometry::fail_requirement("PtemScan.points_W[" + std::to_string(i) + "]", "must be finite",
                                 format_point(scan.points_W[i]));
    }
  }
}

}  // namespace

void PtemParams::validate() const {
  geometry::require(std::isfinite(cluster_distance_m) && cluster_distance_m >= 0.0, "PtemParams.cluster_distance_m",
                    "must be a finite number >= 0", cluster_distance_m);
  geometry::require(std::isfinite(initial_cluster_radius_m) && initial_cluster_radius_m > 0.0,
                    "PtemParams.initial_cluster_radius_m", "must be a finite number > 0", initial_cluster_radius_m);
  geometry::require(std::isfinite(max_cluster_radius_m) &&
                        (max_cluster_radius_m == 0.0 || max_cluster_radius_m >= initial_cluster_radius_m),
                    "PtemParams.max_cluster_radius_m",
                    "must be 0 (unbounded) or a finite number >= initial_cluster_radius_m", max_cluster_radius_m);
  geometry::require(std::isfinite(restricted_threshold) && restricted_threshold > 0.0,
                    "PtemParams.restricted_threshold", "must be a finite number > 0", restricted_threshold);
  if (first_cluster_sigma_m) {
    geometry::require(std::isfinite(*first_cluster_sigma_m) && *first_cluster_sigma_m > 0.0,
                      "PtemParams.first_cluster_sigma_m", "must be a finite number > 0 when set",
                      *first_cluster_sigma_m);
  }
  geometry::require(construction == PtemConstruction::kCumulative || construction == PtemConstruction::kSingleScan,
                    "PtemParams.construction", "must be kCumulative or kSingleScan",
                    std::to_string(static_cast<int>(construction)));
}

PtemCircle enclose_circle_and_point(const PtemCircle& circle, const Eigen::Vector2d& p_W) {
  // §4.2.1: "If the new data point is already inside the cluster, then no change is required."
  if ((p_W - circle.centre_W).norm() <= circle.radius_m) return circle;
  const std::array<MinCircleTraits::Sphere, 2> spheres{
      MinCircleTraits::Sphere(Kernel::Point_2(circle.centre_W.x(), circle.centre_W.y()), circle.radius_m),
      MinCircleTraits::Sphere(Kernel::Point_2(p_W.x(), p_W.y()), 0.0)};
  MinCircle min_circle(spheres.begin(), spheres.end());
  auto centre = min_circle.center_cartesian_begin();
  const double x = *centre;
  ++centre;
  const double y = *centre;
  return PtemCircle{Eigen::Vector2d(x, y), min_circle.radius()};
}

namespace {

// exp(-exponent) for exponent >= 0, with 0 for the exponents whose result would be subnormal or underflow: libm takes
// a slow path for those (raising the underflow flag, setting errno), and a cluster far from the point asked about
// (every cluster but the few near it, on a large map) contributes nothing a double can add to a threat anyway.
double falloff(double exponent) {
  constexpr double kSmallestNormalExponent = 708.0;  // exp(-708) ~ 3.3e-308, just above DBL_MIN
  return exponent < kSmallestNormalExponent ? std::exp(-exponent) : 0.0;
}

}  // namespace

double ptem_term_density(double distance_sq, double sigma_m) {
  const double sigma_sq = sigma_m * sigma_m;
  return falloff(distance_sq / (2.0 * sigma_sq)) / (kTwoPi * sigma_sq);
}

double max_cluster_radius(double f_r) { return 1.0 / std::sqrt(std::numbers::pi * std::numbers::e * f_r); }

std::optional<double> sigma_for_radius(double radius_m, double f_r) {
  // Eq 4.1 for one cluster at distance R = radius_m from its mean, set equal to f_r:
  //   f_r = exp(−R²/(2σ²)) / (2πσ²).
  // With u = R²/(2σ²), i.e. σ² = R²/(2u), this is f_r = u e^{−u} / (πR²), so (−u) e^{−u} = −πR² f_r and
  // −u = W(−πR² f_r). A real solution needs −πR² f_r >= −1/e, i.e. R <= 1/√(πe f_r). Of the two branches, W₀ gives
  // u in (0, 1] and a σ that shrinks as R grows (σ → 1/√(2π f_r), about 2 m, for a tiny cluster); W₋₁ gives u >= 1 and
  // σ that grows with R, which is what the seed reads into σ ("variance increases ... restricted region is also
  // getting bigger", §6.1.1). Both put f_r exactly on the circle; W₋₁ is the one used.
  //
  // W₋₁ is computed here rather than by boost::math::lambert_wm1, which returns 0 when compiled with
  // -frounding-math, as CGAL requires of this file. With a = πR²f_r and L = −ln a, u e^{−u} = a is h(u) = u − ln u − L
  // = 0 on u >= 1; h is increasing and convex there and h(2L) >= 0 for L >= 1, so Newton's method from u = 2L descends
  // monotonically onto the root (linearly only at the branch point itself, L = 1).
  const double a = std::numbers::pi * radius_m * radius_m * f_r;
  const double big_l = -std::log(a);
  if (big_l < 1.0 - 1e-12) return std::nullopt;
  double u = 1.0;
  if (big_l > 1.0) {
    u = 2.0 * big_l;
    for (int iteration = 0; iteration < 200; ++iteration) {
      const double step = (u - std::log(u) - big_l) / (1.0 - 1.0 / u);
      u -= step;
      if (!(step > 1e-15 * u) || u <= 1.0) break;
    }
    u = std::max(u, 1.0);
  }
  return radius_m / std::sqrt(2.0 * u);
}

std::size_t PtemSnapshot::memory_bytes() const {
  std::size_t bytes = clusters_.capacity() * sizeof(PtemCluster) + terms_.capacity() * sizeof(Term);
  for (const PtemCluster& cluster : clusters_) bytes += cluster.extent_W.capacity() * sizeof(Eigen::Vector2d);
  return bytes;
}

PtemSnapshot::PtemSnapshot(std::vector<PtemCluster> clusters, std::optional<double> f_r, std::uint64_t scan_count,
                           std::optional<double> latest_stamp_s)
    : clusters_(std::move(clusters)), f_r_(f_r), scan_count_(scan_count), latest_stamp_s_(latest_stamp_s) {
  terms_.reserve(clusters_.size());
  for (PtemCluster& cluster : clusters_) {
    cluster.age_scans = scan_count_ - 1 - cluster.first_seen_scan;
    cluster.age_s = latest_stamp_s_.value_or(cluster.first_seen_stamp_s) - cluster.first_seen_stamp_s;
    const double s2 = cluster.sigma_m * cluster.sigma_m;
    terms_.push_back(Term{cluster.centre_W, 1.0 / (kTwoPi * s2), 1.0 / (2.0 * s2)});
  }
}

double PtemSnapshot::threat(const Eigen::Vector2d& p_W) const {
  // Eq 4.1 with K_i = σ_i² I: f(r) = Σ_i exp(−|r − μ_i|²/(2σ_i²)) / (2πσ_i²).
  double f = 0.0;
  for (const Term& term : terms_) f += term.peak * falloff((p_W - term.mean_W).squaredNorm() * term.inv_two_sigma_sq);
  return f;
}

PtemThreat PtemSnapshot::threat_and_gradient(const Eigen::Vector2d& p_W) const {
  // ∇ of each term of eq 4.1: −(r − μ_i)/σ_i² · f_i(r) = −2 (r − μ_i) · inv_two_sigma_sq · f_i(r).
  PtemThreat out;
  for (const Term& term : terms_) {
    const Eigen::Vector2d d = p_W - term.mean_W;
    const double f_i = term.peak * falloff(d.squaredNorm() * term.inv_two_sigma_sq);
    out.value += f_i;
    out.gradient_W -= (2.0 * term.inv_two_sigma_sq * f_i) * d;
  }
  return out;
}

bool PtemSnapshot::restricted(const Eigen::Vector2d& p_W) const {
  if (!f_r_) return false;
  // Inside any circle f >= f_r holds exactly (σ puts the cluster's own Gaussian at f_r on it, the others only add);
  // testing the circle first keeps returns that lie on it restricted despite rounding in σ.
  for (const PtemCluster& cluster : clusters_) {
    if ((p_W - cluster.centre_W).norm() <= cluster.radius_m) return true;
  }
  return threat(p_W) >= *f_r_;
}

PtemModel::PtemModel(const PtemParams& params) : params_(params) {
  params_.validate();
  if (!params_.first_cluster_sigma_m) f_r_ = params_.restricted_threshold;
  snapshot_ = make_snapshot();
}

void PtemModel::cluster_points(std::span<const Eigen::Vector2d> points_W, double stamp_s,
                               std::vector<PtemCluster>& clusters, std::vector<bool>& grown) const {
  // The clusters' circles side by side, kept in step with `clusters` below: the search for a point's nearest cluster
  // reads 24 bytes per cluster rather than a whole cluster, and mostly without a square root.
  std::vector<PtemCircle> circles;
  circles.reserve(clusters.size() + points_W.size());
  for (const PtemCluster& cluster : clusters) {
    circles.push_back({cluster.centre_W, cluster.radius_m});
  }
  // A cluster is passed over when its boundary is certainly farther than the nearest so far, by more than rounding:
  // only a strictly nearer one takes the point, so the choice is the plain search's.
  constexpr double kRoundingMargin = 1e-9;  // metres
  std::size_t previous = clusters.size();
  for (const Eigen::Vector2d& p_W : points_W) {
    // The nearest cluster boundary: |p − c| − radius (negative inside the circle).
    std::size_t nearest = clusters.size();
    double nearest_distance = std::numeric_limits<double>::infinity();
    const auto consider = [&](std::size_t i) {
      const PtemCircle& circle = circles[i];
      const double squared = (p_W - circle.centre_W).squaredNorm();
      // |p - c| - r < nearest_distance needs |p - c| < nearest_distance + r.
      const double within = nearest_distance + circle.radius_m + kRoundingMargin;
      if (within <= 0.0 || squared > within * within) return;
      const double distance = std::sqrt(squared) - circle.radius_m;
      if (distance < nearest_distance || (distance == nearest_distance && i < nearest)) {
        nearest_distance = distance;
        nearest = i;
      }
    };
    // A scan's returns come in beam order: the previous point's cluster, looked at first, is mostly the nearest, and
    // then the others are passed over after a multiply and a compare.
    if (previous < clusters.size()) consider(previous);
    for (std::size_t i = 0; i < clusters.size(); ++i) {
      if (i != previous) consider(i);
    }
    bool start_new = nearest == clusters.size() || nearest_distance > params_.cluster_distance_m;
    if (!start_new && nearest_distance > 0.0) {
      PtemCluster& cluster = clusters[nearest];
      const PtemCircle enclosing = enclose_circle_and_point(circles[nearest], p_W);
      const bool bounded = params_.max_cluster_radius_m > 0.0;
      if (bounded && enclosing.radius_m > params_.max_cluster_radius_m) {
        // Growing on would let one circle span a wall and its disc cover the floor in front of it: the wall goes on
        // as the next cluster of a chain.
        start_new = true;
      } else {
        cluster.centre_W = enclosing.centre_W;
        cluster.radius_m = enclosing.radius_m;
        circles[nearest] = enclosing;
        grown[nearest] = true;
      }
    }
    if (start_new) {
      PtemCluster cluster;
      cluster.centre_W = p_W;
      cluster.radius_m = params_.initial_cluster_radius_m;
      cluster.first_seen_scan = scan_count_;
      cluster.first_seen_stamp_s = stamp_s;
      clusters.push_back(cluster);
      circles.push_back({p_W, cluster.radius_m});
      grown.push_back(true);
      nearest = clusters.size() - 1;
    }
    add_to_extent(clusters[nearest], p_W);
    previous = nearest;
  }
}

void PtemModel::insert_scan(const PtemScan& scan) {
  validate_scan(scan, latest_stamp_s_);

  std::vector<PtemCluster> clusters;
  std::vector<bool> grown;
  if (params_.construction == PtemConstruction::kCumulative) {
    // §4.2.2: the clusters of earlier scans are kept and take part in clustering this scan's points. Moved, not
    // copied: clusters_ is replaced below, and the snapshots hold their own copies.
    clusters = std::move(clusters_);
    grown.assign(clusters.size(), false);
    cluster_points(scan.points_W, scan.stamp_s, clusters, grown);
  } else {
    // §4.2.3/§4.2.5: "All the previous information of obstacle is retained only if they fall outside the LRF limits."
    // The scan's points are clustered on their own, so kept clusters neither grow nor absorb them.
    std::vector<PtemCluster> fresh;
    std::vector<bool> fresh_grown;
    cluster_points(scan.points_W, scan.stamp_s, fresh, fresh_grown);
    // How far from the sensor a kept cluster can reach a fresh one or the sector: clusters beyond it are kept as they
    // are without the per-fresh-cluster test, so the cost of this loop follows what the scan saw, not the map's size
    // (each kept cluster is still moved into the new list: moved, not copied with its extent, as clusters_ is replaced
    // below).
    double reach_m = scan.max_range_m;
    for (const PtemCluster& f : fresh) reach_m = std::max(reach_m, (f.centre_W - scan.p_WS).norm() + f.radius_m);
    for (PtemCluster& cluster : clusters_) {
      if ((cluster.centre_W - scan.p_WS).norm() - cluster.radius_m > reach_m) {
        clusters.push_back(std::move(cluster));
        grown.push_back(false);
        continue;
      }
      // Retained unless
      //  (a) its circle lies wholly inside the scanned sector: had the obstacle still been there the scan would have
      //      made it again, so a moving obstacle leaves no trail (§4.2.4, Fig 4.2); or
      //  (b) the scan re-observed it: a cluster of this scan overlaps its circle and supersedes it.
      // Everything else "falls outside the LRF limits", wholly or in part, and is kept as last seen (§4.2.5, Fig 4.4).
      // "In part" matters because an obstacle the robot drives past leaves the field of view sideways: the edge beams
      // see it last, and the cluster they make still overlaps the sector in the next scan. Rule (b) is what keeps
      // that from piling up copies: without it, while an obstacle straddles the sector's edge each scan would make a
      // new cluster of the part inside and also keep the old one (170 clusters instead of 46 in bench_ptem's hall).
      // A cluster wholly inside the sector but hidden behind a nearer obstacle is dropped too: the sector is the
      // scan's field of view and range, not what its beams actually reached.
      const bool wholly_inside = depth_in_scanned_sector(cluster.centre_W, scan) >= cluster.radius_m;
      const bool re_observed = std::any_of(fresh.begin(), fresh.end(),
                                           [&cluster](const PtemCluster& f) { return circles_overlap(cluster, f); });
      if (!wholly_inside && !re_observed) {
        clusters.push_back(std::move(cluster));
        grown.push_back(false);
      }
    }
    clusters.insert(clusters.end(), fresh.begin(), fresh.end());
    grown.insert(grown.end(), fresh_grown.begin(), fresh_grown.end());
  }

  if (!f_r_ && !clusters.empty()) {
    // §4.3, eq 4.2: f_r is set once from the first cluster's radius r_ca and the pre-specified σ. Eq 4.2 is written
    // with the 1D factor 1/(√(2π)σ) although the text derives it from eq 4.1; the 2D factor of eq 4.1 is used here so
    // that f_r is the value the threat f itself takes on the first cluster's circle.
    const double sigma = *params_.first_cluster_sigma_m;
    const double r_ca = clusters.front().radius_m;
    f_r_ = ptem_term_density(r_ca * r_ca, sigma);
  }
  for (std::size_t i = 0; i < clusters.size(); ++i) {
    if (!grown[i]) continue;
    PtemCluster& cluster = clusters[i];
    const std::optional<double> sigma = sigma_for_radius(cluster.radius_m, *f_r_);
    // No σ puts f_r on a circle this large: take σ = R/√2, which maximises f at distance R (the limit of the W₋₁
    // branch as R reaches max_cluster_radius), and let restricted() count the whole circle.
    cluster.threshold_reachable = sigma.has_value();
    cluster.sigma_m = sigma.value_or(cluster.radius_m / std::numbers::sqrt2);
  }

  clusters_ = std::move(clusters);
  ++scan_count_;
  latest_stamp_s_ = scan.stamp_s;
  snapshot_ = make_snapshot();
}

std::shared_ptr<const PtemSnapshot> PtemModel::make_snapshot() const {
  return std::shared_ptr<const PtemSnapshot>(new PtemSnapshot(clusters_, f_r_, scan_count_, latest_stamp_s_));
}

namespace {

constexpr std::string_view kStateMagic = "OCCGEOP2";
// The layout before clusters kept their extents: read as "other parameters", so the PTEM restarts from the journal.
constexpr std::string_view kExtentlessStateMagic = "OCCGEOP1";

static_assert(std::endian::native == std::endian::little, "PTEM state is written in the host's byte order");

using geometry::fnv1a;

class StateWriter {
 public:
  template <typename T>
  void put(T value) {
    static_assert(std::is_trivially_copyable_v<T>);
    std::array<char, sizeof(T)> bytes{};
    std::memcpy(bytes.data(), &value, sizeof(T));
    out_.append(bytes.data(), bytes.size());
  }
  void put_optional(const std::optional<double>& value) {
    put<std::uint8_t>(value ? 1 : 0);
    put(value.value_or(0.0));
  }
  std::string& bytes() { return out_; }

 private:
  std::string out_;
};

class StateReader {
 public:
  explicit StateReader(std::string_view in) : in_(in) {}
  template <typename T>
  T get(const char* field) {
    if (in_.size() < sizeof(T)) throw std::invalid_argument(std::string("PTEM state is truncated at ") + field);
    T value{};
    std::memcpy(&value, in_.data(), sizeof(T));
    in_.remove_prefix(sizeof(T));
    return value;
  }
  std::optional<double> get_optional(const char* field) {
    const auto present = get<std::uint8_t>(field);
    const auto value = get<double>(field);
    if (present > 1) throw std::invalid_argument(std::string("PTEM state is damaged at ") + field);
    return present ? std::optional<double>(value) : std::nullopt;
  }
  [[nodiscard]] bool at_end() const { return in_.empty(); }

 private:
  std::string_view in_;
};

}  // namespace

std::string PtemModel::serialize() const {
  StateWriter out;
  out.bytes() += kStateMagic;
  out.put(static_cast<std::uint8_t>(params_.construction));
  out.put(params_.cluster_distance_m);
  out.put(params_.initial_cluster_radius_m);
  out.put(params_.max_cluster_radius_m);
  out.put(params_.restricted_threshold);
  out.put_optional(params_.first_cluster_sigma_m);
  out.put_optional(f_r_);
  out.put(scan_count_);
  out.put_optional(latest_stamp_s_);
  out.put(static_cast<std::uint64_t>(clusters_.size()));
  for (const PtemCluster& cluster : clusters_) {
    out.put(cluster.centre_W.x());
    out.put(cluster.centre_W.y());
    out.put(cluster.radius_m);
    out.put(cluster.sigma_m);
    out.put<std::uint8_t>(cluster.threshold_reachable ? 1 : 0);
    out.put(cluster.first_seen_scan);
    out.put(cluster.first_seen_stamp_s);
    out.put(static_cast<std::uint64_t>(cluster.extent_W.size()));
    for (const Eigen::Vector2d& p_W : cluster.extent_W) {
      out.put(p_W.x());
      out.put(p_W.y());
    }
  }
  out.put(fnv1a(out.bytes()));
  return std::move(out.bytes());
}

bool PtemModel::restore(std::string_view bytes) {
  constexpr std::size_t kChecksumBytes = sizeof(std::uint64_t);
  if (bytes.substr(0, kExtentlessStateMagic.size()) == kExtentlessStateMagic) return false;
  if (bytes.size() < kStateMagic.size() + kChecksumBytes || bytes.substr(0, kStateMagic.size()) != kStateMagic) {
    throw std::invalid_argument("PTEM state is damaged: it does not start with " + std::string(kStateMagic));
  }
  const std::string_view body = bytes.substr(0, bytes.size() - kChecksumBytes);
  std::uint64_t checksum = 0;
  std::memcpy(&checksum, bytes.data() + body.size(), kChecksumBytes);
  if (checksum != fnv1a(body)) throw std::invalid_argument("PTEM state is damaged: its checksum does not match");

  StateReader in(body.substr(kStateMagic.size()));
  PtemParams saved;
  const auto construction = in.get<std::uint8_t>("params.construction");
  saved.construction = construction == 0 ? PtemConstruction::kCumulative : PtemConstruction::kSingleScan;
  saved.cluster_distance_m = in.get<double>("params.cluster_distance_m");
  saved.initial_cluster_radius_m = in.get<double>("params.initial_cluster_radius_m");
  saved.max_cluster_radius_m = in.get<double>("params.max_cluster_radius_m");
  saved.restricted_threshold = in.get<double>("params.restricted_threshold");
  saved.first_cluster_sigma_m = in.get_optional("params.first_cluster_sigma_m");
  const auto f_r = in.get_optional("f_r");
  const auto scan_count = in.get<std::uint64_t>("scan_count");
  const auto latest_stamp_s = in.get_optional("latest_stamp_s");
  const auto count = in.get<std::uint64_t>("cluster count");
  // Every cluster takes at least 57 bytes; a count the rest cannot hold is damage, not a reason to allocate.
  if (count > body.size() / 57) throw std::invalid_argument("PTEM state is damaged: its cluster count is impossible");
  std::vector<PtemCluster> clusters(static_cast<std::size_t>(count));
  for (PtemCluster& cluster : clusters) {
    cluster.centre_W.x() = in.get<double>("clusters.centre_W");
    cluster.centre_W.y() = in.get<double>("clusters.centre_W");
    cluster.radius_m = in.get<double>("clusters.radius_m");
    cluster.sigma_m = in.get<double>("clusters.sigma_m");
    cluster.threshold_reachable = in.get<std::uint8_t>("clusters.threshold_reachable") != 0;
    cluster.first_seen_scan = in.get<std::uint64_t>("clusters.first_seen_scan");
    cluster.first_seen_stamp_s = in.get<double>("clusters.first_seen_stamp_s");
    const auto extent_count = in.get<std::uint64_t>("clusters.extent count");
    if (extent_count > body.size() / 16) {
      throw std::invalid_argument("PTEM state is damaged: an extent count is impossible");
    }
    cluster.extent_W.resize(static_cast<std::size_t>(extent_count));
    for (Eigen::Vector2d& p_W : cluster.extent_W) {
      p_W.x() = in.get<double>("clusters.extent_W");
      p_W.y() = in.get<double>("clusters.extent_W");
      if (!p_W.allFinite()) throw std::invalid_argument("PTEM state is damaged: an extent point is not finite");
    }
    if (!cluster.centre_W.allFinite() || !(cluster.radius_m > 0.0) || !(cluster.sigma_m > 0.0) ||
        cluster.first_seen_scan >= scan_count) {
      throw std::invalid_argument("PTEM state is damaged: a cluster holds impossible values");
    }
  }
  if (!in.at_end()) throw std::invalid_argument("PTEM state is damaged: bytes follow its last cluster");
  if (construction > 1) throw std::invalid_argument("PTEM state is damaged at params.construction");

  const auto same = [](const std::optional<double>& a, const std::optional<double>& b) {
    return a.has_value() == b.has_value() &&
           (!a || std::bit_cast<std::uint64_t>(*a) == std::bit_cast<std::uint64_t>(*b));
  };
  const auto same_value = [&](double a, double b) { return same(a, b); };
  if (saved.construction != params_.construction || !same_value(saved.cluster_distance_m, params_.cluster_distance_m) ||
      !same_value(saved.initial_cluster_radius_m, params_.initial_cluster_radius_m) ||
      !same_value(saved.max_cluster_radius_m, params_.max_cluster_radius_m) ||
      !same(saved.first_cluster_sigma_m, params_.first_cluster_sigma_m) ||
      (!params_.first_cluster_sigma_m && !same_value(saved.restricted_threshold, params_.restricted_threshold))) {
    return false;
  }
  clusters_ = std::move(clusters);
  f_r_ = f_r;
  scan_count_ = scan_count;
  latest_stamp_s_ = latest_stamp_s;
  snapshot_ = make_snapshot();
  return true;
}

}  // namespace occgeo::mapping
