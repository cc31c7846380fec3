#include "occgeo/service/server.h"

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/strand.hpp>
#include <mutex>
#include <thread>

#include "core.h"
#include "occgeo/mapfile/map_file.h"
#include "occgeo/service/log.h"
#include "session.h"
#include "validation.h"

namespace occgeo::service {

using asio::ip::tcp;

namespace {

std::filesystem::path world_dir(const std::filesystem::path& data_dir, const std::string& world) {
  return data_dir / "worlds" / world;
}

// Loads every world saved in the data directory (grid.yaml and/or octomap.bt; a world whose grid
// saw nothing has only the octree); a damaged map stops the start with its name.
void restore_worlds(ServerCore& core) {
  const auto worlds_dir = core.config().data_dir / "worlds";
  if (!std::filesystem::is_directory(worlds_dir)) return;
  for (const auto& entry : std::filesystem::directory_iterator(worlds_dir)) {
    const auto yaml = entry.path() / "grid.yaml";
    const bool has_grid = std::filesystem::exists(yaml);
    if (!entry.is_directory() || (!has_grid && !std::filesystem::exists(entry.path() / "octomap.bt"))) continue;
    const std::string name = entry.path().filename().string();
    if (!valid_name(name)) {
      log::warn("restore_skipped", {{"path", entry.path().string()}, {"reason", "not a valid world name"}});
      continue;
    }
    mapping::HimmGrid grid = has_grid ? mapping::HimmGrid::from_image(mapfile::read_map_yaml(yaml), core.config().himm)
                                      : mapping::HimmGrid(core.config().himm);
    if (has_grid) {
      log::info("world_restored",
                {{"world", name}, {"file", yaml.string()}, {"occupied_cells", grid.occupied_cell_count()}});
    }
    auto world = core.add_world(name, std::move(grid));
    // The OctoMap saved beside the grid, if any; no strand work exists yet, so this is the writer's thread.
    if (const auto bt = entry.path() / "octomap.bt"; std::filesystem::exists(bt)) {
      world->octomap_on_strand().load_bt(bt);
      const auto snapshot = world->publish_octomap_on_strand();
      log::info("octomap_restored", {{"world", name}, {"file", bt.string()}, {"leaves", snapshot->leaf_count()}});
    }
  }
}

// Writes each world's grid as PGM+YAML and its OctoMap as octomap.bt, via a temporary folder renamed into place. Runs
// after the worker pools have been joined, so no strand is mutating the grids any more.
void save_worlds(ServerCore& core) {
  for (const auto& world : core.worlds()) {
    const bool has_octomap = world->octomap_on_strand().leaf_count() > 0;
    if (world->grid_on_strand().tile_count() == 0 && !has_octomap) continue;  // nothing observed, nothing to keep
    const auto final_dir = world_dir(core.config().data_dir, world->name());
    const auto temp_dir = final_dir.string() + ".saving";
    try {
      std::filesystem::remove_all(temp_dir);
      std::filesystem::create_directories(temp_dir);
      if (world->grid_on_strand().tile_count() > 0) {
        mapfile::write_map(std::filesystem::path(temp_dir) / "grid", world->grid_on_strand().to_image());
      }
      if (has_octomap) world->octomap_on_strand().save_bt(std::filesystem::path(temp_dir) / "octomap.bt");
      std::filesystem::remove_all(final_dir);
      std::filesystem::rename(temp_dir, final_dir);
      log::info("world_saved", {{"world", world->name()}, {"dir", final_dir.string()}});
    } catch (const std::exception& e) {
      log::error("world_save_failed", {{"world", world->name()}, {"error", e.what()}});
    }
  }
}

}  // namespace

struct Server::Impl {
  explicit Impl(ServerConfig config) : core(std::move(config)) {}

  ServerCore core;
  asio::io_context net{1};
  tcp::acceptor acceptor{net};
  asio::signal_set signals{net, SIGINT, SIGTERM};
  std::mutex sessions_mutex;
  std::vector<std::weak_ptr<Session>> sessions;

  void accept() {
    acceptor.async_accept(asio::make_strand(net), [this](const boost::system::error_code& error, tcp::socket socket) {
      if (error) {
        if (error != asio::error::operation_aborted) {
          log::warn("accept_failed", {{"error", error.message()}});
          accept();
        }
        return;
      }
      if (core.sessions.load() >= core.config().limits.max_clients) {
        log::warn("session_refused", {{"reason", "client limit reached"}});
        boost::system::error_code ignored;
        socket.close(ignored);
      } else {
        auto session = std::make_shared<Session>(core, std::move(socket), core.next_session_id++);
        {
          const std::lock_guard lock(sessions_mutex);
          std::erase_if(sessions, [](const auto& weak) { return weak.expired(); });
          sessions.push_back(session);
        }
        session->start();
      }
      accept();
    });
  }

  void shutdown() {
    boost::system::error_code ignored;
    acceptor.close(ignored);
    signals.cancel(ignored);
    const std::lock_guard lock(sessions_mutex);
    for (const auto& weak : sessions) {
      if (auto session = weak.lock()) session->close();
    }
  }
};

Server::Server(ServerConfig config) {
  config.validate();
  log::set_level(log::parse_level(config.log_level));
  impl_ = std::make_unique<Impl>(std::move(config));
  restore_worlds(impl_->core);
  impl_->core.world(impl_->core.config().default_world);

  const auto [host, port] = split_host_port(impl_->core.config().listen, "listen");
  boost::system::error_code error;
  const auto address = asio::ip::make_address(host, error);
  if (error) throw ConfigError("listen address '" + host + "' is not an IP address");
  const tcp::endpoint endpoint(address, port);
  impl_->acceptor.open(endpoint.protocol());
  impl_->acceptor.set_option(tcp::acceptor::reuse_address(true));
  impl_->acceptor.bind(endpoint, error);
  if (error) throw std::runtime_error("cannot listen on " + impl_->core.config().listen + ": " + error.message());
  impl_->acceptor.listen();
}

Server::~Server() = default;

std::uint16_t Server::port() const { return impl_->acceptor.local_endpoint().port(); }

void Server::run() {
  impl_->signals.async_wait([this](const boost::system::error_code& error, int signal) {
    if (error) return;
    log::info("signal_received", {{"signal", signal}});
    impl_->shutdown();
  });
  impl_->accept();
  log::info("server_listening", {{"address", impl_->core.config().listen},
                                 {"port", static_cast<unsigned>(port())},
                                 {"data_dir", impl_->core.config().data_dir.string()}});
  impl_->net.run();
  impl_->core.drain();
  save_worlds(impl_->core);
  log::info("server_stopped");
}

void Server::stop() {
  asio::post(impl_->net, [this] { impl_->shutdown(); });
}

}  // namespace occgeo::service
