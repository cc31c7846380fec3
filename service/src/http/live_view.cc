#include "live_view.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>
#include <vector>

#include "../handlers/robot_control.h"
#include "../validation.h"
#include "occgeo/geometry/fnv1a.h"
#include "occgeo/proto/labels.h"
#include "occgeo/service/log.h"

namespace occgeo::service::http {

namespace {

void append_string(std::string& out, std::string_view text) { log::append_json_string(out, text); }

// Shortest text that reads back as the same double, so the page draws exactly the pose the status reports.
void append_number(std::string& out, double value) {
  if (!std::isfinite(value)) {
    out += "null";
    return;
  }
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  out.append(buffer, result.ptr);
}

// A coordinate to the millimetre: finer than any map cell drawn, and it keeps frames small.
void append_millimetres(std::string& out, double value) {
  if (!std::isfinite(value)) {
    out += "null";
    return;
  }
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value, std::chars_format::fixed, 3);
  out.append(buffer, result.ptr);
}

// [[x, y], ...] of world-frame points, millimetres.
template <typename Point>
void append_points(std::string& out, const std::vector<Point>& points) {
  out += '[';
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (i > 0) out += ',';
    out += '[';
    append_millimetres(out, static_cast<double>(points[i].x()));
    out += ',';
    append_millimetres(out, static_cast<double>(points[i].y()));
    out += ']';
  }
  out += ']';
}

void append_number(std::string& out, std::uint64_t value) { out += std::to_string(value); }
void append_number(std::string& out, std::int64_t value) { out += std::to_string(value); }

std::uint64_t tile_key(std::int32_t tx, std::int32_t ty) {
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(tx)) << 32) | static_cast<std::uint32_t>(ty);
}

