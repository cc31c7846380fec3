#pragma once

#include <array>
#include <atomic>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "metrics.h"
#include "occgeo/geometry/dead_reckoning.h"
#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/kinematics.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/mapping/beam_limits.h"
#include "occgeo/mapping/distance_field.h"
#include "occgeo/mapping/himm_grid.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/mapping/ptem.h"
#include "occgeo/service/config.h"
#include "occgeo/service/control/bearcat.h"
#include "occgeo/service/control/behaviour.h"
#include "occgeo/service/control/cluster_tracker.h"
#include "occgeo/v1/control.pb.h"
#include "occgeo/v1/robot.pb.h"
#include "octree_band_field.h"

namespace occgeo::service::durability {
class WorldJournal;
}

namespace occgeo::service {

namespace asio = boost::asio;
using IngestStrand = asio::strand<asio::thread_pool::executor_type>;
// One sensor message's change to a world's octree, applied where the octree lives (see World).
using OctreeWork = std::function<void(mapping::OctoMapModel& octomap)>;

// The models of a world as one publication made them: a reader holding it sees the grid, its
// distance field and the PTEM after the same sensor message. The OctoMap snapshot is published at
// most every octomap.min_publish_interval_s (deep copies cost O(nodes)), so it may lag the others
// by that long; its own version() says which insertions it holds.
struct WorldSnapshot {
  std::shared_ptr<const mapping::GridSnapshot> grid;
  std::shared_ptr<const mapping::PtemSnapshot> ptem;
  // The clusters of ptem's latest scans that the lasers' trackers follow as moving (World::moving_clusters_on_strand):
  // the people and carts whose returns the grid and the octree do not keep, and the guard checks instead.
  std::shared_ptr<const std::vector<control::TrackedObstacle>> moving;
  std::shared_ptr<const mapping::DistanceFieldSnapshot> distance;  // matches grid (same version)
  std::shared_ptr<const mapping::OctoMapSnapshot> octomap;
  // The octree's clearance fields (one per footprint height asked for), of octomap's version; where a query's height
  // has none it asks octree_band_requests for one and walks the octree meanwhile.
  std::shared_ptr<const std::vector<OctreeBandSnapshot>> octree_bands;
  std::shared_ptr<OctreeBandRequests> octree_band_requests;
};

// Heap bytes a world's models take, counted from their latest snapshots (see each snapshot's memory_bytes). The
// terrain has no entry: it is estimated from the octree snapshot per query and kept by nobody in between.
struct WorldMemory {
  std::uint64_t grid_bytes = 0;
  std::uint64_t distance_field_bytes = 0;
  std::uint64_t octomap_bytes = 0;
  std::uint64_t ptem_bytes = 0;
};

// The process's resident memory (/proc/self/statm), bytes; nullopt where it cannot be read.
std::optional<std::uint64_t> process_resident_bytes();

// Adds `nice` to the calling thread's niceness (Linux: a thread's niceness is its own; raising it needs no privilege),
// at most to 19; logs `warning` when it cannot.
void lower_this_threads_priority(int nice, const char* warning);

// Puts the calling thread under SCHED_FIFO at `priority` (1-99; 0 does nothing), so that no thread of the normal
// policy (queries, a co-located load generator, the octree's lane) holds it off a core for a time slice; logs
// `warning` when it cannot (no CAP_SYS_NICE).
void make_this_thread_realtime(int priority, const char* warning);

// The models a world keeps, and their parameters.
struct WorldParams {
  mapping::PtemParams ptem;
  mapping::OctoMapParams octomap;
  mapping::DistanceFieldParams distance_field;
  std::uint32_t octomap_publish_every_messages = 0;  // > 0: publish the octree every N-th message, not on a timer
};

// One world: the HIMM grid and the 3D OctoMap all its robots' sensors update, the distance field
// kept in step with the grid, and the PTEM (seed 004 §4) its robots' laser scans build. All are
// only touched on the world's ingest strand; readers take the latest published immutable
// snapshots.
//
// The octree costs far more per scan than the other models (milliseconds against tens of microseconds), so when it is
// published on a timer (octomap.min_publish_interval_s > 0) it lives on its own lane, a strand on another thread:
// the ingest strand hands each message's octree work over and goes on to compute the robot's command. Readers already
// see the octree up to that interval stale, so the robots lose nothing they had. With the octree published every
// message or every N messages (lockstep runs that must repeat exactly), the work runs inline on the ingest strand.
class World : public std::enable_shared_from_this<World> {
 public:
  // octree_lane: where the octree's work runs when it is published on a timer; nullopt keeps it on `strand`.
  // publish_lane: where the distance field is updated and publications are made, with an octree lane (see
  // publish_staged_on_strand); nullopt, or no octree lane, keeps them on `strand`.
  World(std::string name, mapping::HimmGrid grid, const WorldParams& params, IngestStrand strand,
        std::optional<IngestStrand> octree_lane = std::nullopt,
        std::optional<IngestStrand> publish_lane = std::nullopt);

