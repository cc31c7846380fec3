#include "occgeo/service/config.h"

#include <yaml-cpp/yaml.h>

#include <charconv>
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
      const auto key = entry.first.as<std::string>();
      if (std::find(known_.begin(), known_.end(), key) == known_.end()) {
        throw ConfigError("unknown configuration key '" + where(key) + "'");
      }
    }
  }

 private:
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

}  // namespace

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
  require(queries.clearance_max_distance_m <= limits.max_query_distance_m, "queries.clearance_max_distance_m",
          "must not exceed limits.max_query_distance_m");
  require(control.command_expiry_s > 0 && control.command_expiry_s <= 10, "control.command_expiry_s",
          "must be in (0, 10] seconds");
  require(queries.clearance_max_distance_m > 0, "queries.clearance_max_distance_m", "must be positive");
  try {
    himm.validate();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("configuration 'himm': ") + e.what());
  }
  try {
    bearcat.validate();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("configuration 'bearcat': ") + e.what());
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
                       .field("max_point_cloud_points", config.limits.max_point_cloud_points);
                 })
        .section("control", [&](Section& s) { s.field("command_expiry_s", config.control.command_expiry_s); })
        .section("queries",
                 [&](Section& s) { s.field("clearance_max_distance_m", config.queries.clearance_max_distance_m); })
        .section("himm",
                 [&](Section& s) {
                   auto& h = config.himm;
                   s.field("cell_size_m", h.cell_size_m)
                       .field("increment", h.increment)
                       .field("decrement", h.decrement)
                       .field("max_certainty", h.max_certainty)
                       .field("growth_center_weight", h.growth_center_weight)
                       .field("growth_neighbour_weight", h.growth_neighbour_weight)
                       .field("occupied_threshold", h.occupied_threshold)
                       .field("tile_cells", h.tile_cells);
                 })
        .section("bearcat", [&](Section& s) {
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
