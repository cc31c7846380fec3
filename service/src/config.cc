#include "occgeo/service/config.h"

#include <yaml-cpp/yaml.h>

#include <boost/asio/ip/address.hpp>

#include <charconv>
#include <cmath>
#include <functional>
#include <map>

#include "occgeo/service/log.h"

namespace occgeo::service {

namespace {

// Reads one mapping's keys into fields; every key must be known.
class Section {
 public:
  Section(const YAML::Node& node, std::string path) : node_(node), path_(std::move(path)) {
    if (node_ && !node_.IsMap()) throw ConfigError(where("") + " must be a mapping");
  }

  template <typename T>
  Section& field(const std::string& key, T& target) {
    known_.push_back(key);
    if (!node_ || !node_[key]) return *this;
    try {
      target = node_[key].as<T>();
    } catch (const YAML::Exception&) {
      throw ConfigError(where(key) + " has a value of the wrong type");
    }
    return *this;
  }

  // Like field, for a key that may be left out: target stays nullopt then.
  template <typename T>
  Section& optional_field(const std::string& key, std::optional<T>& target) {
    known_.push_back(key);
    if (!node_ || !node_[key]) return *this;
    try {
      target = node_[key].as<T>();
    } catch (const YAML::Exception&) {
      throw ConfigError(where(key) + " has a value of the wrong type");
    }
    return *this;
  }

  // A mapping from names the user chooses (e.g. world names) to sections; read is called for each.
  Section& named_sections(const std::string& key, const std::function<void(const std::string&, Section&)>& read) {
    known_.push_back(key);
    if (!node_ || !node_[key]) return *this;
    const YAML::Node map = node_[key];
    if (!map.IsMap()) throw ConfigError(where(key) + " must be a mapping");
    for (const auto& entry : map) {
      const auto name = key_name(entry.first, where(key));
      Section child(entry.second, where(key) + "." + name);
      read(name, child);
      child.reject_unknown();
    }
    return *this;
  }

  [[nodiscard]] const std::string& path() const { return path_; }

  Section& section(const std::string& key, const std::function<void(Section&)>& read) {
    known_.push_back(key);
    Section child(node_ ? node_[key] : YAML::Node(), where(key));
    read(child);
    child.reject_unknown();
    return *this;
  }

  void reject_unknown() const {
    if (!node_) return;
    for (const auto& entry : node_) {
      const auto key = key_name(entry.first, path_);
      if (std::find(known_.begin(), known_.end(), key) == known_.end()) {
        throw ConfigError("unknown configuration key '" + where(key) + "'");
      }
    }
  }

 private:
  // A key must be a plain name; YAML also allows sequences and mappings as keys ("? [a]: 1").
  static std::string key_name(const YAML::Node& key, const std::string& within) {
    if (!key.IsScalar()) {
      throw ConfigError("a configuration key " +
                        (within.empty() ? std::string("at the top level") : "in '" + within + "'") +
                        " is not a plain name");
    }
    return key.Scalar();
  }

  [[nodiscard]] std::string where(const std::string& key) const {
    if (path_.empty()) return key;
    return key.empty() ? path_ : path_ + "." + key;
  }