  [[nodiscard]] const std::string& name() const { return name_; }
  [[nodiscard]] IngestStrand& strand() { return strand_; }
  // The mutable grid; call only from the world's strand.
  mapping::HimmGrid& grid_on_strand() { return grid_; }
  // Adds one laser scan to the PTEM; call only from the world's strand. Every laser of every robot
  // in the world feeds the one model, so a stamp older than the model's latest (another robot's
  // clock) is taken as the latest: cluster ages never run backwards. Throws std::invalid_argument
  // (naming the field) for a scan the model refuses, changing nothing.
  void insert_ptem_on_strand(mapping::PtemScan scan);
  // The PTEM's parameters (fixed when the world is made); safe from any thread.
  [[nodiscard]] const mapping::PtemParams& ptem_params() const { return ptem_params_; }
  // The PTEM model's whole state, for a snapshot (mapping::PtemModel::serialize); call only from the world's strand.
  [[nodiscard]] std::string serialize_ptem_on_strand() const { return ptem_.serialize(); }
  // Replaces the PTEM by a snapshot's state (mapping::PtemModel::restore: false when it was written under other
  // parameters, throws when damaged); call only before any work reaches the strand.
  bool restore_ptem_on_strand(std::string_view state);
  [[nodiscard]] std::uint64_t ptem_scan_count_on_strand() const { return ptem_.scan_count(); }
  // The clusters of the PTEM's latest scan that continue a moving track (control::ClusterTracker) of the laser that
  // took it: `sensor` names the laser (robot and laser), which saw `arc` from p_WS out to max_range_m. Those are people
  // and carts going by, whose returns insert_laser_scan does not map as matter, so that they leave no trail in the
  // grid or the octree. Call from the strand right after insert_ptem_on_strand of that laser's scan. Each laser has
  // its own tracker, kept for the world's life and in its snapshots (serialize_trackers_on_strand), so that a world
  // restored from a snapshot and its journal flags the same returns as ingest did.
  // The trackers' state for a snapshot (control::ClusterTracker::serialize, per laser), and back; on the strand
  // (restore: before any work reaches it). restore throws std::invalid_argument, changing nothing, for damaged bytes.
  [[nodiscard]] std::string serialize_trackers_on_strand() const;
  void restore_trackers_on_strand(std::string_view state);
  std::vector<control::TrackedObstacle> moving_clusters_on_strand(const std::string& sensor,
                                                                  const Eigen::Vector2d& p_WS, double max_range_m,
                                                                  const control::LaserArc& arc);
  // The octree's parameters (fixed when the world is made); safe from any thread.
  [[nodiscard]] const mapping::OctoMapParams& octomap_params() const { return octomap_params_; }
  // Applies one sensor message's octree work (possibly none) in order after every earlier message's, and publishes the
  // octree under the octomap.* rules: on the octree lane when the world has one (returning at once, unless the lane
  // is kOctreeBacklogMessages behind, when it waits, so that a lane that cannot keep up slows ingest rather than
  // growing without bound), inline otherwise. Call only from the world's strand (or before any work reaches it).
  void apply_octree_work_on_strand(std::vector<OctreeWork> work);
  // Runs fn on the octree once all octree work handed over before has been applied, and returns when it has run.
  // Call only from the world's strand (or before any work reaches it), never from the octree lane.
  void with_octree_on_strand(const std::function<void(mapping::OctoMapModel& octomap)>& fn);
  // Makes the grid's and the PTEM's current state visible to readers, together, after bringing the
  // distance field in step with the grid: the grid's log of flipped cells says which cells to
  // compare; when it overflowed, those inside `touched` (it must hold every cell whose occupancy may
  // have flipped since the last publication; nullopt compares the whole grid). The OctoMap is published too when its
  // last snapshot is older than octomap.min_publish_interval_s; otherwise a timer on the strand publishes it when that
  // interval has passed, so readers never see it lag by more. With a publish lane all of this but the octree happens
  // there, after the call returns (see stage_on_strand). Call only from the world's strand.
  void publish_on_strand(std::optional<mapping::CellBox> touched = std::nullopt);
  // publish_on_strand in two steps, for a scan that steers its robot: stage_on_strand takes the grid's and the PTEM's
  // snapshots, which snapshots_on_strand then gives the robot's command, and publish_staged_on_strand, after the
  // command went out, brings the distance field in step and makes grid, PTEM and field visible to readers together.
  // A flipped cell costs the field a wavefront out to max_distance_m (about a millisecond in the open at 0.1 m cells)
  // and no command reads the field, so with a publish lane that step runs there, in publication order, and the strand
  // goes on to the next message (another robot's scan) at once. Both only from the world's strand;
  // publish_staged_on_strand does nothing when nothing is staged.
  void stage_on_strand(std::optional<mapping::CellBox> touched = std::nullopt);
  void publish_staged_on_strand();
  // Runs reply once every publication staged before has been made (on the publish lane, or here without one): a
  // driver's acks and rejections go through it, so an ack means its message is in the published models and replies
  // keep the messages' order. Call only from the world's strand.
  void after_publications_on_strand(std::function<void()> reply);
  // Returns once every publication staged before has been made, e.g. before a restored world takes connections. Call
  // only from the world's strand (or before any work reaches it), never from the publish lane.
  void wait_for_publications_on_strand();
  // The models as the strand has them: the grid and PTEM of the latest message staged or published, with the latest
  // published octree and field. Call only from the world's strand.
  [[nodiscard]] WorldSnapshot snapshots_on_strand() const;
  // Publishes the OctoMap now, with all octree work handed over before (e.g. before an export); call only from the
  // world's strand.
  std::shared_ptr<const mapping::OctoMapSnapshot> publish_octomap_on_strand();
  // Once the octree and publish pools have been joined (ServerCore::drain), the octree's work and the publications
  // run on the caller, e.g. the final snapshot at shutdown. Call only when no thread uses the world's strands.
  void retire_lanes() {
    octree_lane_.reset();
    publish_lane_.reset();
  }
  // True when the octree's work runs on a lane of its own (published on a timer); false when it runs on the strand,
  // inline and in step with the grid (octomap_publish_every_messages, as lockstep runs and tests use).
  [[nodiscard]] bool octree_has_lane() const { return octree_lane_.has_value(); }
  // How many messages' octree work the lane may hold before the ingest strand waits for it.
  static constexpr int kOctreeBacklogMessages = 32;
  // How many publications the publish lane may hold before the ingest strand waits for it.
  static constexpr int kPublishBacklogMessages = 32;
  // Publications made (grid, field and PTEM together), and messages that went out in a later message's publication
  // because the publish lane had not caught up with them; safe from any thread.
  [[nodiscard]] std::uint64_t publications() const { return publications_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t merged_publications() const {
    return merged_publications_.load(std::memory_order_relaxed);
  }
  // What the models take as of their latest snapshots; safe from any thread, costs a walk over the snapshots' tiles
  // and blocks (not their cells).
  [[nodiscard]] WorldMemory memory() const;
  // The latest published state of the grid; safe from any thread.
  [[nodiscard]] std::shared_ptr<const mapping::GridSnapshot> snapshot() const;
  // The journal every accepted sensor message is written to before it is applied (see durability/journal.h); set
  // before any work reaches the strand, then used from the strand.
  [[nodiscard]] durability::WorldJournal* journal() const { return journal_.get(); }
  void attach_journal(std::shared_ptr<durability::WorldJournal> journal) { journal_ = std::move(journal); }
  // The latest published grid and PTEM, from the same publication; safe from any thread.
  [[nodiscard]] WorldSnapshot snapshots() const;
  // The same for a network thread answering many queries: when nothing was published since this thread's last call,
  // no lock is taken and no reference count touched (both are shared by every thread). The reference is valid until
  // this thread calls it again.
  [[nodiscard]] const WorldSnapshot& snapshots_for_this_thread() const;

 private:
  std::string name_;
  mapping::HimmGrid grid_;
  mapping::PtemParams ptem_params_;
  mapping::PtemModel ptem_;
  std::optional<double> ptem_latest_stamp_s_;
  std::map<std::string, control::ClusterTracker, std::less<>> ptem_trackers_;  // by laser; only on the strand
  // Each laser's moving clusters of its latest scan, and all of them fresh enough as one list for the next
  // publication (WorldSnapshot::moving); only on the strand.
  std::map<std::string, std::vector<control::TrackedObstacle>, std::less<>> moving_by_sensor_;
  std::shared_ptr<const std::vector<control::TrackedObstacle>> moving_now_ =
      std::make_shared<const std::vector<control::TrackedObstacle>>();
  mapping::OctoMapParams octomap_params_;
  mapping::OctoMapModel octomap_;
  mapping::DistanceField distance_field_;
  mapping::DistanceFieldParams distance_field_params_;  // also the octree band fields'
  IngestStrand strand_;
  std::optional<IngestStrand> octree_lane_;   // set when the octree's work runs off the ingest strand
  std::optional<IngestStrand> publish_lane_;  // set with an octree lane: the field's updates and the publications
  std::atomic<int> publish_backlog_{0};       // publications handed to the publish lane and not yet made
  std::atomic<int> octree_backlog_{0};        // messages handed to the lane and not yet applied
  asio::steady_timer octomap_timer_;          // on the octree lane when there is one
  bool octomap_timer_armed_ = false;
  std::uint32_t octomap_publish_every_messages_ = 0;
  std::uint32_t messages_since_octomap_ = 0;
  // Where the octree's work and publishing run: the lane or the ingest strand. Both only from there.
  void apply_octree_work_here(const std::vector<OctreeWork>& work);
  void publish_octomap_here();
  // Brings the octree's clearance fields to octomap (making those queries asked for, kMaxOctreeBands at most) and
  // swaps both in for readers: every octree publish ends here.
  void store_octomap_snapshot_here(std::shared_ptr<const mapping::OctoMapSnapshot> octomap);
  static constexpr std::size_t kMaxOctreeBands = 4;
  std::vector<std::unique_ptr<OctreeBandField>> octree_bands_;
  std::shared_ptr<OctreeBandRequests> octree_band_requests_ = std::make_shared<OctreeBandRequests>();
  // What stage_on_strand took, until publish_staged_on_strand hands it on; only on the strand.
  struct StagedPublication {
    std::shared_ptr<const mapping::GridSnapshot> grid;
    std::shared_ptr<const mapping::PtemSnapshot> ptem;
    std::shared_ptr<const std::vector<control::TrackedObstacle>> moving;
    std::optional<std::vector<geometry::CellIndex>> changed;  // the grid's flipped cells; nullopt: the log overflowed
    std::optional<mapping::CellBox> touched;
  };
  std::optional<StagedPublication> staged_;
  // The publication handed to the publish lane and not yet taken by it, into which later ones merge.
  std::mutex pending_publication_mutex_;
  std::optional<StagedPublication> pending_publication_;
  std::atomic<std::uint64_t> publications_{0};         // grid, field and PTEM published together
  std::atomic<std::uint64_t> merged_publications_{0};  // messages published with a later one's publication
  // Makes `into` the publication of both: the later models, the flipped cells and touched areas of both.
  static void merge_publications(StagedPublication& into, StagedPublication&& later);
  // The grid and PTEM of the latest message staged, for snapshots_on_strand; only on the strand.
  std::shared_ptr<const mapping::GridSnapshot> latest_grid_on_strand_;
  std::shared_ptr<const mapping::PtemSnapshot> latest_ptem_on_strand_;
  std::shared_ptr<const std::vector<control::TrackedObstacle>> latest_moving_on_strand_;
  // Brings the distance field in step with `staged` and publishes it; on the publish lane, or the strand without one.
  void publish_here(StagedPublication& staged);
  mutable std::mutex snapshot_mutex_;  // held only to copy or swap the two pointers
  WorldSnapshot snapshot_;
  // Changes with every change of snapshot_, unique across worlds (see snapshots_for_this_thread).
  std::atomic<std::uint64_t> snapshot_generation_{0};
  std::shared_ptr<durability::WorldJournal> journal_;
};

// A planar laser as declared in a RobotSpec, converted to SI geometry types.
struct LaserModel {
  std::string name;
  geometry::Pose3 X_BS;  // sensor in base_link
  double angle_min_rad = 0.0;
  double angle_increment_rad = 0.0;
  std::uint32_t beam_count = 0;
  double range_min_m = 0.0;
  double range_max_m = 0.0;
  mapping::BeamLimits beam_limits;  // what its readings change: the spec's ranges over the server's defaults
};

// A ring or array of single-beam range sensors (sonar, infrared) as declared in a RobotSpec.
struct RangeArrayModel {
  std::string name;
  geometry::Pose3 X_BS;               // sensor in base_link
  std::vector<geometry::Pose2> X_SE;  // each element in the sensor frame; it measures along its own x axis
  double beam_width_rad = 0.0;
  double range_min_m = 0.0;
  double range_max_m = 0.0;
  mapping::BeamLimits beam_limits;  // what its readings change: the spec's ranges over the server's defaults
  double period_s = 0.0;
};

// A single-beam rangefinder turned by a servo about the sensor frame's z axis.
struct ServoRangeModel {
  std::string name;
  geometry::Pose3 X_BS;  // sensor in base_link; the beam is its x axis rotated by the servo angle
  double servo_min_rad = 0.0;
  double servo_max_rad = 0.0;
  double servo_step_rad = 0.0;
  double step_period_s = 0.0;
  double range_min_m = 0.0;
  double range_max_m = 0.0;
  mapping::BeamLimits beam_limits;  // what its readings change: the spec's ranges over the server's defaults
};

// A 3D point sensor (depth camera, 3D lidar).
struct PointCloudModel {
  std::string name;
  geometry::Pose3 X_BS;  // sensor in base_link
  double range_max_m = 0.0;
  std::size_t max_points = 0;       // the spec's limit, or the server's when the spec leaves it 0
  mapping::BeamLimits beam_limits;  // what its points change: the spec's ranges over the server's defaults
};

// How the robot's wheels or tracks move it; decides what a motion command's wheel speeds mean.
using DriveModel = std::variant<geometry::DifferentialDriveParams, geometry::SkidSteerParams>;

// What a robot is: fixed once its driver has sent the RobotSpec.
struct RobotModel {
  std::string id;
  std::string model;
  geometry::Footprint footprint;
  DriveModel drive;
  std::vector<LaserModel> lasers;
  std::vector<RangeArrayModel> range_arrays;
  std::vector<ServoRangeModel> servo_ranges;
  std::vector<PointCloudModel> point_clouds;
  // Set when the spec declares wheel encoders: the server then dead-reckons the pose from
  // WheelEncoders messages, starting at initial_pose.
  std::optional<geometry::EncoderParams> encoders;
  geometry::Pose2 initial_pose;
  v1::RobotSpec spec;

