#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>

#include "occgeo/mapping/beam_limits.h"
#include "occgeo/mapping/distance_field.h"
#include "occgeo/mapping/himm_grid.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/mapping/ptem.h"
#include "occgeo/mapping/terrain.h"
#include "occgeo/service/control/bearcat.h"
#include "occgeo/service/control/safety_guard.h"

namespace occgeo::service {

// A configuration file or flag is wrong; the message names the key.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Resource limits that protect the server from bad or slow clients.
struct LimitsConfig {
  std::size_t max_frame_bytes = std::size_t{4} << 20;        // larger frames close the connection
  std::size_t max_send_queue_bytes = std::size_t{32} << 20;  // a client whose unread replies exceed this is dropped
  std::size_t max_clients = 1024;                            // concurrent sessions of any role
  std::size_t max_robots = 256;                              // registered robots
  std::uint32_t max_beams = 100000;                          // beams per laser in a RobotSpec
  double max_abs_coordinate_m = 1.0e5;                       // odometry and query poses beyond this are rejected
  double max_sensor_range_m = 200.0;                         // a RobotSpec's range_max_m above this is rejected
  double max_query_distance_m = 100.0;                       // clearance search radius limit
  std::size_t max_grid_reply_cells = std::size_t{16} << 20;  // whole-grid replies larger than this are refused
  std::size_t max_point_cloud_points = 200000;               // larger point clouds are rejected (each is a ray)
  std::size_t max_ptem_query_points = 100000;                // points per PtemQuery
  // Octree voxels one laser scan or point cloud may touch (scan_voxel_estimate): more is refused naming the limit.
  std::uint64_t max_scan_voxels = 25000000;
  std::size_t max_octree_reply_bytes = std::size_t{16} << 20;  // OctreeReply.bt larger than this (or than
                                                               // max_send_queue_bytes / 2) is refused
  std::size_t max_batch_queries = 100000;                      // entries (poses, rays, points) in one batch request
  std::size_t max_pending_requests = 64;  // a session's queries in flight; beyond it the server stops reading it
  // Queries in flight across all sessions (admitted, not yet answered). A query or observer session's request beyond
  // it is answered ERROR_BUSY at once, so a query flood cannot queue work ahead of the robots'.
  std::size_t max_query_backlog = 256;
  std::size_t max_watch_queue_messages = 256;  // WatchEvents queued per session; a slow watcher loses its oldest
  double hello_timeout_s = 5.0;                // a connection that has not completed its hello by then is closed
  // Connections from one address that have not said hello yet; a newer one evicts the oldest of them, so idle
  // connections can neither pile up nor keep a robot's driver out.
  std::size_t max_silent_per_address = 64;
  double write_timeout_s = 60.0;  // a client that accepts no bytes for this long while some wait is dropped
};

// Server-side control of the robots.
struct ControlConfig {
  double command_expiry_s = 0.6;      // every motion command tells the driver to stop after this long without a new one
  double lease_timeout_s = 2.0;       // a control lease not retained for this long lapses (LeaseRequest.timeout_s 0)
  double max_lease_timeout_s = 30.0;  // the longest LeaseRequest.timeout_s a controller may ask for
  double sensor_timeout_s = 0.5;      // a driven robot with no sensor message for this long is sent a stop
  std::string initial_behaviour = "bearcat";  // a newly registered robot's behaviour: "bearcat" or "stop"
  // SCHED_FIFO priority (1-99) of the threads that turn a scan into its MotionCommand: the ingest strands' and the
  // robot drivers' event loop. 0: they keep the process's policy. Without the privilege (CAP_SYS_NICE) the server
  // warns once per thread and they keep it too.
  int realtime_priority = 10;
};

// Who may do what beyond their role.
struct AuthConfig {
  // Hello.auth_token that lets a session TAKE a lease forcibly; empty (the default) disables TAKE. It also
  // authenticates a hello of any role.
  std::string operator_token;
  // Hello.auth_token each role must present; empty leaves the role open (only allowed on a loopback listen address).
  std::string driver_token;
  std::string controller_token;
  std::string observer_token;
  std::string query_token;
  // After this many refused hellos from one address within failure_window_s, its further hellos are refused
  // unchecked until the window has passed.
  std::size_t max_failures = 5;
  double failure_window_s = 60.0;
};

// TLS on the occgeo.v1 socket: both files (PEM) or neither (plain TCP).
struct TlsConfig {
  std::filesystem::path cert;  // certificate chain
  std::filesystem::path key;   // its private key
  [[nodiscard]] bool enabled() const { return !cert.empty(); }
};

// How accepted sensor data is made durable (section `durability:`; docs/ARCHITECTURE.md, "Durability").
struct DurabilityConfig {
  // When a sensor message counts as durable, hence is acknowledged: "every" (an fdatasync covering its journal record,
  // started at once by the journal's sync thread, before the ack), "batch" (acks wait for a group fsync at most
  // batch_interval_s later) or "none" (written to the OS only).
  std::string policy = "every";
  double batch_interval_s = 0.005;  // batch: the group-commit window, seconds
  // A world whose journal grew is snapshotted (and its journal emptied) this often, seconds; 0: only on clean shutdown.
  double snapshot_interval_s = 300.0;
};

// Geometry query defaults.
struct QueryConfig {
  double clearance_max_distance_m = 5.0;  // search radius when the query leaves it 0
  // Threads reading and writing the sockets; they also answer cheap single queries inline.
  std::size_t network_threads = 2;
  // The longest a network thread that ran out of work polls its sockets (yielding the core between polls) before it
  // sleeps, microseconds; 0: it sleeps at once. Waking a halted core costs more than a cheap query on some machines.
  double network_poll_us = 200.0;
  // Niceness the network threads add to their own (Linux, 0-19). They answer queries inline; at a lower priority than
  // the ingest and control threads, a flood of queries slows the queries, not the robot's map updates and commands.
  int network_nice = 5;
  // Robot drivers' sessions (plain TCP) move after their hello to an event loop of their own, served by a thread at
  // the process's priority that answers no queries: scans are read and commands written without queuing behind
  // query sessions. false: they stay on the network thread that accepted them.
  bool driver_loop = true;
};

// The HTTP listener: the live web view (/), its WebSocket (/ws) and Prometheus metrics (/metrics).
struct HttpConfig {
  std::string listen = "127.0.0.1:7701";  // host:port; port 0 picks a free one
  bool enabled = true;                    // false: no HTTP listener at all
  // Open HTTP connections at most (pages, scrapes and WebSockets together); one more is closed at once, so browsers
  // and scrapers cannot pile up connections. Each request is timed out after 30 s, a WebSocket by its pings.
  std::size_t max_connections = 64;
};

// What one world's PTEM overrides of the `ptem:` section (`ptem.worlds.<name>`); unset fields take the section's.
struct PtemWorldOverride {
  std::optional<mapping::PtemConstruction> construction;
  std::optional<double> cluster_distance_m;
  std::optional<double> max_cluster_radius_m;
};

// The PTEM (seed 004 §4, mapping/include/occgeo/mapping/ptem.h) every world builds from its laser scans. YAML:
//   ptem:
//     construction: single_scan      # or cumulative (seed §4.2.2); default single_scan (§4.2.3)
//     cluster_distance_m: 0.381      # C_r, metres; default the seed UGV's width (15 in). One model serves every
//                                    # robot of a world, so C_r is per world, not per robot: set it to the width of
//                                    # the widest robot that must not pass between two obstacles
//     initial_cluster_radius_m: 0.25 # radius of a new cluster, metres (how far behind its first return it reaches)
//     max_cluster_radius_m: 0.5      # largest cluster circle, metres; a wall becomes a chain of clusters.
//                                    # 0: unbounded, the seed's clusters (§4.2.2), e.g. for a seed-faithful world
//     restricted_threshold: 0.04     # f_r, 1/m² (seed §4.3)
//     first_cluster_sigma_m: 0.1     # optional: fix f_r from the first cluster instead (seed eq 4.2)
//     worlds:                        # optional per-world overrides
//       lab: {construction: cumulative, cluster_distance_m: 0.8, max_cluster_radius_m: 0}
struct PtemConfig {
  mapping::PtemParams params;
  std::map<std::string, PtemWorldOverride> worlds;

