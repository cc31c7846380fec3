#include "occgeo/service/control/cluster_tracker.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <tuple>
#include <type_traits>

namespace occgeo::service::control {

namespace {

// Whether two clusters' returns (their circles when they carry none) come within gap_m of each other. Returns are in
// scan order, so two neighbours on a wall meet at the end of one and the start of the other: looked at first.
bool within_gap(const mapping::PtemCluster& a, const mapping::PtemCluster& b, double gap_m) {
  if (a.extent_W.empty() || b.extent_W.empty()) {
    return (a.centre_W - b.centre_W).norm() - a.radius_m - b.radius_m <= gap_m;
  }
  const double gap_sq = gap_m * gap_m;
  for (const Eigen::Vector2d& p : {a.extent_W.front(), a.extent_W.back()}) {
    for (const Eigen::Vector2d& q : {b.extent_W.front(), b.extent_W.back()}) {
      if ((p - q).squaredNorm() <= gap_sq) return true;
    }
  }
  for (const Eigen::Vector2d& p : a.extent_W) {
    for (const Eigen::Vector2d& q : b.extent_W) {
      if ((p - q).squaredNorm() <= gap_sq) return true;
    }
  }
  return false;
}

// Median over `now` of the distance to the nearest of `before`, metres (both non-empty).
double median_nearest_m(const std::vector<Eigen::Vector2d>& now, const std::vector<Eigen::Vector2d>& before) {
  std::vector<double> nearest_sq;
  nearest_sq.reserve(now.size());
  for (const Eigen::Vector2d& p : now) {
    double best_sq = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector2d& q : before) best_sq = std::min(best_sq, (p - q).squaredNorm());
    nearest_sq.push_back(best_sq);
  }
  const auto middle = nearest_sq.begin() + static_cast<std::ptrdiff_t>(nearest_sq.size() / 2);
  std::nth_element(nearest_sq.begin(), middle, nearest_sq.end());
  return std::sqrt(*middle);
}

}  // namespace

ClusterTracker::ClusterTracker(const ClusterTrackerParams& params) : params_(params) {}

namespace {

constexpr std::string_view kStateMagic = "occgeo-cluster-tracker-1";

template <typename T>
void put(std::string& out, const T& value) {
  static_assert(std::is_trivially_copyable_v<T>);
  out.append(reinterpret_cast<const char*>(&value), sizeof(T));
}

// Reads trivially copyable values off the front of a byte string, throwing when it runs out.
struct Reader {
  std::string_view bytes;
  template <typename T>
  T get() {
    static_assert(std::is_trivially_copyable_v<T>);
    if (bytes.size() < sizeof(T)) throw std::invalid_argument("cluster tracker state: truncated");
    T value;
    std::memcpy(&value, bytes.data(), sizeof(T));
    bytes.remove_prefix(sizeof(T));
    return value;
  }
  // A count of items of item_bytes each that the remaining bytes can hold.
  std::uint64_t count(std::size_t item_bytes) {
    const auto n = get<std::uint64_t>();
    if (n > bytes.size() / item_bytes) throw std::invalid_argument("cluster tracker state: count beyond its bytes");
    return n;
  }
};

void put_point(std::string& out, const Eigen::Vector2d& p) {
  put(out, p.x());
  put(out, p.y());
}

Eigen::Vector2d get_point(Reader& in) {
  const auto x = in.get<double>();
  return {x, in.get<double>()};
}

}  // namespace

std::string ClusterTracker::serialize() const {
  std::string out(kStateMagic);
  put<std::uint8_t>(out, scan_count_ ? 1 : 0);
  put<std::uint64_t>(out, scan_count_.value_or(0));
  put<std::uint8_t>(out, stamp_s_ ? 1 : 0);
  put<double>(out, stamp_s_.value_or(0.0));
  put<std::uint64_t>(out, tracks_.size());
  for (std::size_t t = 0; t < tracks_.size(); ++t) {
    const TrackedObstacle& track = tracks_[t];
    const State& state = states_[t];
    put_point(out, track.centre_W);
    put_point(out, track.velocity_W);
    put(out, track.radius_m);
    put(out, track.stamp_s);
    put<std::uint8_t>(out, track.moving ? 1 : 0);
    put_point(out, state.mean_W);
    put<std::int32_t>(out, state.fast_scans);
    put<std::int32_t>(out, state.updates);
    put<std::uint64_t>(out, state.returns_W.size());
    for (const auto& [stamp_s, returns_W] : state.returns_W) {
      put(out, stamp_s);
      put<std::uint64_t>(out, returns_W.size());
      for (const Eigen::Vector2d& p : returns_W) put_point(out, p);
    }
  }
  return out;
}