  [[nodiscard]] const LaserModel* find_laser(const std::string& name) const;
  [[nodiscard]] const RangeArrayModel* find_range_array(const std::string& name) const;
  [[nodiscard]] const ServoRangeModel* find_servo_range(const std::string& name) const;
  [[nodiscard]] const PointCloudModel* find_point_cloud(const std::string& name) const;
  // True when any sensor of any kind has this name.
  [[nodiscard]] bool has_sensor(const std::string& name) const;
};

// The Bearcat behaviour's parameters for one robot: the configured ones (section `bearcat:`), with the wheel (or
// track) separation the robot's own drive declares, which turns the behaviour's wheel speeds into its body velocity.
control::BearcatParams bearcat_params_for(const RobotModel& model, control::BearcatParams configured);

class SessionContext;

// Which controller session holds a robot's lease, and until when.
struct Lease {
  std::uint64_t session_id = 0;
  std::string client_name;
  double timeout_s = 0.0;
  std::chrono::steady_clock::time_point expires_at;
};

// Who drives a robot and how: the lease, the behaviour its holder set, the e-stop latch and the
// watchdogs' view. One RobotControl is kept per robot id across driver reconnections (a new Robot
// object takes over its predecessor's), so a lease and a latched e-stop survive a reconnecting
// driver. Guarded by its own mutex; read and changed from the network thread (lease, drive, e-stop
// requests) and the world's strand (commands, watchdogs).
struct ControlState {
  std::optional<Lease> lease;
  // control.initial_behaviour (or the robot spec's default) while no controller set one
  v1::Behaviour behaviour = v1::BEHAVIOUR_BEARCAT;
  v1::DriveRequest drive;              // the holder's last accepted request: goal, waypoints, escape
  std::uint64_t drive_generation = 0;  // counts accepted DriveRequests: the strand rebuilds the behaviour on change
  double teleop_linear_mps = 0.0;      // teleop: the holder's velocities, already clamped to the robot's limits
  double teleop_angular_radps = 0.0;
  bool estop = false;         // latched: every command is a stop until the lease holder releases it
  bool sensor_stale = false;  // the sensor watchdog stopped the robot; cleared by the next sensor message
  std::optional<std::chrono::steady_clock::time_point> last_sensor_at;  // of the connected driver
  std::weak_ptr<SessionContext> driver;  // the connected driver's session, for unsolicited stop commands
};

class RobotControl {
 public:
  [[nodiscard]] ControlState state() const {
    const std::lock_guard lock(mutex_);
    return state_;
  }
  template <typename Update>
  auto update(Update&& update) {
    const std::lock_guard lock(mutex_);
    return update(state_);
  }

