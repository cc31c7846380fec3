#pragma once

#include <array>
#include <boost/asio/ip/tcp.hpp>
#include <deque>
#include <memory>
#include <string>

#include "handlers/handlers.h"
#include "occgeo/proto/framing.h"

namespace occgeo::service {

// One client connection. Reads frames on its strand and hands them to the handlers; replies
// from any thread are queued without blocking. A client that lets more than the configured bytes
// pile up unread is disconnected, so a slow client never holds up anyone else.
class Session final : public SessionContext, public std::enable_shared_from_this<Session> {
 public:
  Session(ServerCore& core, asio::ip::tcp::socket socket, std::uint64_t id);
  ~Session() override;

  void start();
  // Closes the connection now (server shutdown).
  void close();

  ServerCore& core() override { return core_; }
  SessionInfo& info() override { return info_; }
  void send(v1::ServerMessage message) override;

 private:
  void read_more();
  void on_read(const boost::system::error_code& error, std::size_t size);
  void enqueue(std::string frame);
  void write_next();
  // Sends an error, then closes once it is written (for a stream that cannot be trusted).
  void fail_stream(v1::ErrorCode code, const std::string& message);
  void shutdown();

  ServerCore& core_;
  asio::ip::tcp::socket socket_;
  SessionInfo info_;
  proto::FrameDecoder decoder_;
  std::array<char, std::size_t{64} * 1024> read_buffer_{};
  std::deque<std::string> outbox_;
  std::size_t outbox_bytes_ = 0;
  bool writing_ = false;
  bool close_after_write_ = false;
  bool closed_ = false;
};

}  // namespace occgeo::service
