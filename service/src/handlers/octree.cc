#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <boost/asio/post.hpp>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "handlers.h"
#include "occgeo/service/log.h"

namespace occgeo::service {

namespace {

// A file name of its own for each export, in the system's temporary folder.
std::filesystem::path export_path(const std::string& world) {
  static std::atomic<std::uint64_t> counter{0};
  return std::filesystem::temp_directory_path() /
         ("occgeod-" + std::to_string(::getpid()) + "-" + world + "-" + std::to_string(counter++) + ".bt");
}

}  // namespace

// The export runs on the world's ingest strand: OctoMap's .bt writer needs the live tree (the
// snapshot API has no writer), so it publishes a snapshot (O(nodes)), writes the tree to a
// temporary file (O(nodes)) and reads it back. Ingest of that world waits meanwhile (about the
// cost of two publishes); queries do not.
void handle_octree_request(const SessionPtr& session, std::uint64_t request_id, const v1::OctreeRequest& request) {
  const ServerConfig& config = session->core().config();
  const std::string name = request.world().empty() ? config.default_world : request.world();
  auto world = session->core().find_world(name);
  if (!world) {
    session->send_error(v1::ERROR_UNKNOWN_WORLD, "octree.world", "no world '" + name + "' exists", request_id);
    return;
  }
  // A reply must also fit in the client's send queue, with room for the replies around it.
  const std::size_t max_bytes = std::min(config.limits.max_octree_reply_bytes, config.limits.max_send_queue_bytes / 2);
  asio::post(world->strand(), [session, world, request_id, max_bytes] {
    run_guarded(session, "octree", request_id, [&] {
      const auto snapshot = world->publish_octomap_on_strand();
      const std::filesystem::path path = export_path(world->name());
      std::string bytes;
      try {
        world->with_octree_on_strand([&](mapping::OctoMapModel& octomap) { octomap.save_bt(path); });
        const auto size = std::filesystem::file_size(path);
        if (size > max_bytes) {
          std::filesystem::remove(path);
          session->send_error(v1::ERROR_INVALID_ARGUMENT, "octree.world",
                              "world '" + world->name() + "' has an OctoMap of " + std::to_string(size) +
                                  " bytes, over the reply limit of " + std::to_string(max_bytes) +
                                  " (limits.max_octree_reply_bytes, or half of limits.max_send_queue_bytes)",
                              request_id);
          return;
        }
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
      } catch (...) {
        std::error_code ignored;
        std::filesystem::remove(path, ignored);
        throw;
      }
      std::filesystem::remove(path);
      v1::ServerMessage reply;
      auto* out = reply.mutable_octree();
      reply.set_request_id(request_id);
      out->set_world(world->name());
      out->set_version(snapshot->version());
      out->set_resolution_m(snapshot->resolution());
      out->set_node_count(snapshot->node_count());
      out->set_leaf_count(snapshot->leaf_count());
      log::info("octree_exported",
                {{"world", world->name()}, {"bytes", bytes.size()}, {"nodes", snapshot->node_count()}});
      out->set_bt(std::move(bytes));
      session->send(reply);
    });
  });
}

}  // namespace occgeo::service