 private:
  mutable std::mutex mutex_;
  ControlState state_;
};

// What a robot is doing: updated by its world's strand, read by status queries.
struct RobotState {
  bool connected = false;
  std::optional<geometry::Pose2> X_WB;  // from the latest accepted odometry or wheel encoders
  std::optional<double> last_odometry_stamp_s;
  std::optional<double> last_encoder_stamp_s;
  std::optional<std::uint64_t> last_encoder_seq;
  // Shared by every sensor message (laser scan, range array, servo range, point cloud): one
  // increasing seq and non-decreasing stamp per robot across all of them.
  std::optional<double> last_scan_stamp_s;
  std::optional<std::uint64_t> last_scan_seq;
  std::uint64_t scans_ingested = 0;  // sensor messages of every kind
  std::uint64_t scans_rejected = 0;
  std::uint64_t commands_sent = 0;
  v1::Behaviour behaviour = v1::BEHAVIOUR_BEARCAT;
  v1::BehaviourState behaviour_state = v1::BEHAVIOUR_STATE_UNSPECIFIED;
  double last_linear_mps = 0.0;
  double last_angular_radps = 0.0;
  v1::GuardDecision guard;  // the safety guard's verdict on the latest command
  // The active behaviour's planned path, world frame; null without one. Shared, as scan_W, so that copying the state
  // (every sensor message, every status) never copies a path.
  std::shared_ptr<const std::vector<Eigen::Vector2d>> path_W;
  // The first laser's latest accepted returns, world frame; shared so that copying the state stays cheap.
  std::shared_ptr<const std::vector<Eigen::Vector2f>> scan_W;
  std::optional<double> scan_stamp_s;  // stamp of the scan in scan_W

