#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "occgeo/mapping/himm_grid.h"
#include "occgeo/service/control/bearcat.h"

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
};

// Server-side control of the robots.
struct ControlConfig {
  double command_expiry_s = 0.6;  // every motion command tells the driver to stop after this long without a new one
};

// Geometry query defaults.
struct QueryConfig {
  double clearance_max_distance_m = 5.0;  // search radius when the query leaves it 0
};

// Everything occgeod can be configured with; file keys mirror the field names.
struct ServerConfig {
  std::string listen = "127.0.0.1:7700";
  std::filesystem::path data_dir = "occgeo-data";
  std::string log_level = "info";
  std::string default_world = "default";
  LimitsConfig limits;
  ControlConfig control;
  QueryConfig queries;
  mapping::HimmParams himm;
  control::BearcatParams bearcat;

  // Checks every field; throws ConfigError naming the first bad one.
  void validate() const;
};

// Reads a YAML configuration over the defaults; unknown keys are an error naming the key.
ServerConfig load_config(const std::filesystem::path& file);

// Splits "HOST:PORT"; throws ConfigError naming `what` when malformed.
std::pair<std::string, std::uint16_t> split_host_port(const std::string& text, const std::string& what);

}  // namespace occgeo::service