  // The parameters of the world with this name: the section's, with that world's overrides applied.
  [[nodiscard]] mapping::PtemParams params_for(const std::string& world) const;
};

// "cumulative" / "single_scan", as the config and the protocol spell the constructions.
[[nodiscard]] std::string ptem_construction_name(mapping::PtemConstruction construction);
// The construction with this name; nullopt for anything else.
[[nodiscard]] std::optional<mapping::PtemConstruction> parse_ptem_construction(const std::string& name);

// The distance field's defaults in the server: the library's, with max_distance_m = 5 m (the default clearance search
// radius).
inline mapping::DistanceFieldParams default_distance_field_params() {
  mapping::DistanceFieldParams params;
  params.max_distance_m = 5.0;
  return params;
}

// What every sensor's readings change unless its RobotSpec says otherwise (section `sensors:`, the fields of
// mapping::BeamLimits): enough for indoor sensors to map as far as they see, while an 80 m lidar costs each scan what
// its near 30 m do (docs/CONFIG.md has the measurements).
inline mapping::BeamLimits default_sensor_beam_limits() {
  mapping::BeamLimits limits;
  limits.max_insert_range_m = 30.0;
  limits.max_free_range_m = 30.0;
  limits.no_return_clear_m = 10.0;
  return limits;
}

// Everything occgeod can be configured with; file keys mirror the field names.
struct ServerConfig {
  std::string listen = "127.0.0.1:7700";
  std::filesystem::path data_dir = "occgeo-data";
  std::string log_level = "info";
  std::string default_world = "default";
  LimitsConfig limits;
  ControlConfig control;
  AuthConfig auth;
  TlsConfig tls;
  QueryConfig queries;
  DurabilityConfig durability;
  HttpConfig http;
  mapping::HimmParams himm;
  control::BearcatParams bearcat;
  control::GuardParams guard;  // the safety guard every motion command passes (section `guard:`)
  PtemConfig ptem;
  // Every world's OctoMap (section `octomap:`, keys as the fields of mapping::OctoMapParams, e.g. resolution_m,
  // prob_hit, voxel_filter_enabled, outlier_mean_k, min_publish_interval_s).
  mapping::OctoMapParams octomap;
  // octomap.publish_every_messages: > 0 publishes each world's octree after every N-th sensor message instead of at
  // most every min_publish_interval_s of wall time, so a lockstep simulation sees the same models on every run.
  std::uint32_t octomap_publish_every_messages = 0;
  // octomap.lane_nice: niceness the octree's lane thread adds to its own (Linux, 0-19). Its work costs milliseconds per
  // scan and nobody waits for it (readers see the octree up to min_publish_interval_s stale); below the ingest strand,
  // a scan's command does not share a core with the previous scans' octree insertion.
  int octomap_lane_nice = 3;
  // The terrain rule (section `terrain:`): surfaces the octree shows a robot can drive on (a ramp) are not obstacles
  // to its behaviour, planner and guard; ground_band_m is the floor's height band for every model.
  mapping::TerrainParams terrain;
  // Every world's distance field over its HIMM grid (section `distance_field:`: max_distance_m). max_distance_m
  // defaults to queries.clearance_max_distance_m's default so that default clearance queries are answered from the
  // field.
  mapping::DistanceFieldParams distance_field = default_distance_field_params();
  // Each sensor's reach into the maps unless its RobotSpec's SensorSpec.ranges says otherwise (section `sensors:`).
  mapping::BeamLimits sensors = default_sensor_beam_limits();

  // Checks every field; throws ConfigError naming the first bad one.
  void validate() const;
};

// Reads a YAML configuration over the defaults; unknown keys are an error naming the key.
ServerConfig load_config(const std::filesystem::path& file);

// Splits "HOST:PORT"; throws ConfigError naming `what` when malformed.
std::pair<std::string, std::uint16_t> split_host_port(const std::string& text, const std::string& what);

}  // namespace occgeo::service