void ClusterTracker::restore(std::string_view state) {
  if (!state.starts_with(kStateMagic)) throw std::invalid_argument("cluster tracker state: not written by serialize");
  Reader in{state.substr(kStateMagic.size())};
  std::optional<std::uint64_t> scan_count;
  if (in.get<std::uint8_t>() != 0)
    scan_count = in.get<std::uint64_t>();
  else
    in.get<std::uint64_t>();
  std::optional<double> stamp_s;
  if (in.get<std::uint8_t>() != 0)
    stamp_s = in.get<double>();
  else
    in.get<double>();
  std::vector<TrackedObstacle> tracks;
  std::vector<State> states;
  const std::uint64_t n = in.count(1);
  for (std::uint64_t t = 0; t < n; ++t) {
    TrackedObstacle track;
    track.centre_W = get_point(in);
    track.velocity_W = get_point(in);
    track.radius_m = in.get<double>();
    track.stamp_s = in.get<double>();
    track.moving = in.get<std::uint8_t>() != 0;
    State s;
    s.mean_W = get_point(in);
    s.fast_scans = in.get<std::int32_t>();
    s.updates = in.get<std::int32_t>();
    const std::uint64_t entries = in.count(1);
    for (std::uint64_t e = 0; e < entries; ++e) {
      const auto then_s = in.get<double>();
      std::vector<Eigen::Vector2d> returns_W(in.count(2 * sizeof(double)));
      for (Eigen::Vector2d& p : returns_W) p = get_point(in);
      s.returns_W.emplace_back(then_s, std::move(returns_W));
    }
    tracks.push_back(track);
    states.push_back(std::move(s));
  }
  if (!in.bytes.empty()) throw std::invalid_argument("cluster tracker state: bytes after the last track");
  tracks_ = std::move(tracks);
  states_ = std::move(states);
  scan_count_ = scan_count;
  stamp_s_ = stamp_s;
}

std::vector<TrackedObstacle> ClusterTracker::moving() const {
  std::vector<TrackedObstacle> out;
  for (const TrackedObstacle& track : tracks_) {
    if (!track.moving) continue;
    TrackedObstacle now = track;
    if (stamp_s_) {
      now.centre_W = track.predicted_W(*stamp_s_ - track.stamp_s);
      now.stamp_s = *stamp_s_;
    }
    out.push_back(now);
  }
  return out;
}

