#pragma once

// What the live web view shows, as JSON text frames over its WebSocket (service/web/app.js draws them).
// Built on the HTTP thread from published snapshots only, so a browser never holds up ingest.

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "../core.h"

namespace occgeo::service::http {

// Tiles sent per frame at most: a large map arrives over several frames instead of one huge one.
inline constexpr std::size_t kMaxTilesPerFrame = 32;
// OctoMap slice voxels sent at most (the nearest to the grid's centre are not preferred: the cap only bounds size).
inline constexpr std::size_t kMaxSliceVoxels = 20000;
// PTEM clusters sent at most.
inline constexpr std::size_t kMaxClusters = 4000;

// One browser's view: which world it shows, what of that world's grid it already has, and the slice height.
// Touched only by its connection's thread.
class LiveViewState {
 public:
  explicit LiveViewState(ServerCore& core);

  // The next frame: every robot's state, the shown world's PTEM clusters, and the grid tiles whose contents differ
  // from what this view was last sent (at most kMaxTilesPerFrame; "map_complete" tells whether more are waiting).
  // The OctoMap slice is included when the octree or the slice height changed, at most once a second.
  [[nodiscard]] std::string next_frame();

  // Applies a message from the page: {"type":"select","world":W,"slice_z_m":Z} or
  // {"type":"estop","robot":ID}. Returns a JSON reply for the page, or an error naming the field.
  [[nodiscard]] std::string handle_message(std::string_view text);

 private:
  void select_world(const std::string& name);

  ServerCore& core_;
  std::string world_;
  std::uint64_t sent_grid_version_ = 0;
  bool map_complete_ = false;
  std::unordered_map<std::uint64_t, std::uint64_t> sent_tile_hashes_;  // tile key -> FNV-1a of its cells
  double slice_z_m_ = 0.3;
  std::optional<std::uint64_t> sent_octomap_version_;
  std::optional<double> sent_slice_z_m_;
  std::chrono::steady_clock::time_point last_slice_at_{};
  std::uint64_t frame_seq_ = 0;
};

// Appends the bytes as a quoted base64 JSON string (RFC 4648, padded).
void append_base64(std::string& out, const std::vector<std::uint8_t>& bytes);

// Engages a robot's e-stop from the web view, under the protocol's rule: anyone may engage, only the lease holder
// releases (so the page can only engage). Returns false when no robot has this id.
bool engage_estop_from_web(ServerCore& core, const std::string& robot_id);

}  // namespace occgeo::service::http