// Floor division, for tiles of negative cell indices.
std::int32_t floor_div(std::int32_t a, std::int32_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

void append_footprint(std::string& out, const geometry::Footprint& footprint) {
  if (const auto* box = std::get_if<geometry::BoxFootprint>(&footprint)) {
    out += R"({"shape":"box","length_m":)";
    append_number(out, box->length);
    out += R"(,"width_m":)";
    append_number(out, box->width);
    out += R"(,"center_x_m":)";
    append_number(out, box->center_x);
    out += '}';
  } else if (const auto* cylinder = std::get_if<geometry::CylinderFootprint>(&footprint)) {
    out += R"({"shape":"cylinder","radius_m":)";
    append_number(out, cylinder->radius);
    out += '}';
  } else if (const auto* polygon = std::get_if<geometry::ConvexPolygonFootprint>(&footprint)) {
    // base_link vertices, counter-clockwise, metres.
    out += R"({"shape":"polygon","vertices_m":[)";
    for (std::size_t k = 0; k < polygon->vertices_B.size(); ++k) {
      if (k > 0) out += ',';
      out += '[';
      append_number(out, polygon->vertices_B[k].x());
      out += ',';
      append_number(out, polygon->vertices_B[k].y());
      out += ']';
    }
    out += "]}";
  } else {
    out += "null";
  }
}

// Every robot's state; the scan and the path only for robots of the shown world (the page draws no others).
void append_robots(std::string& out, ServerCore& core, const std::string& shown_world) {
  out += R"("robots":[)";
  bool first = true;
  for (const auto& robot : core.robots()) {
    const RobotState state = robot->state();
    const ControlState control = robot->control().state();
    if (!first) out += ',';
    first = false;
    out += R"({"id":)";
    append_string(out, robot->model().id);
    out += R"(,"world":)";
    append_string(out, robot->world().name());
    out += R"(,"model":)";
    append_string(out, robot->model().model);
    out += R"(,"connected":)";
    out += state.connected ? "true" : "false";
    out += R"(,"pose":)";
    if (state.X_WB) {
      out += R"({"x":)";
      append_number(out, state.X_WB->x);
      out += R"(,"y":)";
      append_number(out, state.X_WB->y);
      out += R"(,"theta":)";
      append_number(out, state.X_WB->theta);
      out += '}';
    } else {
      out += "null";
    }
    out += R"(,"footprint":)";
    append_footprint(out, robot->model().footprint);
    out += R"(,"behaviour":)";
    append_string(out, proto::behaviour_label(control.behaviour));
    out += R"(,"behaviour_state":)";
    append_string(out, proto::behaviour_state_label(state.behaviour_state));
    out += R"(,"estop":)";
    out += control.estop ? "true" : "false";
    out += R"(,"sensor_stale":)";
    out += control.sensor_stale ? "true" : "false";
    out += R"(,"lease_holder":)";
    if (control.lease) {
      append_string(out, control.lease->client_name + " (session " + std::to_string(control.lease->session_id) + ")");
    } else {
      out += "null";
    }
    out += R"(,"linear_mps":)";
    append_number(out, state.last_linear_mps);
    out += R"(,"angular_radps":)";
    append_number(out, state.last_angular_radps);
    out += R"(,"scans_ingested":)";
    append_number(out, state.scans_ingested);
    // The safety guard's verdict on the latest command, as one line for the page; null before it checked one.
    out += R"(,"guard":)";
    if (state.guard.checked()) {
      std::string verdict = state.guard.action();
      if (!state.guard.zone().empty()) verdict += " (" + state.guard.zone() + " zone, " + state.guard.model() + ")";
      append_string(out, verdict);
    } else {
      out += "null";
    }
    const bool shown = robot->world().name() == shown_world;
    out += R"(,"scan":)";
    if (shown && state.scan_stamp_s && state.scan_W) {
      out += R"({"stamp_s":)";
      append_number(out, *state.scan_stamp_s);
      out += R"(,"points":)";
      append_points(out, *state.scan_W);
      out += '}';
    } else {
      out += "null";
    }
    out += R"(,"path":)";
    if (shown) {
      append_points(out, state.path());
    } else {
      out += "[]";
    }
    out += '}';
  }
  out += ']';
}

// The string value of "key":"value" in a flat JSON object (the page's messages have no escapes); nullopt if absent.
// The value of a message's key as a string or a finite number; nullopt when absent or of another type.
std::optional<std::string> string_field(const nlohmann::json& message, const char* key) {
  const auto it = message.find(key);
  if (it == message.end() || !it->is_string()) return std::nullopt;
  return it->get<std::string>();
}

std::optional<double> number_field(const nlohmann::json& message, const char* key) {
  const auto it = message.find(key);
  if (it == message.end() || !it->is_number()) return std::nullopt;
  const double value = it->get<double>();
  if (!std::isfinite(value)) return std::nullopt;
  return value;
}

std::string error_reply(std::string_view field, std::string_view message) {
  std::string out = R"({"type":"error","field":)";
  append_string(out, field);
  out += R"(,"message":)";
  append_string(out, message);
  return out + "}";
}

}  // namespace

void append_base64(std::string& out, const std::vector<std::uint8_t>& bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  out += '"';
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const std::uint32_t n = (std::uint32_t{bytes[i]} << 16) | (std::uint32_t{bytes[i + 1]} << 8) | bytes[i + 2];
    out += kAlphabet[(n >> 18) & 63];
    out += kAlphabet[(n >> 12) & 63];
    out += kAlphabet[(n >> 6) & 63];
    out += kAlphabet[n & 63];
  }
  if (i + 1 == bytes.size()) {
    const std::uint32_t n = std::uint32_t{bytes[i]} << 16;
    out += kAlphabet[(n >> 18) & 63];
    out += kAlphabet[(n >> 12) & 63];
    out += "==";
  } else if (i + 2 == bytes.size()) {
    const std::uint32_t n = (std::uint32_t{bytes[i]} << 16) | (std::uint32_t{bytes[i + 1]} << 8);
    out += kAlphabet[(n >> 18) & 63];
    out += kAlphabet[(n >> 12) & 63];
    out += kAlphabet[(n >> 6) & 63];
    out += '=';
  }
  out += '"';
}

LiveViewState::LiveViewState(ServerCore& core) : core_(core), world_(core.config().default_world) {
  // Show where the robots are when the default world has none of them.
  const auto robots = core_.robots();
  const bool default_has_robot =
      std::any_of(robots.begin(), robots.end(), [&](const auto& robot) { return robot->world().name() == world_; });
  if (!default_has_robot && !robots.empty()) world_ = robots.front()->world().name();
}

