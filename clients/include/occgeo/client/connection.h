#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "occgeo/v1/session.pb.h"

namespace occgeo::client {

// Raised for connection failures, protocol violations and errors the server reports.
class ClientError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A server address. Parsed from "HOST:PORT"; the default is the server's default listen address.
struct Endpoint {
  std::string host = "127.0.0.1";
  std::uint16_t port = 7700;

  // Parses "HOST:PORT"; throws ClientError naming the text when it is malformed.
  static Endpoint parse(std::string_view text);
  [[nodiscard]] std::string to_string() const;
};

// One blocking TCP connection to occgeod speaking occgeo.v1 delimited frames. Not thread-safe:
// one thread sends and receives.
class Connection {
 public:
  // Connects within `timeout`; throws ClientError on failure.
  static Connection open(const Endpoint& endpoint, std::chrono::milliseconds timeout = std::chrono::seconds(5));

  Connection(Connection&&) noexcept;
  Connection& operator=(Connection&&) noexcept;
  ~Connection();

  // Sends the hello and waits for the welcome; throws ClientError carrying the server's error.
  v1::Welcome hello(const v1::Hello& hello, std::chrono::milliseconds timeout = std::chrono::seconds(5));

  // Queues one framed message and writes it out before returning.
  void send(const v1::ClientMessage& message);

  // Waits up to `timeout` for the next message; nullopt when none arrived in time. Throws
  // ClientError when the server closed the connection or sent an undecodable frame.
  std::optional<v1::ServerMessage> receive(std::chrono::milliseconds timeout);

  // Sends `request` (its envelope's request_id set to `request_id`) and waits for the reply whose request_id matches,
  // skipping unrelated messages; a server Error with that request_id is thrown as ClientError.
  v1::ServerMessage call(const v1::ClientMessage& request, std::uint64_t request_id,
                         std::chrono::milliseconds timeout = std::chrono::seconds(10));

  void close();

 private:
  struct Impl;
  explicit Connection(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The request_id a server message answers (a reply's or an Error's); 0 for messages that answer no
// request (Welcome, ScanAck, MotionCommand).
std::uint64_t reply_request_id(const v1::ServerMessage& message);

// "field: message" text for a server Error, for printing and exceptions.
std::string describe(const v1::Error& error);

}  // namespace occgeo::client
