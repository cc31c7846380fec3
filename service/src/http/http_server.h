#pragma once

#include <cstdint>
#include <memory>
#include <string>

namespace occgeo::service {
class ServerCore;
}

namespace occgeo::service::http {

// The HTTP side of occgeod (Boost.Beast), on its own thread so that browsers and scrapers never delay the protocol's
// network thread or ingest:
//   GET /            the live view page (service/web, compiled into the binary)
//   GET /app.js, /style.css
//   GET /metrics     Prometheus text exposition format
//   GET /ws          WebSocket: JSON frames of robots, grid tiles changed since the page's copy, PTEM clusters and
//                    an OctoMap slice, ~10 per second; the page may send "select" and "estop" messages.
//   any WebSocket upgrade asking for subprotocol foxglove.websocket.v1: the grid and the robots' scans as Foxglove
//                    channels (foxglove.h)
class HttpServer {
 public:
  // Binds HOST:PORT now (port 0 picks a free one); throws std::runtime_error when it cannot.
  HttpServer(ServerCore& core, const std::string& listen);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  [[nodiscard]] std::uint16_t port() const;
  // Starts serving on a thread of its own.
  void start();
  // Closes the listener and every connection and joins the thread; idempotent.
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace occgeo::service::http