void ClusterTracker::update(const mapping::PtemSnapshot& snapshot, const Eigen::Vector2d& p_WS, double max_range_m,
                            const std::optional<LaserArc>& arc) {
  if (scan_count_ && *scan_count_ == snapshot.scan_count()) return;
  scan_count_ = snapshot.scan_count();
  const double stamp_s = snapshot.latest_stamp_s().value_or(stamp_s_.value_or(0.0));

  // The latest scan's clusters, and whether each may be a free-standing moving thing at all.
  std::vector<const mapping::PtemCluster*> seen;
  for (const mapping::PtemCluster& cluster : snapshot.clusters()) {
    if (cluster.age_scans == 0) seen.push_back(&cluster);
  }
  std::vector<bool> may_move(seen.size(), true);
  for (std::size_t i = 0; i < seen.size(); ++i) {
    // A wall becomes a chain of bounded clusters whose boundaries shift with the viewpoint: any cluster touching
    // another belongs to such a structure. The same goes for a wall's end at the laser's range limit, which advances
    // with the robot.
    const double reach_m = (seen[i]->centre_W - p_WS).norm() + seen[i]->radius_m;
    if (reach_m > max_range_m - params_.range_margin_m) may_move[i] = false;
    for (std::size_t j = i + 1; j < seen.size(); ++j) {
      const double centre_gap_m =
          (seen[i]->centre_W - seen[j]->centre_W).norm() - seen[i]->radius_m - seen[j]->radius_m;
      if (centre_gap_m > params_.attached_gap_m) continue;
      if (within_gap(*seen[i], *seen[j], params_.attached_gap_m)) may_move[i] = may_move[j] = false;
    }
  }

  // Greedy one-to-one association, nearest pairs first, against each track's centre predicted to this stamp.
  std::vector<std::tuple<double, std::size_t, std::size_t>> pairs;  // distance, track, cluster
  for (std::size_t t = 0; t < tracks_.size(); ++t) {
    const Eigen::Vector2d predicted = tracks_[t].predicted_W(stamp_s - tracks_[t].stamp_s);
    for (std::size_t c = 0; c < seen.size(); ++c) {
      const double d = (seen[c]->centre_W - predicted).norm();
      if (d <= params_.gate_m) pairs.emplace_back(d, t, c);
    }
  }
  std::sort(pairs.begin(), pairs.end());
  std::vector<int> track_of(seen.size(), -1);
  std::vector<bool> track_taken(tracks_.size(), false);
  for (const auto& [d, t, c] : pairs) {
    if (track_taken[t] || track_of[c] >= 0) continue;
    track_taken[t] = true;
    track_of[c] = static_cast<int>(t);
  }

  std::vector<TrackedObstacle> next;
  std::vector<State> next_states;
  for (std::size_t c = 0; c < seen.size(); ++c) {
    TrackedObstacle track;
    track.centre_W = seen[c]->centre_W;
    track.radius_m = seen[c]->radius_m;
    track.stamp_s = stamp_s;
    State state;
    Eigen::Vector2d mean_W = seen[c]->centre_W;
    if (!seen[c]->extent_W.empty()) {
      mean_W.setZero();
      for (const Eigen::Vector2d& p : seen[c]->extent_W) mean_W += p;
      mean_W /= static_cast<double>(seen[c]->extent_W.size());
    }
    if (track_of[c] >= 0) {
      const TrackedObstacle& previous = tracks_[static_cast<std::size_t>(track_of[c])];
      // Each track continues in at most one cluster: its state moves on.
      State& previous_state = states_[static_cast<std::size_t>(track_of[c])];
      const double dt_s = stamp_s - previous.stamp_s;
      track.velocity_W = previous.velocity_W;
      state = std::move(previous_state);
      if (dt_s > 1e-6) {
        const Eigen::Vector2d raw = (mean_W - state.mean_W) / dt_s;
        if (raw.norm() <= params_.max_speed_mps) {
          // The first velocity is taken whole: smoothing it from zero would hide a walker for several scans.
          track.velocity_W =
              state.updates == 0 ? raw : previous.velocity_W + params_.smoothing * (raw - previous.velocity_W);
          ++state.updates;
        }
      }
    }
    state.mean_W = mean_W;
    // A fast track must also show its returns moved on from where they lay surface_lag_s or more ago (the latest such
    // returns); only fast ones are tested, as the test costs a nearest-neighbour search per return.
    const bool fast = may_move[c] && state.updates > 0 && track.velocity_W.norm() > params_.moving_speed_mps;
    bool surface_moved = true;
    if (!seen[c]->extent_W.empty()) {
      if (fast) {
        const std::vector<Eigen::Vector2d>* before = nullptr;
        for (const auto& [then_s, returns_W] : state.returns_W) {
          if (stamp_s - then_s >= params_.surface_lag_s) before = &returns_W;
        }
        surface_moved = before != nullptr && median_nearest_m(seen[c]->extent_W, *before) > params_.surface_moved_m;
      }
      // Keep what the next scans look back to: the latest entry at least the lag old, and the newer ones.
      while (state.returns_W.size() > 1 && stamp_s - state.returns_W[1].first >= params_.surface_lag_s) {
        state.returns_W.pop_front();
      }
      state.returns_W.emplace_back(stamp_s, seen[c]->extent_W);
    }
    if (!may_move[c]) {
      track.velocity_W.setZero();
      state.fast_scans = 0;
    } else if (fast && surface_moved) {
      ++state.fast_scans;
    } else {
      state.fast_scans = 0;
    }
    track.moving = state.fast_scans >= params_.moving_after_scans;
    next.push_back(track);
    next_states.push_back(state);
  }
  // A moving track not seen in this scan (occluded, or out of view for a moment) coasts until lost_after_s, or
  // lost_out_of_view_after_s while predicted where the laser does not look; a still one is just gone (a wall's
  // fragments come and go with the occlusions in front of it).
  const auto out_of_view = [&](const Eigen::Vector2d& p_W) {
    if (!arc) return false;
    const Eigen::Vector2d d_W = p_W - p_WS;
    const double bearing = std::remainder(std::atan2(d_W.y(), d_W.x()) - arc->heading_rad, 2.0 * std::numbers::pi);
    return bearing < arc->angle_min_rad || bearing > arc->angle_max_rad;
  };
  for (std::size_t t = 0; t < tracks_.size(); ++t) {
    if (track_taken[t] || !tracks_[t].moving) continue;
    const double unseen_s = stamp_s - tracks_[t].stamp_s;
    const double lost_after_s =
        out_of_view(tracks_[t].predicted_W(unseen_s)) ? params_.lost_out_of_view_after_s : params_.lost_after_s;
    if (unseen_s > lost_after_s) continue;
    next.push_back(tracks_[t]);
    next_states.push_back(states_[t]);
  }
  tracks_ = std::move(next);
  states_ = std::move(next_states);
  stamp_s_ = stamp_s;
}

}  // namespace occgeo::service::control
