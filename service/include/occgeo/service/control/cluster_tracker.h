#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "occgeo/mapping/ptem.h"

// Velocities of the PTEM's clusters: the clusters of each new snapshot are associated with the tracks of the previous
// ones (nearest predicted centre within a gate) and each track keeps a smoothed world-frame velocity and a "moving"
// flag, so that the control loop can predict where a person or a cart will be over the next seconds. PTEM rebuilds
// its clusters from every scan (single-scan construction), so identity across scans lives here, not in the model.

namespace occgeo::service::control {

// One tracked cluster as of the latest snapshot the tracker took.
struct TrackedObstacle {
  Eigen::Vector2d centre_W = Eigen::Vector2d::Zero();    // world frame, metres
  Eigen::Vector2d velocity_W = Eigen::Vector2d::Zero();  // smoothed, world frame, m/s
  double radius_m = 0.0;                                 // the cluster's circle, metres
  double stamp_s = 0.0;                                  // when centre_W was (last) seen, seconds
  bool moving = false;  // fast enough for enough scans in a row, and not part of a larger structure
  // Where the centre will be t_s seconds after stamp_s, assuming the velocity holds.
  [[nodiscard]] Eigen::Vector2d predicted_W(double t_s) const { return centre_W + velocity_W * t_s; }
};

struct ClusterTrackerParams {
  double gate_m = 0.6;             // a cluster continues the track whose predicted centre is nearest, within this
  double smoothing = 0.3;          // weight of the newest scan's velocity in the smoothed one, (0, 1]
  double moving_speed_mps = 0.15;  // a track is moving when its smoothed speed stays above this ...
  int moving_after_scans = 3;      // ... for this many scans in a row
  double attached_gap_m = 0.4;     // a cluster this close to another is part of a wall or shelf: never moving
  double range_margin_m = 0.5;     // a cluster this close to the laser's range limit is never moving (see .cc)
  double lost_after_s = 0.5;       // a track unseen this long is dropped ...
  // ... unless it is moving and predicted outside the laser's arc (behind a robot whose laser looks ahead): the laser
  // cannot see such a walker go on, so its prediction is kept this long, and a robot turning on the spot does not
  // swing into the person who just passed out of its view.
  double lost_out_of_view_after_s = 1.5;
  double max_speed_mps = 1.5;  // an association implying more than this starts a new track instead
  // A still thing seen from a moving robot (a pillar whose visible side turns as the robot drives by) seems to move:
  // its returns' mean shifts. A track is moving only while its returns also lie, at the median, farther than
  // surface_moved_m from its own returns of at least surface_lag_s earlier: a pillar's lie on the same surface, a
  // walker's 0.15 m/s x 0.4 s = 6 cm on. Clusters without returns skip the test.
  double surface_lag_s = 0.4;
  double surface_moved_m = 0.03;
};

// The bearings a laser sees, world frame: from heading_rad + angle_min_rad to heading_rad + angle_max_rad.
struct LaserArc {
  double heading_rad = 0.0;
  double angle_min_rad = 0.0;
  double angle_max_rad = 0.0;
};

class ClusterTracker {
 public:
  explicit ClusterTracker(const ClusterTrackerParams& params = {});

  // Takes a snapshot seen by a laser at p_WS (world frame) reaching max_range_m. A snapshot of a scan already taken
  // (same scan count) changes nothing. Only the clusters the latest scan made are observations; clusters the PTEM
  // kept from earlier scans (out of the laser's view) are not. With the laser's arc, moving tracks predicted outside it
  // coast for lost_out_of_view_after_s rather than lost_after_s.
  void update(const mapping::PtemSnapshot& snapshot, const Eigen::Vector2d& p_WS, double max_range_m,
              const std::optional<LaserArc>& arc = std::nullopt);

  // The tracks, each as last seen (centre_W at its stamp_s).
  [[nodiscard]] const std::vector<TrackedObstacle>& tracks() const { return tracks_; }
  // The tracker's whole state (tracks, their histories, the latest scan taken) as bytes, doubles bit for bit, for a
  // server's snapshot: restore() of them followed by the same snapshots gives the same tracks. Parameters are not in
  // it. restore() throws std::invalid_argument, changing nothing, for bytes serialize() did not write.
  [[nodiscard]] std::string serialize() const;
  void restore(std::string_view state);
  // Only the moving ones, each predicted to the latest snapshot's stamp (those not seen in it coast on their
  // velocity), so that predicted_W(t) is t seconds after that stamp for every one of them.
  [[nodiscard]] std::vector<TrackedObstacle> moving() const;

 private:
  struct State {
    Eigen::Vector2d mean_W =
        Eigen::Vector2d::Zero();  // mean of the cluster's returns: steadier than its circle's centre
    int fast_scans = 0;           // consecutive scans with the smoothed speed above moving_speed_mps
    int updates = 0;              // how many velocity updates the track has had
    // The track's returns of recent scans, oldest first, with their stamps: what surface_lag_s looks back to.
    std::deque<std::pair<double, std::vector<Eigen::Vector2d>>> returns_W;
  };
  ClusterTrackerParams params_;
  std::vector<TrackedObstacle> tracks_;
  std::vector<State> states_;
  std::optional<std::uint64_t> scan_count_;
  std::optional<double> stamp_s_;
};

}  // namespace occgeo::service::control
