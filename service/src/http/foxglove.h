#pragma once

// The Foxglove WebSocket protocol (subprotocol foxglove.websocket.v1), JSON encoding: what occgeod publishes to
// Foxglove Studio and other clients of that protocol, built from published snapshots only. Included by
// http_server.cc, which runs the sessions.
//
// Channels: 1 "/map", foxglove.Grid of the world's HIMM certainties (uint8 field "certainty": 0..max_certainty, 255
// never observed), sent when the grid changed, at most once a second; 2 "/scans", foxglove.PointCloud of every robot's
// latest scan in that world (float32 x, y in the world frame), sent when a scan is newer.

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "../core.h"
#include "live_view.h"
#include "occgeo/service/log.h"

namespace occgeo::service::http::foxglove {

inline constexpr const char* kSubprotocol = "foxglove.websocket.v1";
inline constexpr std::uint32_t kMapChannel = 1;
inline constexpr std::uint32_t kScansChannel = 2;
// A map larger than this many cells is not sent (the /ws view streams it tile by tile instead).
inline constexpr std::size_t kMaxGridCells = 16 * 1024 * 1024;

// The world the Foxglove channels show: the default one, or the first robot's when the default has no robot.
inline std::string shown_world(ServerCore& core) {
  std::string world = core.config().default_world;
  const auto robots = core.robots();
  const bool default_has_robot =
      std::any_of(robots.begin(), robots.end(), [&](const auto& robot) { return robot->world().name() == world; });
  if (!default_has_robot && !robots.empty()) world = robots.front()->world().name();
  return world;
}

inline std::string server_info(std::uint64_t session_id) {
  return R"({"op":"serverInfo","name":"occgeod","capabilities":[],"supportedEncodings":[],"metadata":{},"sessionId":")" +
         std::to_string(session_id) + "\"}";
}

inline std::string advertise() {
  // JSON encoding takes a JSON Schema per channel; these describe the fields sent.
  return R"({"op":"advertise","channels":[)"
         R"({"id":1,"topic":"/map","encoding":"json","schemaName":"foxglove.Grid","schemaEncoding":"jsonschema",)"
         R"("schema":"{\"type\":\"object\",\"properties\":{\"timestamp\":{},\"frame_id\":{},\"pose\":{},)"
         R"(\"column_count\":{},\"cell_size\":{},\"row_stride\":{},\"cell_stride\":{},\"fields\":{},\"data\":{}}}"},)"
         R"({"id":2,"topic":"/scans","encoding":"json","schemaName":"foxglove.PointCloud","schemaEncoding":"jsonschema",)"
         R"("schema":"{\"type\":\"object\",\"properties\":{\"timestamp\":{},\"frame_id\":{},\"pose\":{},)"
         R"(\"point_stride\":{},\"fields\":{},\"data\":{}}}"}]})";
}

// A subscription the client asked for: its id and the channel.
struct Subscription {
  std::uint32_t id = 0;
  std::uint32_t channel = 0;
};

// What a client's text message asks for: {"op":"subscribe","subscriptions":[{"id":I,"channelId":C},...]} or
// {"op":"unsubscribe","subscriptionIds":[I,...]}, parsed as JSON (any key order, extra keys ignored as the protocol
// allows). Other ops are returned with nothing to do; `problem` says why a message was not understood.
struct ClientRequest {
  std::string op;
  std::vector<Subscription> subscribe;
  std::vector<std::uint32_t> unsubscribe;
  std::string problem;
};

inline ClientRequest parse_client_request(const std::string& text) {
  ClientRequest out;
  const nlohmann::json message = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (message.is_discarded() || !message.is_object()) {
    out.problem = "not a JSON object";
    return out;
  }
  const auto op = message.find("op");
  if (op == message.end() || !op->is_string()) {
    out.problem = "no \"op\" string";
    return out;
  }
  out.op = op->get<std::string>();
  const auto id_of = [](const nlohmann::json& value) -> std::optional<std::uint32_t> {
    if (!value.is_number_unsigned() || value.get<std::uint64_t>() > UINT32_MAX) return std::nullopt;
    return static_cast<std::uint32_t>(value.get<std::uint64_t>());
  };
  if (out.op == "subscribe") {
    const auto list = message.find("subscriptions");
    if (list == message.end() || !list->is_array()) {
      out.problem = "subscribe without a \"subscriptions\" array";
      return out;
    }
    for (const nlohmann::json& entry : *list) {
      const auto id = entry.is_object() && entry.contains("id") ? id_of(entry["id"]) : std::nullopt;
      const auto channel = entry.is_object() && entry.contains("channelId") ? id_of(entry["channelId"]) : std::nullopt;
      if (!id || !channel) {
        out.problem = "a subscription without unsigned \"id\" and \"channelId\"";
        continue;
      }
      out.subscribe.push_back({*id, *channel});
    }
  } else if (out.op == "unsubscribe") {
    const auto list = message.find("subscriptionIds");
    if (list == message.end() || !list->is_array()) {
      out.problem = "unsubscribe without a \"subscriptionIds\" array";
      return out;
    }
    for (const nlohmann::json& entry : *list) {
      if (const auto id = id_of(entry)) {
        out.unsubscribe.push_back(*id);
      } else {
        out.problem = "a subscription id that is not an unsigned number";
      }
    }
  }
  return out;
}