void LiveViewState::select_world(const std::string& name) {
  if (name == world_) return;
  world_ = name;
  sent_tile_hashes_.clear();
  sent_grid_version_ = 0;
  map_complete_ = false;
  sent_octomap_version_.reset();
}

std::string LiveViewState::next_frame() {
  std::string out;
  out.reserve(16384);
  out += R"({"type":"frame","seq":)";
  append_number(out, ++frame_seq_);
  out += R"(,"worlds":[)";
  bool first = true;
  for (const auto& world : core_.worlds()) {
    if (!first) out += ',';
    first = false;
    append_string(out, world->name());
  }
  out += "],";
  append_robots(out, core_, world_);

  out += R"(,"world":)";
  append_string(out, world_);
  const auto world = core_.find_world(world_);
  if (!world) {
    out += R"(,"map":null})";
    return out;
  }
  const WorldSnapshot snapshots = world->snapshots();
  const auto& grid = *snapshots.grid;
  const std::int32_t tile_cells = core_.config().himm.tile_cells;

  out += R"(,"map":{"version":)";
  append_number(out, grid.version());
  out += R"(,"cell_size_m":)";
  append_number(out, grid.cell_size());
  out += R"(,"tile_cells":)";
  append_number(out, std::int64_t{tile_cells});
  out += R"(,"occupied_threshold":)";
  append_number(out, std::int64_t{grid.occupied_threshold()});
  out += R"(,"max_certainty":)";
  append_number(out, std::int64_t{grid.max_certainty()});
  out += R"(,"occupied_cells":)";
  append_number(out, std::uint64_t{grid.occupied_cell_count()});

  // Changes since what this view has: only tiles whose cells differ from those last sent. A new grid version
  // restarts the scan; an unchanged one resumes it when the previous frame hit the per-frame cap.
  out += R"(,"tiles":[)";
  std::size_t tiles_sent = 0;
  bool complete = true;
  if (grid.version() != sent_grid_version_ || !map_complete_) {
    if (const auto bounds = grid.tile_bounds()) {
      const std::int32_t tx0 = floor_div(bounds->min.ix, tile_cells);
      const std::int32_t tx1 = floor_div(bounds->max.ix, tile_cells);
      const std::int32_t ty0 = floor_div(bounds->min.iy, tile_cells);
      const std::int32_t ty1 = floor_div(bounds->max.iy, tile_cells);
      for (std::int32_t ty = ty0; ty <= ty1 && complete; ++ty) {
        for (std::int32_t tx = tx0; tx <= tx1; ++tx) {
          const auto cells = grid.window({tx * tile_cells, ty * tile_cells}, tile_cells, tile_cells);
          const std::uint64_t hash = geometry::fnv1a(std::span<const std::uint8_t>(cells));
          const std::uint64_t key = tile_key(tx, ty);
          const auto known = sent_tile_hashes_.find(key);
          if (known == sent_tile_hashes_.end()) {
            const bool unobserved =
                std::all_of(cells.begin(), cells.end(), [](std::uint8_t c) { return c == mapping::kUnobserved; });
            if (unobserved) continue;  // nothing to draw, and the page starts with nothing
          } else if (known->second == hash) {
            continue;
          }
          if (tiles_sent == kMaxTilesPerFrame) {
            complete = false;
            break;
          }
          if (tiles_sent > 0) out += ',';
          out += R"({"tx":)";
          append_number(out, std::int64_t{tx});
          out += R"(,"ty":)";
          append_number(out, std::int64_t{ty});
          out += R"(,"cells":)";
          append_base64(out, cells);
          out += '}';
          sent_tile_hashes_[key] = hash;
          ++tiles_sent;
        }
      }
    }
    sent_grid_version_ = grid.version();
    map_complete_ = complete;
  }
  out += R"(],"map_complete":)";
  out += complete ? "true" : "false";
  out += '}';

  out += R"(,"ptem":{"restricted_threshold":)";
  if (const auto f_r = snapshots.ptem->restricted_threshold()) {
    append_number(out, *f_r);
  } else {
    out += "null";
  }
  out += R"(,"clusters":[)";
  std::size_t cluster_count = 0;
  for (const auto& cluster : snapshots.ptem->clusters()) {
    if (cluster_count == kMaxClusters) break;
    if (cluster_count++ > 0) out += ',';
    out += '[';
    append_number(out, cluster.centre_W.x());
    out += ',';
    append_number(out, cluster.centre_W.y());
    out += ',';
    append_number(out, cluster.radius_m);
    out += ',';
    out += cluster.threshold_reachable ? '1' : '0';
    out += ']';
  }
  out += "]}";

  // The OctoMap's occupied voxels crossing the chosen height, over the grid's extent (or 20 m around the origin).
  const auto now = std::chrono::steady_clock::now();
  const auto& octomap = snapshots.octomap;
  const bool slice_changed = sent_octomap_version_ != octomap->version() || sent_slice_z_m_ != slice_z_m_;
  if (slice_changed && now - last_slice_at_ >= std::chrono::seconds(1)) {
    last_slice_at_ = now;
    sent_octomap_version_ = octomap->version();
    sent_slice_z_m_ = slice_z_m_;
    Eigen::Vector3d min_W(-20.0, -20.0, slice_z_m_);
    Eigen::Vector3d max_W(20.0, 20.0, slice_z_m_);
    if (const auto bounds = grid.tile_bounds()) {
      min_W.head<2>() = Eigen::Vector2d(bounds->min.ix, bounds->min.iy) * grid.cell_size();
      max_W.head<2>() = Eigen::Vector2d(bounds->max.ix + 1, bounds->max.iy + 1) * grid.cell_size();
    }
    out += R"(,"octomap_slice":{"z_m":)";
    append_number(out, slice_z_m_);
    out += R"(,"version":)";
    append_number(out, octomap->version());
    out += R"(,"voxels":[)";
    std::size_t voxels = 0;
    octomap->for_each_occupied(min_W, max_W, [&](const mapping::OctoVoxel& voxel) {
      if (voxels++ > 0) out += ',';
      out += '[';
      append_number(out, voxel.center_W.x());
      out += ',';
      append_number(out, voxel.center_W.y());
      out += ',';
      append_number(out, voxel.size_m);
      out += ']';
      return voxels < kMaxSliceVoxels;
    });
    out += "]}";
  }
  out += '}';
  return out;
}