  // The planned path (empty without one).
  [[nodiscard]] const std::vector<Eigen::Vector2d>& path() const {
    static const std::vector<Eigen::Vector2d> kNone;
    return path_W ? *path_W : kNone;
  }
};

// A robot's own counters in its server's registry, found once when it registers (a lookup takes the registry's mutex).
struct RobotCounters {
  metrics::Counter& scans_rejected;
  metrics::Counter& scans_duplicate;
  metrics::Counter& guard_interventions;
};
[[nodiscard]] RobotCounters robot_counters(metrics::Registry& registry, const std::string& robot_id);

class Robot : public std::enable_shared_from_this<Robot> {
 public:
  Robot(std::shared_ptr<const RobotModel> model, std::shared_ptr<World> world, control::BearcatParams bearcat,
        RobotCounters counters, std::shared_ptr<RobotControl> control = nullptr);

  [[nodiscard]] const RobotModel& model() const { return *model_; }
  [[nodiscard]] std::shared_ptr<const RobotModel> model_ptr() const { return model_; }
  [[nodiscard]] World& world() const { return *world_; }
  [[nodiscard]] std::shared_ptr<World> world_ptr() const { return world_; }
  [[nodiscard]] const RobotCounters& counters() const { return counters_; }
  // occgeo_scans_ingested_total of this robot, its world and one sensor message kind ("laser_scan", "range_array",
  // "servo_range", "point_cloud"): found in the registry at the kind's first message, then kept, so that the
  // per-message path takes no lock. Call only from the world's strand.
  metrics::Counter& ingested_counter_on_strand(metrics::Registry& registry, std::string_view kind);
  // The obstacle-avoidance behaviour; used only from the world's strand.
  control::BearcatBehaviour& behaviour_on_strand() { return behaviour_; }
  // Dead reckoning from wheel ticks, present when the spec declares encoders; used only from the
  // world's strand.
  std::optional<geometry::EncoderOdometry>& encoder_odometry_on_strand() { return encoder_odometry_; }
  // The behaviour a DriveRequest set (wander, goto, ...) and the drive_generation it was built for; used only from
  // the world's strand.
  std::unique_ptr<control::Behaviour>& active_behaviour_on_strand() { return active_behaviour_; }
  std::uint64_t& active_generation_on_strand() { return active_generation_; }

