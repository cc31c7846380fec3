#include "occgeo/service/control/cluster_tracker.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <tuple>

namespace occgeo::service::control {

namespace {

// Smallest distance between two clusters' returns (their circles when they carry none), metres.
double gap_between(const mapping::PtemCluster& a, const mapping::PtemCluster& b) {
  if (a.extent_W.empty() || b.extent_W.empty()) {
    return std::max(0.0, (a.centre_W - b.centre_W).norm() - a.radius_m - b.radius_m);
  }
  double best_sq = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector2d& p : a.extent_W) {
    for (const Eigen::Vector2d& q : b.extent_W) best_sq = std::min(best_sq, (p - q).squaredNorm());
  }
  return std::sqrt(best_sq);
}

}  // namespace

ClusterTracker::ClusterTracker(const ClusterTrackerParams& params) : params_(params) {}

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
      if (gap_between(*seen[i], *seen[j]) <= params_.attached_gap_m) may_move[i] = may_move[j] = false;
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
      const State& previous_state = states_[static_cast<std::size_t>(track_of[c])];
      const double dt_s = stamp_s - previous.stamp_s;
      track.velocity_W = previous.velocity_W;
      state = previous_state;
      if (dt_s > 1e-6) {
        const Eigen::Vector2d raw = (mean_W - previous_state.mean_W) / dt_s;
        if (raw.norm() <= params_.max_speed_mps) {
          // The first velocity is taken whole: smoothing it from zero would hide a walker for several scans.
          track.velocity_W =
              state.updates == 0 ? raw : previous.velocity_W + params_.smoothing * (raw - previous.velocity_W);
          ++state.updates;
        }
      }
    }
    state.mean_W = mean_W;
    if (!may_move[c]) {
      track.velocity_W.setZero();
      state.fast_scans = 0;
    } else if (state.updates > 0 && track.velocity_W.norm() > params_.moving_speed_mps) {
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