std::string LiveViewState::handle_message(std::string_view text) {
  // Any valid JSON object, whatever its key order, spacing, escapes or extra keys.
  const nlohmann::json message = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!message.is_object()) return error_reply("message", "not a JSON object");
  const auto type = string_field(message, "type");
  if (!type) return error_reply("type", "every message needs a \"type\": \"select\" or \"estop\"");
  if (*type == "select") {
    if (const auto world = string_field(message, "world")) {
      if (!core_.find_world(*world)) return error_reply("world", "no world '" + *world + "' exists");
      select_world(*world);
    }
    if (message.contains("slice_z_m")) {
      const auto z = number_field(message, "slice_z_m");
      if (!z || std::abs(*z) > 1000.0) return error_reply("slice_z_m", "must be a finite height in metres");
      slice_z_m_ = *z;
    }
    return R"({"type":"selected"})";
  }
  if (*type == "estop") {
    const auto robot = string_field(message, "robot");
    if (!robot || !valid_name(*robot)) return error_reply("robot", "name the robot whose e-stop to engage");
    if (!engage_estop_from_web(core_, *robot)) return error_reply("robot", "no robot '" + *robot + "' exists");
    std::string out = R"({"type":"estop","robot":)";
    append_string(out, *robot);
    return out + R"(,"engaged":true})";
  }
  return error_reply("type", "unknown message type '" + *type + "'; expected \"select\" or \"estop\"");
}

bool engage_estop_from_web(ServerCore& core, const std::string& robot_id) {
  const auto robot = core.find_robot(robot_id);
  if (!robot) return false;
  bool engaged_now = false;
  robot->control().update([&](ControlState& control) {
    engaged_now = !control.estop;
    control.estop = true;
  });
  // As for a protocol EStop: the robot stops now rather than at its next scan.
  send_stop_to_driver(*robot, v1::BEHAVIOUR_STATE_ESTOP, core.config().control.command_expiry_s);
  if (engaged_now) log::warn("estop", {{"robot", robot_id}, {"source", "web"}, {"engaged", true}});
  return true;
}

}  // namespace occgeo::service::http