  [[nodiscard]] RobotState state() const;
  template <typename Update>
  void update_state(Update&& update) {
    const std::lock_guard lock(mutex_);
    update(state_);
  }

  // Lease, behaviour, e-stop; shared with the robot's earlier and later registrations.
  [[nodiscard]] RobotControl& control() const { return *control_; }
  [[nodiscard]] std::shared_ptr<RobotControl> control_ptr() const { return control_; }

  // The watchdog timer (lease expiry, stale sensors) on the world's strand; see robot_control.h.
  asio::steady_timer& watchdog_timer_on_strand() { return watchdog_; }
  std::optional<std::chrono::steady_clock::time_point>& watchdog_deadline_on_strand() { return watchdog_deadline_; }
  // Shutting down: the watchdog is cancelled and never armed again (so draining the pool does not wait for it).
  void stop_watchdog_on_strand() {
    watchdog_stopped_ = true;
    watchdog_deadline_.reset();
    watchdog_.cancel();
  }
  [[nodiscard]] bool watchdog_stopped_on_strand() const { return watchdog_stopped_; }

 private:
  std::shared_ptr<const RobotModel> model_;
  std::shared_ptr<World> world_;
  RobotCounters counters_;
  std::shared_ptr<RobotControl> control_;
  asio::steady_timer watchdog_;
  std::optional<std::chrono::steady_clock::time_point> watchdog_deadline_;  // when the armed timer fires
  bool watchdog_stopped_ = false;
  control::BearcatBehaviour behaviour_;
  std::unique_ptr<control::Behaviour> active_behaviour_;
  std::uint64_t active_generation_ = 0;
  std::optional<geometry::EncoderOdometry> encoder_odometry_;
  std::array<metrics::Counter*, 4> ingested_counters_{};  // by kind, as ingested_counter_on_strand lists them
  mutable std::mutex mutex_;
  RobotState state_;
};

// What a query needs of a registered robot: its model (the footprint) and its world.
struct RobotQueryView {
  std::shared_ptr<const RobotModel> model;  // null when no robot has the id
  World* world = nullptr;                   // worlds live as long as the ServerCore
};

// State shared by every session: configuration, worlds, robots and the worker pools. Ingest
// runs on one pool (a strand per world) and queries on another, so neither waits for the other
// or for the network thread.
class ServerCore {
 public:
  // Above every ClientMessage body's field number (NumberedFamily's table size).
  static constexpr std::size_t kBodyFieldCount = 64;

