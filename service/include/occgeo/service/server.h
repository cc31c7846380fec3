#pragma once

#include <cstdint>
#include <memory>

#include "occgeo/service/config.h"

namespace occgeo::service {

// The occgeod server: accepts sessions on the configured address, keeps the worlds, restores
// them from the data directory on start and saves them there on stop.
class Server {
 public:
  // Restores the data directory and binds the listen address; throws on failure.
  explicit Server(ServerConfig config);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // The bound TCP port (useful when the configuration asked for port 0).
  [[nodiscard]] std::uint16_t port() const;
  // Serves until stop() or SIGINT/SIGTERM, then saves the worlds.
  void run();
  // Asks run() to return; safe from any thread.
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace occgeo::service
