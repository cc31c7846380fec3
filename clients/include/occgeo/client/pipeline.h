#pragma once

#include <boost/asio/io_context.hpp>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "occgeo/client/connection.h"
#include "occgeo/v1/session.pb.h"

namespace occgeo::client {

// One request's outcome on a PipelinedConnection.
struct Reply {
  std::uint64_t request_id = 0;
  // The server's answer: the reply message, or an Error carrying this request_id. Empty when `failure` is set.
  v1::ServerMessage message;
  // Non-empty when the connection failed (closed, undecodable frame, timed out) before the answer came.
  std::string failure;
  std::chrono::steady_clock::time_point submitted_at;
  std::chrono::steady_clock::time_point completed_at;

  [[nodiscard]] bool ok() const { return failure.empty() && !message.has_error(); }
  // "field: message" of the server's Error or the transport failure; empty when ok().
  [[nodiscard]] std::string error_text() const;
  [[nodiscard]] std::chrono::nanoseconds latency() const { return completed_at - submitted_at; }
};

using ReplyHandler = std::function<void(Reply&&)>;

// Many requests in flight on one TCP connection: requests are written without waiting for earlier answers (frames
// queued while a write is in progress go out together in the next write), and each answer completes its request by
// request_id, in whatever order the server sends them. At most `max_in_flight` requests are outstanding.
//
// Two ways to use it, on the same implementation:
//  - asynchronous: async_submit(request, handler) on an io_context the caller runs (one thread); the handler runs on
//    that thread. Many connections can share one io_context, which is how occgeo-load drives hundreds of sessions
//    from one thread.
//  - blocking: submit() / next() / wait_all() / call() / run_batch() run the io_context themselves until their
//    condition holds. Call them only from the thread that owns the io_context and never from inside a handler.
// The connection assigns request_ids (1, 2, 3 ...) and writes them on the request's envelope; any request_id already
// set is overwritten. Messages that answer no request (ScanAck, MotionCommand, an Error with request_id 0) go to the
// unsolicited handler if one is set, else to a queue read with take_unsolicited().
class PipelinedConnection {
 public:
  // Connects to `endpoint` on `io` and exchanges hello/welcome (running `io` until done, bounded by `timeout`).
  // Throws ClientError on failure or when the server refuses the hello. max_in_flight >= 1.
  static std::unique_ptr<PipelinedConnection> open(boost::asio::io_context& io, const Endpoint& endpoint,
                                                   const v1::Hello& hello, std::size_t max_in_flight,
                                                   std::chrono::milliseconds timeout = std::chrono::seconds(5));
  // The same on an io_context of its own (for the blocking calls).
  static std::unique_ptr<PipelinedConnection> open(const Endpoint& endpoint, const v1::Hello& hello,
                                                   std::size_t max_in_flight,
                                                   std::chrono::milliseconds timeout = std::chrono::seconds(5));

  PipelinedConnection(const PipelinedConnection&) = delete;
  PipelinedConnection& operator=(const PipelinedConnection&) = delete;
  ~PipelinedConnection();

  [[nodiscard]] const v1::Welcome& welcome() const;
  [[nodiscard]] std::size_t max_in_flight() const;
  [[nodiscard]] std::size_t in_flight() const;
  [[nodiscard]] bool can_submit() const { return in_flight() < max_in_flight(); }
  // False once the connection failed or was closed; every outstanding request then completed with `failure`.
  [[nodiscard]] bool healthy() const;

  // Queues `request` for writing and returns its request_id; `on_reply` runs once with its answer (or failure).
  // Throws ClientError when max_in_flight requests are already outstanding, the message kind carries no
  // request_id, or the connection failed.
  std::uint64_t async_submit(v1::ClientMessage request, ReplyHandler on_reply);
  // The same, leaving `request` with the caller (its request_id overwritten): the request is serialised at once, so
  // the caller may refill the same message for the next one, and a client sending many builds and frees none.
  std::uint64_t async_submit_in_place(v1::ClientMessage& request, ReplyHandler on_reply);

  // Blocking: waits (running the io_context) until fewer than max_in_flight are outstanding, then submits; the
  // answer is kept for next()/wait_all(). Throws ClientError on timeout or connection failure.
  std::uint64_t submit(v1::ClientMessage request, std::chrono::milliseconds timeout = std::chrono::seconds(10));
  // Blocking: the next answer of a submit()ted request, in completion order; nullopt after `timeout`.
  std::optional<Reply> next(std::chrono::milliseconds timeout = std::chrono::seconds(10));
  // Blocking: every submit()ted request's answer, in completion order; throws ClientError when some did not
  // complete within `timeout`.
  std::vector<Reply> wait_all(std::chrono::milliseconds timeout = std::chrono::seconds(30));
  // Blocking: submits every request keeping up to max_in_flight outstanding and returns the answers in the
  // requests' order.
  std::vector<Reply> run_batch(std::vector<v1::ClientMessage> requests,
                               std::chrono::milliseconds timeout = std::chrono::seconds(60));
  // Blocking: one request and its answer; a server Error is thrown as ClientError (as Connection::call does).
  v1::ServerMessage call(v1::ClientMessage request, std::chrono::milliseconds timeout = std::chrono::seconds(10));

  // Messages that answer no request, for connections that also receive pushes.
  void set_unsolicited_handler(std::function<void(v1::ServerMessage&&)> handler);
  std::deque<v1::ServerMessage> take_unsolicited();

  // Closes the socket; outstanding requests complete with a failure.
  void close();

 private:
  struct Impl;
  explicit PipelinedConnection(std::shared_ptr<Impl> impl);
  static std::unique_ptr<PipelinedConnection> open_on(std::shared_ptr<Impl> impl, const Endpoint& endpoint,
                                                      const v1::Hello& hello, std::chrono::milliseconds timeout);
  // Shared with the asynchronous operations in flight on the io_context.
  std::shared_ptr<Impl> impl_;
};

// Writes request_id on `message`'s envelope; false when its body is no request (a body numbered below 10: hello,
// robot_spec, odometry, sensor data), which no reply would answer.
bool set_request_id(v1::ClientMessage& message, std::uint64_t request_id);

}  // namespace occgeo::client
