#pragma once

// A raw protocol socket for tests that need to misbehave as a client: a tiny receive buffer, reads that stop.

#include <array>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/write.hpp>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "occgeo/proto/framing.h"
#include "occgeo/v1/session.pb.h"

namespace occgeo::testing {

// A raw observer socket whose receive buffer is tiny, so the server's writes to it stall as soon as it stops
// reading (a phone on a bad link, a hung process).
class RawClient {
 public:
  explicit RawClient(std::uint16_t port, int receive_buffer_bytes = 4096) : socket_(io_) {
    socket_.open(boost::asio::ip::tcp::v4());
    socket_.set_option(boost::asio::socket_base::receive_buffer_size(receive_buffer_bytes));
    socket_.connect({boost::asio::ip::make_address("127.0.0.1"), port});
  }
  void send(const v1::ClientMessage& message) {
    boost::asio::write(socket_, boost::asio::buffer(proto::encode_frame(message)));
  }
  // Already framed bytes (several frames in one write, as a client batching its writes sends them).
  void send_bytes(const std::string& frames) { boost::asio::write(socket_, boost::asio::buffer(frames)); }
  // Sends without ever blocking longer than `limit`; false when the bytes could not all be written in time.
  bool send_within(const v1::ClientMessage& message, std::chrono::milliseconds limit) {
    const std::string frame = proto::encode_frame(message);
    bool done = false;
    boost::asio::async_write(socket_, boost::asio::buffer(frame),
                             [&](const boost::system::error_code& error, std::size_t) { done = !error; });
    io_.restart();
    io_.run_for(limit);
    if (!io_.stopped()) {
      boost::system::error_code ignored;
      socket_.cancel(ignored);
      io_.restart();
      io_.run();
      return false;
    }
    return done;
  }
  // The next message, or nullopt at end of stream or after `limit`.
  std::optional<v1::ServerMessage> receive(std::chrono::milliseconds limit) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    v1::ServerMessage message;
    while (decoder_.next(message) != proto::FrameStatus::frame) {
      if (closed_ || std::chrono::steady_clock::now() >= deadline) return std::nullopt;
      std::size_t got = 0;
      boost::system::error_code result = boost::asio::error::would_block;
      socket_.async_read_some(boost::asio::buffer(buffer_), [&](const boost::system::error_code& error, std::size_t n) {
        result = error;
        got = n;
      });
      io_.restart();
      io_.run_until(deadline);
      if (!io_.stopped()) {
        boost::system::error_code ignored;
        socket_.cancel(ignored);
        io_.restart();
        io_.run();
        return std::nullopt;
      }
      if (result) {
        closed_ = true;
        return std::nullopt;
      }
      decoder_.append(buffer_.data(), got);
    }
    return message;
  }
  [[nodiscard]] bool closed() const { return closed_; }

 private:
  boost::asio::io_context io_;
  boost::asio::ip::tcp::socket socket_;
  proto::FrameDecoder decoder_{std::size_t{64} << 20};
  std::array<char, 65536> buffer_{};
  bool closed_ = false;
};

}  // namespace occgeo::testing
