#include "occgeo/client/connection.h"

#include <array>
#include <boost/asio.hpp>
#include <charconv>
#include <deque>

#include "occgeo/proto/framing.h"

namespace occgeo::client {

namespace asio = boost::asio;
using asio::ip::tcp;

namespace {
// Replies such as whole-map windows can be large; the client accepts up to this frame size.
constexpr std::size_t kClientMaxFrameBytes = std::size_t{256} * 1024 * 1024;
}  // namespace

Endpoint Endpoint::parse(std::string_view text) {
  const auto colon = text.rfind(':');
  if (colon == std::string_view::npos || colon == 0 || colon + 1 == text.size()) {
    throw ClientError("server address '" + std::string(text) + "' is not HOST:PORT");
  }
  Endpoint endpoint;
  endpoint.host = std::string(text.substr(0, colon));
  const std::string_view port_text = text.substr(colon + 1);
  unsigned port = 0;
  const auto [end, error] = std::from_chars(port_text.data(), port_text.data() + port_text.size(), port);
  if (error != std::errc() || end != port_text.data() + port_text.size() || port == 0 || port > 65535) {
    throw ClientError("server address '" + std::string(text) + "' has an invalid port");
  }
  endpoint.port = static_cast<std::uint16_t>(port);
  return endpoint;
}

std::string Endpoint::to_string() const { return host + ":" + std::to_string(port); }

std::string describe(const v1::Error& error) {
  std::string text = v1::ErrorCode_Name(error.code());
  if (!error.field().empty()) text += " " + error.field();
  return text + ": " + error.message();
}

struct Connection::Impl {
  asio::io_context io;
  tcp::socket socket{io};
  proto::FrameDecoder decoder{kClientMaxFrameBytes};
  std::deque<v1::ServerMessage> pending;  // decoded but not yet returned
  std::array<char, std::size_t{64} * 1024> read_buffer{};

  // Runs the io_context until `done` or the deadline; returns false on timeout.
  bool run_until(const bool& done, std::chrono::milliseconds timeout) {
    io.restart();
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (!done) {
      const auto now = std::chrono::steady_clock::now();
      if (now >= deadline) return false;
      io.run_one_for(deadline - now);
    }
    return true;
  }

  // Decodes every complete frame in the buffer into `pending`.
  void drain_decoder() {
    while (true) {
      v1::ServerMessage message;
      switch (decoder.next(message)) {
        case proto::FrameStatus::frame:
          pending.push_back(std::move(message));
          continue;
        case proto::FrameStatus::need_more:
          return;
        case proto::FrameStatus::too_large:
          throw ClientError("server sent a frame over " + std::to_string(kClientMaxFrameBytes) + " bytes");
        case proto::FrameStatus::malformed:
          throw ClientError("server sent an undecodable frame");
      }
    }
  }
};

Connection::Connection(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Connection::Connection(Connection&&) noexcept = default;
Connection& Connection::operator=(Connection&&) noexcept = default;
Connection::~Connection() = default;

Connection Connection::open(const Endpoint& endpoint, std::chrono::milliseconds timeout) {
  auto impl = std::make_unique<Impl>();
  boost::system::error_code resolve_error;
  tcp::resolver resolver(impl->io);
  const auto endpoints = resolver.resolve(endpoint.host, std::to_string(endpoint.port), resolve_error);
  if (resolve_error) {
    throw ClientError("cannot resolve " + endpoint.to_string() + ": " + resolve_error.message());
  }
  bool done = false;
  boost::system::error_code connect_error;
  asio::async_connect(impl->socket, endpoints, [&](const boost::system::error_code& error, const tcp::endpoint&) {
    connect_error = error;
    done = true;
  });
  if (!impl->run_until(done, timeout)) {
    throw ClientError("timed out connecting to " + endpoint.to_string());
  }
  if (connect_error) {
    throw ClientError("cannot connect to " + endpoint.to_string() + ": " + connect_error.message());
  }
  impl->socket.set_option(tcp::no_delay(true));
  return Connection(std::move(impl));
}

v1::Welcome Connection::hello(const v1::Hello& hello, std::chrono::milliseconds timeout) {
  v1::ClientMessage message;
  *message.mutable_hello() = hello;
  send(message);
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    const auto reply =
        receive(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()));
    if (!reply) break;
    if (reply->has_welcome()) return reply->welcome();
    if (reply->has_error()) throw ClientError("server refused hello: " + describe(reply->error()));
  }
  throw ClientError("timed out waiting for the server's welcome");
}