  YAML::Node node_;
  std::string path_;
  std::vector<std::string> known_;
};

void require(bool ok, const std::string& key, const std::string& rule) {
  if (!ok) throw ConfigError("configuration '" + key + "' " + rule);
}

// Whether HOST:PORT names a loopback host (127.0.0.0/8, ::1 or "localhost"); anything else, including a
// wildcard address, can be reached from other machines.
bool listen_is_loopback(const std::string& listen) {
  const std::string host = split_host_port(listen, "listen").first;
  if (host == "localhost") return true;
  boost::system::error_code error;
  const auto address = boost::asio::ip::make_address(host, error);
  return !error && address.is_loopback();
}

// Reads a construction name at key into target (left alone when the key is absent).
void read_construction(Section& s, const std::string& key, std::optional<mapping::PtemConstruction>& target) {
  std::optional<std::string> name;
  s.optional_field(key, name);
  if (!name) return;
  target = parse_ptem_construction(*name);
  const std::string path = s.path().empty() ? key : s.path() + "." + key;
  require(target.has_value(), path, "must be cumulative or single_scan, got '" + *name + "'");
}

// Runs a parameter block's own validate(), reporting its std::invalid_argument as a ConfigError naming `key`.
template <typename Params>
void validate_block(const Params& params, const std::string& key) {
  try {
    params.validate();
  } catch (const std::invalid_argument& e) {
    throw ConfigError("configuration '" + key + "': " + e.what());
  }
}

}  // namespace

std::string ptem_construction_name(mapping::PtemConstruction construction) {
  return construction == mapping::PtemConstruction::kCumulative ? "cumulative" : "single_scan";
}

std::optional<mapping::PtemConstruction> parse_ptem_construction(const std::string& name) {
  if (name == "cumulative") return mapping::PtemConstruction::kCumulative;
  if (name == "single_scan") return mapping::PtemConstruction::kSingleScan;
  return std::nullopt;
}

mapping::PtemParams PtemConfig::params_for(const std::string& world) const {
  mapping::PtemParams out = params;
  if (const auto it = worlds.find(world); it != worlds.end()) {
    if (it->second.construction) out.construction = *it->second.construction;
    if (it->second.cluster_distance_m) out.cluster_distance_m = *it->second.cluster_distance_m;
    if (it->second.max_cluster_radius_m) out.max_cluster_radius_m = *it->second.max_cluster_radius_m;
  }
  return out;
}

std::pair<std::string, std::uint16_t> split_host_port(const std::string& text, const std::string& what) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == text.size()) {
    throw ConfigError(what + " '" + text + "' is not HOST:PORT");
  }
  unsigned port = 0;
  const char* begin = text.data() + colon + 1;
  const char* end = text.data() + text.size();
  const auto [last, error] = std::from_chars(begin, end, port);
  if (error != std::errc() || last != end || port > 65535) {
    throw ConfigError(what + " '" + text + "' has an invalid port");
  }
  std::string host = text.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  return {host, static_cast<std::uint16_t>(port)};
}