inline void append_double(std::string& out, double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, std::isfinite(value) ? value : 0.0);
  out.append(buffer, result.ptr);
}

inline void append_header(std::string& out, double stamp_s, double origin_x, double origin_y) {
  const double sec = std::floor(stamp_s);
  out += R"({"timestamp":{"sec":)" + std::to_string(static_cast<std::int64_t>(sec)) + R"(,"nsec":)" +
         std::to_string(static_cast<std::int64_t>((stamp_s - sec) * 1e9)) +
         R"(},"frame_id":"world","pose":{"position":{"x":)";
  append_double(out, origin_x);
  out += R"(,"y":)";
  append_double(out, origin_y);
  out += R"(,"z":0},"orientation":{"x":0,"y":0,"z":0,"w":1}})";
}

// foxglove.Grid of the world's grid (its allocated tiles); nullopt when it has none or is too large.
inline std::optional<std::string> grid_message(const mapping::GridSnapshot& grid, double stamp_s) {
  const auto bounds = grid.tile_bounds();
  if (!bounds) return std::nullopt;
  const int width = bounds->max.ix - bounds->min.ix + 1;
  const int height = bounds->max.iy - bounds->min.iy + 1;
  if (width <= 0 || height <= 0 || static_cast<std::size_t>(width) * static_cast<std::size_t>(height) > kMaxGridCells) {
    return std::nullopt;
  }
  // Rows from the grid's lowest y upwards, as foxglove.Grid lays them out from its pose.
  const std::vector<std::uint8_t> cells = grid.window(bounds->min, width, height);
  std::string out;
  out.reserve(cells.size() * 4 / 3 + 512);
  append_header(out, stamp_s, bounds->min.ix * grid.cell_size(), bounds->min.iy * grid.cell_size());
  out += R"(,"column_count":)" + std::to_string(width) + R"(,"cell_size":{"x":)";
  append_double(out, grid.cell_size());
  out += R"(,"y":)";
  append_double(out, grid.cell_size());
  out += R"(},"row_stride":)" + std::to_string(width) +
         R"(,"cell_stride":1,"fields":[{"name":"certainty","offset":0,"type":1}],"data":)";
  append_base64(out, cells);
  out += '}';
  return out;
}

// foxglove.PointCloud of the latest scans of the world's robots (float32 x then y, world frame).
inline std::string scans_message(const std::vector<std::vector<Eigen::Vector2f>>& scans_W, double stamp_s) {
  std::vector<std::uint8_t> data;
  for (const auto& scan_W : scans_W) {
    for (const Eigen::Vector2f& p : scan_W) {
      const float xy[2] = {p.x(), p.y()};
      const std::size_t at = data.size();
      data.resize(at + sizeof xy);
      std::memcpy(data.data() + at, xy, sizeof xy);
    }
  }
  std::string out;
  append_header(out, stamp_s, 0.0, 0.0);
  out += R"(,"point_stride":8,"fields":[{"name":"x","offset":0,"type":7},{"name":"y","offset":4,"type":7}],"data":)";
  append_base64(out, data);
  out += '}';
  return out;
}

// A binary Message Data frame: opcode 1, subscription id (uint32 LE), receive time (uint64 ns LE), payload.
inline std::string message_data(std::uint32_t subscription, std::uint64_t time_ns, const std::string& payload) {
  std::string out(1 + 4 + 8, '\0');
  out[0] = '\x01';
  for (int i = 0; i < 4; ++i)
    out[static_cast<std::size_t>(1 + i)] = static_cast<char>((subscription >> (8 * i)) & 0xff);
  for (int i = 0; i < 8; ++i) out[static_cast<std::size_t>(5 + i)] = static_cast<char>((time_ns >> (8 * i)) & 0xff);
  return out + payload;
}

}  // namespace occgeo::service::http::foxglove