  explicit ServerCore(ServerConfig config);
  ~ServerCore();
  ServerCore(const ServerCore&) = delete;
  ServerCore& operator=(const ServerCore&) = delete;

  [[nodiscard]] const ServerConfig& config() const { return config_; }
  asio::thread_pool& query_pool() { return query_pool_; }
  // This server's metrics (GET /metrics); another ServerCore in the process counts apart.
  metrics::Registry& metrics() { return metrics_; }
  // occgeo_queries_total and occgeo_query_duration_seconds per request kind, by the ClientMessage body's field number.
  metrics::NumberedFamily<metrics::Counter, kBodyFieldCount>& query_counts() { return query_counts_; }
  metrics::NumberedFamily<metrics::Histogram, kBodyFieldCount>& query_durations() { return query_durations_; }
  // Queries answered ERROR_BUSY (kept at hand: a flood refuses many).
  metrics::Counter& queries_busy() { return queries_busy_; }

  // The world with this name, created empty on first use.
  std::shared_ptr<World> world(const std::string& name);
  [[nodiscard]] std::shared_ptr<World> find_world(const std::string& name) const;
  [[nodiscard]] std::vector<std::shared_ptr<World>> worlds() const;
  // Adds a world restored from storage and returns it; replaces nothing that exists (then returns
  // the existing world).
  std::shared_ptr<World> add_world(const std::string& name, mapping::HimmGrid grid);
  // The models' parameters of the world with this name.
  [[nodiscard]] WorldParams world_params(const std::string& name) const;