void ServerConfig::validate() const {
  split_host_port(listen, "listen");
  split_host_port(http.listen, "http.listen");
  require(http.max_connections >= 1 && http.max_connections <= 100000, "http.max_connections",
          "must be between 1 and 100000");
  try {
    log::parse_level(log_level);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("configuration 'log_level': ") + e.what());
  }
  require(!default_world.empty(), "default_world", "must not be empty");
  require(limits.max_frame_bytes >= 1024 && limits.max_frame_bytes <= (std::size_t{512} << 20),
          "limits.max_frame_bytes", "must be between 1 KiB and 512 MiB");
  require(limits.max_send_queue_bytes >= limits.max_frame_bytes, "limits.max_send_queue_bytes",
          "must be at least limits.max_frame_bytes");
  require(limits.max_clients > 0, "limits.max_clients", "must be positive");
  require(limits.max_robots > 0, "limits.max_robots", "must be positive");
  require(limits.max_beams > 0, "limits.max_beams", "must be positive");
  require(limits.max_abs_coordinate_m > 0, "limits.max_abs_coordinate_m", "must be positive");
  require(limits.max_sensor_range_m > 0 && limits.max_sensor_range_m <= 1.0e4, "limits.max_sensor_range_m",
          "must be in (0, 10000] metres");
  require(limits.max_query_distance_m > 0 && limits.max_query_distance_m <= 1.0e4, "limits.max_query_distance_m",
          "must be in (0, 10000] metres");
  require(limits.max_grid_reply_cells > 0, "limits.max_grid_reply_cells", "must be positive");
  require(limits.max_point_cloud_points > 0, "limits.max_point_cloud_points", "must be positive");
  require(limits.max_ptem_query_points > 0, "limits.max_ptem_query_points", "must be positive");
  require(queries.clearance_max_distance_m <= limits.max_query_distance_m, "queries.clearance_max_distance_m",
          "must not exceed limits.max_query_distance_m");
  require(control.command_expiry_s > 0 && control.command_expiry_s <= 10, "control.command_expiry_s",
          "must be in (0, 10] seconds");
  require(control.lease_timeout_s > 0 && control.lease_timeout_s <= control.max_lease_timeout_s,
          "control.lease_timeout_s", "must be in (0, control.max_lease_timeout_s] seconds");
  require(control.max_lease_timeout_s > 0 && control.max_lease_timeout_s <= 3600, "control.max_lease_timeout_s",
          "must be in (0, 3600] seconds");
  require(control.sensor_timeout_s > 0 && control.sensor_timeout_s <= 60, "control.sensor_timeout_s",
          "must be in (0, 60] seconds");
  require(auth.operator_token.size() <= 1024, "auth.operator_token", "must be at most 1024 characters");
  for (const auto& [key, token] : {std::pair<const char*, const std::string*>{"auth.driver_token", &auth.driver_token},
                                   {"auth.controller_token", &auth.controller_token},
                                   {"auth.observer_token", &auth.observer_token},
                                   {"auth.query_token", &auth.query_token}}) {
    require(token->size() <= 1024, key, "must be at most 1024 characters");
  }
  require(auth.max_failures > 0, "auth.max_failures", "must be positive");
  require(auth.failure_window_s > 0 && auth.failure_window_s <= 86400, "auth.failure_window_s",
          "must be in (0, 86400] seconds");
  if (!listen_is_loopback(listen)) {
    std::string missing;
    for (const auto& [key, token] :
         {std::pair<const char*, const std::string*>{"auth.driver_token", &auth.driver_token},
          {"auth.controller_token", &auth.controller_token},
          {"auth.observer_token", &auth.observer_token},
          {"auth.query_token", &auth.query_token},
          {"auth.operator_token", &auth.operator_token}}) {
      if (token->empty()) missing += (missing.empty() ? "" : ", ") + std::string(key);
    }
    require(missing.empty(), "listen",
            "is '" + listen +
                "', not a loopback address: anyone who can reach it could drive the robots, so every "
                "role needs a token; missing: " +
                missing);
  }
  if (http.enabled && !listen_is_loopback(http.listen)) {
    require(!auth.observer_token.empty(), "http.listen",
            "is '" + http.listen +
                "', not a loopback address: the live view (with its e-stop) and the Foxglove channels would be "
                "open to anyone who can reach it; set auth.observer_token, which every page and WebSocket request "
                "must then carry");
  }
  require(tls.cert.empty() == tls.key.empty(), tls.cert.empty() ? "tls.cert" : "tls.key",
          "must be set together with tls." + std::string(tls.cert.empty() ? "key" : "cert"));
  require(limits.max_batch_queries > 0, "limits.max_batch_queries", "must be positive");
  require(limits.max_pending_requests > 0, "limits.max_pending_requests", "must be positive");
  require(limits.max_query_backlog > 0, "limits.max_query_backlog", "must be positive");
  require(limits.max_watch_queue_messages > 0, "limits.max_watch_queue_messages", "must be positive");
  require(limits.hello_timeout_s > 0 && limits.hello_timeout_s <= 3600, "limits.hello_timeout_s",
          "must be in (0, 3600] seconds");
  require(limits.max_silent_per_address > 0, "limits.max_silent_per_address", "must be positive");
  require(limits.write_timeout_s > 0 && limits.write_timeout_s <= 3600, "limits.write_timeout_s",
          "must be in (0, 3600] seconds");
  require(queries.clearance_max_distance_m > 0, "queries.clearance_max_distance_m", "must be positive");
  require(queries.network_threads >= 1 && queries.network_threads <= 64, "queries.network_threads",
          "must be between 1 and 64");
  require(queries.network_poll_us >= 0 && queries.network_poll_us <= 10000, "queries.network_poll_us",
          "must be in [0, 10000] microseconds (0: no polling)");
  require(queries.network_nice >= 0 && queries.network_nice <= 19, "queries.network_nice",
          "must be between 0 and 19 (added to the network threads' niceness)");
  require(durability.policy == "every" || durability.policy == "batch" || durability.policy == "none",
          "durability.policy", "must be every, batch or none");
  require(durability.batch_interval_s > 0 && durability.batch_interval_s <= 1, "durability.batch_interval_s",
          "must be in (0, 1] seconds");
  require(durability.snapshot_interval_s >= 0 && durability.snapshot_interval_s <= 86400,
          "durability.snapshot_interval_s", "must be in [0, 86400] seconds (0: only on clean shutdown)");
  validate_block(himm, "himm");
  validate_block(bearcat, "bearcat");
  require(control.realtime_priority >= 0 && control.realtime_priority <= 99, "control.realtime_priority",
          "must be 0 (off) or a SCHED_FIFO priority in [1, 99]");
  require(control.initial_behaviour == "bearcat" || control.initial_behaviour == "stop", "control.initial_behaviour",
          "must be \"bearcat\" or \"stop\"");
  validate_block(guard, "guard");
  validate_block(ptem.params, "ptem");
  require(limits.max_octree_reply_bytes > 0, "limits.max_octree_reply_bytes", "must be positive");
  require(limits.max_scan_voxels > 0, "limits.max_scan_voxels", "must be positive");
  validate_block(octomap, "octomap");
  require(octomap_publish_every_messages <= 1000000, "octomap.publish_every_messages", "must be in [0, 1000000]");
  require(octomap_lane_nice >= 0 && octomap_lane_nice <= 19, "octomap.lane_nice",
          "must be between 0 and 19 (added to the octree lane thread's niceness)");
  validate_block(terrain, "terrain");
  validate_block(distance_field, "distance_field");
  require(std::isfinite(sensors.max_insert_range_m) && sensors.max_insert_range_m > 0, "sensors.max_insert_range_m",
          "must be a positive length in metres");
  require(std::isfinite(sensors.max_free_range_m) && sensors.max_free_range_m >= 0, "sensors.max_free_range_m",
          "must be a length >= 0 in metres");
  require(std::isfinite(sensors.no_return_clear_m) && sensors.no_return_clear_m >= 0, "sensors.no_return_clear_m",
          "must be a length >= 0 in metres (0: no-return beams clear nothing)");
  for (const auto& [name, override_params] : ptem.worlds) {
    validate_block(ptem.params_for(name), "ptem.worlds." + name);
  }
}