void Connection::send(const v1::ClientMessage& message) {
  const std::string frame = proto::encode_frame(message);
  boost::system::error_code error;
  asio::write(impl_->socket, asio::buffer(frame), error);
  if (error) throw ClientError("send failed: " + error.message());
}

std::optional<v1::ServerMessage> Connection::receive(std::chrono::milliseconds timeout) {
  impl_->drain_decoder();
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (impl_->pending.empty()) {
    bool done = false;
    boost::system::error_code read_error;
    std::size_t read_size = 0;
    impl_->socket.async_read_some(asio::buffer(impl_->read_buffer),
                                  [&](const boost::system::error_code& error, std::size_t size) {
                                    read_error = error;
                                    read_size = size;
                                    done = true;
                                  });
    const auto now = std::chrono::steady_clock::now();
    const auto remaining = now < deadline ? std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now)
                                          : std::chrono::milliseconds(0);
    if (!impl_->run_until(done, remaining)) {
      impl_->socket.cancel();
      impl_->run_until(done, std::chrono::seconds(1));
      if (read_size > 0) impl_->decoder.append(impl_->read_buffer.data(), read_size);
      impl_->drain_decoder();
      break;
    }
    if (read_error) {
      if (read_error == asio::error::eof) throw ClientError("server closed the connection");
      throw ClientError("receive failed: " + read_error.message());
    }
    impl_->decoder.append(impl_->read_buffer.data(), read_size);
    impl_->drain_decoder();
  }
  if (impl_->pending.empty()) return std::nullopt;
  v1::ServerMessage message = std::move(impl_->pending.front());
  impl_->pending.pop_front();
  return message;
}

std::uint64_t reply_request_id(const v1::ServerMessage& message) {
  switch (message.body_case()) {
    case v1::ServerMessage::kCollision:
      return message.collision().request_id();
    case v1::ServerMessage::kClearance:
      return message.clearance().request_id();
    case v1::ServerMessage::kStatus:
      return message.status().request_id();
    case v1::ServerMessage::kGrid:
      return message.grid().request_id();
    case v1::ServerMessage::kPtem:
      return message.ptem().request_id();
    case v1::ServerMessage::kOctree:
      return message.octree().request_id();
    case v1::ServerMessage::kLease:
      return message.lease().request_id();
    case v1::ServerMessage::kDrive:
      return message.drive().request_id();
    case v1::ServerMessage::kEstop:
      return message.estop().request_id();
    case v1::ServerMessage::kError:
      return message.error().request_id();
    default:
      return 0;
  }
}

v1::ServerMessage Connection::call(const v1::ClientMessage& request, std::uint64_t request_id,
                                   std::chrono::milliseconds timeout) {
  send(request);
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (true) {
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline) break;
    auto reply = receive(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now));
    if (!reply) break;
    if (reply_request_id(*reply) != request_id) continue;
    if (reply->has_error()) throw ClientError(describe(reply->error()));
    return std::move(*reply);
  }
  throw ClientError("timed out waiting for the reply to request " + std::to_string(request_id));
}

void Connection::close() {
  boost::system::error_code ignored;
  impl_->socket.shutdown(tcp::socket::shutdown_both, ignored);
  impl_->socket.close(ignored);
}

}  // namespace occgeo::client