  [[nodiscard]] std::shared_ptr<Robot> find_robot(const std::string& id) const;
  // The same for a network thread answering many queries: while no robot was registered since this thread's last
  // call for the same id, no lock is taken and no reference count touched (both are shared by every thread). The
  // reference is valid until this thread calls it again.
  [[nodiscard]] const RobotQueryView& robot_for_this_thread(const std::string& id) const;
  [[nodiscard]] std::vector<std::shared_ptr<Robot>> robots() const;
  // Registers (or re-registers, when its driver reconnects) a robot; nullptr with `error` set
  // when the robot limit is reached.
  std::shared_ptr<Robot> register_robot(const std::shared_ptr<const RobotModel>& model, const std::string& world,
                                        std::string& error);

  std::atomic<std::uint32_t> sessions{0};
  // Queries admitted and not yet answered, over every session (limits.max_query_backlog); see Session.
  std::atomic<std::size_t> queries_in_flight{0};
  std::atomic<std::uint64_t> next_session_id{1};
  [[nodiscard]] double uptime_s() const;
  // The process's resident memory, bytes, read from /proc at most every kResidentRefreshInterval: a status request
  // asks for it, and opening /proc/self/statm for each of them cost more than the rest of the reply.
  [[nodiscard]] std::uint64_t recent_resident_bytes() const;
  static constexpr std::chrono::milliseconds kResidentRefreshInterval{250};

  // Stops the robots' watchdog timers, then waits for queued ingest and query work to finish.
  void drain();

 private:
  // First, so that it outlives everything holding references to its metrics (journals, sessions' gauges).
  metrics::Registry metrics_;
  metrics::NumberedFamily<metrics::Counter, kBodyFieldCount> query_counts_{metrics_, "occgeo_queries_total", "kind"};
  metrics::NumberedFamily<metrics::Histogram, kBodyFieldCount> query_durations_{
      metrics_, "occgeo_query_duration_seconds", "kind"};
  metrics::Counter& queries_busy_{metrics_.counter("occgeo_queries_busy_total", {},
                                                   "Queries answered ERROR_BUSY: the server's query backlog was full")};
  ServerConfig config_;
  asio::thread_pool ingest_pool_{1};
  // The worlds' octree lanes (see World): one thread, so that a scan's octree insertion never delays a robot's command.
  asio::thread_pool octree_pool_{1};
  // The worlds' publish lanes (see World::publish_staged_on_strand): one thread at the ingest pool's priority, so that
  // a distance field's update never delays the next scan's command and readers see each message soon after it.
  asio::thread_pool publish_pool_{1};
  static constexpr std::size_t kQueryThreads = 2;
  asio::thread_pool query_pool_{kQueryThreads};
  mutable std::mutex registry_mutex_;
  std::map<std::string, std::shared_ptr<World>> worlds_;
  std::map<std::string, std::shared_ptr<Robot>> robots_;
  // Changes with every change of robots_, unique across cores (see robot_for_this_thread).
  std::atomic<std::uint64_t> robots_generation_;
  std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
  // recent_resident_bytes()'s value and when it was read (steady clock, ns since its epoch), first at construction.
  mutable std::atomic<std::uint64_t> resident_bytes_{0};
  mutable std::atomic<std::int64_t> resident_read_at_ns_{0};
};

}  // namespace occgeo::service