ServerConfig load_config(const std::filesystem::path& file) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw ConfigError(file.string() + ": " + e.what());
  }
  ServerConfig config;
  std::string data_dir = config.data_dir.string();
  try {
    Section top(root, "");
    top.field("listen", config.listen)
        .field("data_dir", data_dir)
        .field("log_level", config.log_level)
        .field("default_world", config.default_world)
        .section("limits",
                 [&](Section& s) {
                   s.field("max_frame_bytes", config.limits.max_frame_bytes)
                       .field("max_send_queue_bytes", config.limits.max_send_queue_bytes)
                       .field("max_clients", config.limits.max_clients)
                       .field("max_robots", config.limits.max_robots)
                       .field("max_beams", config.limits.max_beams)
                       .field("max_abs_coordinate_m", config.limits.max_abs_coordinate_m)
                       .field("max_sensor_range_m", config.limits.max_sensor_range_m)
                       .field("max_query_distance_m", config.limits.max_query_distance_m)
                       .field("max_grid_reply_cells", config.limits.max_grid_reply_cells)
                       .field("max_point_cloud_points", config.limits.max_point_cloud_points)
                       .field("max_ptem_query_points", config.limits.max_ptem_query_points)
                       .field("max_octree_reply_bytes", config.limits.max_octree_reply_bytes)
                       .field("max_scan_voxels", config.limits.max_scan_voxels)
                       .field("max_batch_queries", config.limits.max_batch_queries)
                       .field("max_pending_requests", config.limits.max_pending_requests)
                       .field("max_query_backlog", config.limits.max_query_backlog)
                       .field("max_watch_queue_messages", config.limits.max_watch_queue_messages)
                       .field("hello_timeout_s", config.limits.hello_timeout_s)
                       .field("max_silent_per_address", config.limits.max_silent_per_address)
                       .field("write_timeout_s", config.limits.write_timeout_s);
                 })
        .section("control",
                 [&](Section& s) {
                   s.field("command_expiry_s", config.control.command_expiry_s)
                       .field("lease_timeout_s", config.control.lease_timeout_s)
                       .field("max_lease_timeout_s", config.control.max_lease_timeout_s)
                       .field("sensor_timeout_s", config.control.sensor_timeout_s)
                       .field("initial_behaviour", config.control.initial_behaviour)
                       .field("realtime_priority", config.control.realtime_priority);
                 })
        .section("auth",
                 [&](Section& s) {
                   s.field("operator_token", config.auth.operator_token)
                       .field("driver_token", config.auth.driver_token)
                       .field("controller_token", config.auth.controller_token)
                       .field("observer_token", config.auth.observer_token)
                       .field("query_token", config.auth.query_token)
                       .field("max_failures", config.auth.max_failures)
                       .field("failure_window_s", config.auth.failure_window_s);
                 })
        .section("tls",
                 [&](Section& s) {
                   std::string cert = config.tls.cert.string();
                   std::string key = config.tls.key.string();
                   s.field("cert", cert).field("key", key);
                   config.tls.cert = cert;
                   config.tls.key = key;
                 })
        .section("queries",
                 [&](Section& s) {
                   s.field("clearance_max_distance_m", config.queries.clearance_max_distance_m)
                       .field("network_threads", config.queries.network_threads)
                       .field("network_poll_us", config.queries.network_poll_us)
                       .field("network_nice", config.queries.network_nice)
                       .field("driver_loop", config.queries.driver_loop);
                 })
        .section("durability",
                 [&](Section& s) {
                   s.field("policy", config.durability.policy)
                       .field("batch_interval_s", config.durability.batch_interval_s)
                       .field("snapshot_interval_s", config.durability.snapshot_interval_s);
                 })
        .section("http",
                 [&](Section& s) {
                   s.field("listen", config.http.listen)
                       .field("enabled", config.http.enabled)
                       .field("max_connections", config.http.max_connections);
                 })
        .section("himm",
                 [&](Section& s) {
                   auto& h = config.himm;
                   s.field("cell_size_m", h.cell_size_m)
                       .field("increment", h.increment)
                       .field("decrement", h.decrement)
                       .field("seen_through_decrement", h.seen_through_decrement)
                       .field("max_certainty", h.max_certainty)
                       .field("growth_center_weight", h.growth_center_weight)
                       .field("growth_neighbour_weight", h.growth_neighbour_weight)
                       .field("occupied_threshold", h.occupied_threshold)
                       .field("tile_cells", h.tile_cells);
                 })
        .section("bearcat",
                 [&](Section& s) {
                   auto& b = config.bearcat;
                   s.field("zone_width_m", b.zone_width_m)
                       .field("zone_depth_m", b.zone_depth_m)
                       .field("gap_range_m", b.gap_range_m)
                       .field("gap_min_width_m", b.gap_min_width_m)
                       .field("straight_deadband_deg", b.straight_deadband_deg)
                       .field("base_speed_mps", b.base_speed_mps)
                       .field("speed_per_degree_mps", b.speed_per_degree_mps)
                       .field("max_wheel_speed_mps", b.max_wheel_speed_mps)
                       .field("wheel_separation_m", b.wheel_separation_m)
                       .field("turn_small_deg", b.turn_small_deg)
                       .field("turn_large_deg", b.turn_large_deg);
                 })
        .section("ptem",
                 [&](Section& s) {
                   auto& p = config.ptem.params;
                   std::optional<mapping::PtemConstruction> construction;
                   read_construction(s, "construction", construction);
                   if (construction) p.construction = *construction;
                   s.field("cluster_distance_m", p.cluster_distance_m)
                       .field("initial_cluster_radius_m", p.initial_cluster_radius_m)
                       .field("max_cluster_radius_m", p.max_cluster_radius_m)
                       .field("restricted_threshold", p.restricted_threshold)
                       .optional_field("first_cluster_sigma_m", p.first_cluster_sigma_m)
                       .named_sections("worlds", [&](const std::string& name, Section& w) {
                         PtemWorldOverride& world = config.ptem.worlds[name];
                         read_construction(w, "construction", world.construction);
                         w.optional_field("cluster_distance_m", world.cluster_distance_m)
                             .optional_field("max_cluster_radius_m", world.max_cluster_radius_m);
                       });
                 })
        .section("octomap",
                 [&](Section& s) {
                   auto& o = config.octomap;
                   s.field("resolution_m", o.resolution_m)
                       .field("prob_hit", o.prob_hit)
                       .field("prob_miss", o.prob_miss)
                       .field("clamping_min", o.clamping_min)
                       .field("clamping_max", o.clamping_max)
                       .field("occupancy_threshold", o.occupancy_threshold)
                       .field("max_range_m", o.max_range_m)
                       .field("discretize_endpoints", o.discretize_endpoints)
                       .field("laser_see_through_clears", o.laser_see_through_clears)
                       .field("voxel_filter_enabled", o.voxel_filter_enabled)
                       .field("voxel_leaf_m", o.voxel_leaf_m)
                       .field("outlier_filter_enabled", o.outlier_filter_enabled)
                       .field("outlier_mean_k", o.outlier_mean_k)
                       .field("outlier_stddev_mul", o.outlier_stddev_mul)
                       .field("min_publish_interval_s", o.min_publish_interval_s)
                       .field("publish_every_messages", config.octomap_publish_every_messages)
                       .field("lane_nice", config.octomap_lane_nice);
                 })
        .section("terrain",
                 [&](Section& s) {
                   auto& t = config.terrain;
                   s.field("enabled", t.enabled)
                       .field("ground_band_m", t.ground_band_m)
                       .field("max_slope_rad", t.max_slope_rad)
                       .field("max_step_m", t.max_step_m);
                 })
        .section("guard",
                 [&](Section& s) {
                   auto& g = config.guard;
                   s.field("enabled", g.enabled)
                       .field("horizon_s", g.horizon_s)
                       .field("step_m", g.step_m)
                       .field("step_rad", g.step_rad)
                       .field("stop_time_s", g.stop_time_s)
                       .field("stop_distance_m", g.stop_distance_m)
                       .field("slowdown_ratio", g.slowdown_ratio)
                       .field("limit_distance_m", g.limit_distance_m)
                       .field("limit_linear_mps", g.limit_linear_mps)
                       .field("limit_angular_radps", g.limit_angular_radps)
                       .field("check_grid", g.check_grid)
                       .field("check_octomap", g.check_octomap)
                       .field("check_ptem", g.check_ptem)
                       .field("check_scan_returns", g.check_scan_returns)
                       .field("scan_returns_max_age_s", g.scan_returns_max_age_s)
                       .field("predict_horizon_s", g.predict_horizon_s)
                       .field("predict_margin_m", g.predict_margin_m);
                 })
        .section("distance_field",
                 [&](Section& s) {
                   auto& d = config.distance_field;
                   s.field("max_distance_m", d.max_distance_m);
                 })
        .section("sensors", [&](Section& s) {
          auto& r = config.sensors;
          s.field("max_insert_range_m", r.max_insert_range_m)
              .field("max_free_range_m", r.max_free_range_m)
              .field("no_return_clear_m", r.no_return_clear_m);
        });
    top.reject_unknown();
  } catch (const ConfigError& e) {
    throw ConfigError(file.string() + ": " + e.what());
  }
  config.data_dir = data_dir;
  config.validate();
  return config;
}

}  // namespace occgeo::service
