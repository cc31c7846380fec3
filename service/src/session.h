#pragma once

#include <array>
#include <atomic>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl/context.hpp>
#include <boost/asio/ssl/stream.hpp>
#include <boost/asio/steady_timer.hpp>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "handlers/handlers.h"
#include "occgeo/proto/framing.h"

namespace occgeo::service {

class Session;

// Which sessions watch which worlds and robots. publish() runs on ingest strands, subscribe/unsubscribe on the
// network thread; it only posts events to the watchers, so a slow watcher never slows ingest.
class WatchHub {
 public:
  // Replaces the session's filter (empty world or robot: all); with_data: the session takes data events instead of
  // ack-only ones.
  void subscribe(const std::shared_ptr<Session>& session, std::string world, std::string robot_id, bool with_data);
  void unsubscribe(const Session* session);
  // One accepted sensor message of robot_id in world (ack-only watchers).
  void publish(const std::string& world, const std::string& robot_id, std::uint64_t seq, std::uint64_t world_version);
  // Whether any session asked for data events: the ingest path builds them only then. Lock-free.
  [[nodiscard]] bool has_data_watchers() const { return data_watchers_.load(std::memory_order_relaxed) > 0; }
  // One data event (world and robot_id set) to the data watchers whose filter matches.
  void publish_data(const std::shared_ptr<const v1::WatchEvent>& event);

 private:
  struct Watcher {
    const Session* key = nullptr;
    std::weak_ptr<Session> session;
    std::string world;
    std::string robot_id;
    bool with_data = false;
  };
  // Sessions of watchers_ that still hold a reference; called with mutex_ held.
  std::vector<std::shared_ptr<Session>> matching_locked(const std::string& world, const std::string& robot_id,
                                                        bool with_data) const;
  void count_data_watchers_locked();

  mutable std::mutex mutex_;
  std::vector<Watcher> watchers_;
  std::atomic<std::size_t> data_watchers_{0};
};

// What every session of one server shares.
struct SessionShared {
  WatchHub watch;
  HelloThrottle hello_throttle;
  std::shared_ptr<asio::ssl::context> tls;  // null: plain TCP
  // The event loop robot drivers' sessions move to once they said hello (plain TCP), run by a thread that answers
  // no queries; null: they stay on the loop that accepted them.
  asio::io_context* driver_loop = nullptr;
};

// One client connection. Reads frames on its strand and hands them to the handlers; replies
// from any thread are queued without blocking. A client that lets more than the configured bytes
// pile up unread, or takes no bytes for limits.write_timeout_s, is disconnected, so a slow client
// never holds up anyone else. Watch events are queued apart and bounded: the oldest are dropped
// first and the next event delivered says how many. A client with limits.max_pending_requests
// queries in flight is not read until some are answered.
class Session final : public SessionContext, public std::enable_shared_from_this<Session> {
 public:
  // loop: the event loop the socket was accepted on, run by one thread.
  Session(ServerCore& core, SessionShared& shared, asio::io_context& loop, asio::ip::tcp::socket socket,
          std::uint64_t id);
  ~Session() override;

  void start();
  // Closes the connection now (server shutdown).
  void close();
  // Closes it now unless it has said hello by the time this runs on its own thread (a silent connection the acceptor
  // evicts to make room; see Server). Safe from any thread.
  void close_if_silent();
  // Whether the session has completed its hello; safe from any thread.
  [[nodiscard]] bool greeted() const { return greeted_.load(std::memory_order_acquire); }
  // The peer's address (no port), fixed at accept; safe from any thread.
  [[nodiscard]] const std::string& peer_address() const { return peer_address_; }

  ServerCore& core() override { return core_; }
  SessionInfo& info() override { return info_; }
  void send(const v1::ServerMessage& message) override;
  void close_after_send() override;
  HelloThrottle* hello_throttle() override { return &shared_.hello_throttle; }
  void watch(std::uint64_t request_id, const v1::WatchRequest& request) override;
  [[nodiscard]] bool data_watched() const override { return shared_.watch.has_data_watchers(); }
  void publish_data(std::shared_ptr<v1::WatchEvent> event) override;

  // Queues one watch event (any thread).
  void push_watch_event(std::shared_ptr<const v1::WatchEvent> event);

 private:
  // Runs f on the TLS stream or the plain socket, whichever this session uses.
  template <typename Function>
  void with_stream(Function&& f) {
    if (tls_) {
      f(*tls_);
    } else {
      f(socket_);
    }
  }
  asio::ip::tcp::socket& tcp_socket() { return tls_ ? tls_->next_layer() : socket_; }

  void read_more();
  void on_read(const boost::system::error_code& error, std::size_t size);
  // Decodes and dispatches buffered frames until none is whole or too many queries are in flight, then writes the
  // replies queued meanwhile and reads on (unless paused).
  void process_frames();
  // The decoding loop of process_frames; true when it stopped after kMaxFramesPerRound frames with more buffered.
  bool dispatch_frames();
  // True on the thread running this session's event loop (its handlers all run there, one at a time).
  [[nodiscard]] bool on_session_thread() const;
  // Runs f on this session's event loop later. A driver's session changes loops once (move_to_driver_loop): what was
  // posted to the old loop before then is passed on to the new one, so f always runs on the session's own thread.
  template <typename Function>
  void post_here(Function&& f) {
    asio::post(*loop_.load(std::memory_order_acquire),
               [self = shared_from_this(), f = std::forward<Function>(f)]() mutable {
                 if (!self->on_session_thread()) {
                   self->post_here(std::move(f));
                   return;
                 }
                 f();
               });
  }
  // Whether this session should move to the driver loop now: a plain-TCP driver just greeted, nothing in flight.
  [[nodiscard]] bool should_move_to_driver_loop() const;
  // Moves the socket and timers to shared_.driver_loop; on this session's thread, with no read or write in flight.
  // False (the session stays) when the socket cannot be handed over.
  bool move_to_driver_loop();
  // Checks the outbox after frames were appended to it, then writes unless corked or a write is in progress.
  void after_enqueue();
  void enqueue(const std::string& frame);
  void enqueue_watch_event(std::shared_ptr<const v1::WatchEvent> event);
  void write_next();
  void arm_write_timer();
  // Answers a request ERROR_BUSY (the server-wide query backlog is full), doing nothing else.
  void refuse_busy(const v1::ClientMessage& message, std::size_t backlog);
  // Sends an error, then closes once it is written (for a stream that cannot be trusted).
  void fail_stream(v1::ErrorCode code, const std::string& message);
  void shutdown();

  ServerCore& core_;
  SessionShared& shared_;
  // The session's event loop, run by one thread: no strand is needed to keep its handlers apart. Changes once at
  // most, from the accepting loop to the driver loop, on the session's own thread.
  std::atomic<asio::io_context*> loop_;
  asio::ip::tcp::socket socket_;  // plain TCP; unused (moved into tls_) with TLS
  std::unique_ptr<asio::ssl::stream<asio::ip::tcp::socket>> tls_;
  asio::steady_timer write_timer_;
  asio::steady_timer hello_timer_;  // limits.hello_timeout_s: a connection that says nothing is closed
  SessionInfo info_;
  std::string peer_address_;
  std::atomic<bool> greeted_{false};
  proto::FrameDecoder decoder_;
  std::array<char, std::size_t{64} * 1024> read_buffer_{};
  // Watch events encoded into one write at most.
  static constexpr std::size_t kMaxWatchEventsPerWrite = 64;
  // A write buffer that grew beyond this (a large reply) is released once written rather than kept.
  static constexpr std::size_t kKeptWriteBufferBytes = std::size_t{1} << 20;
  // Frames handled in one go before other sessions on the same network thread get a turn.
  static constexpr std::size_t kMaxFramesPerRound = 256;
  // Frames serialised back to back: queued_ waits for the write of writing_ to finish, then the two swap, so a burst
  // of replies costs one system call and no allocation per frame.
  std::string queued_;
  std::string writing_buffer_;
  std::size_t outbox_bytes_ = 0;  // queued_ and writing_buffer_
  std::deque<std::shared_ptr<const v1::WatchEvent>> watch_queue_;
  std::uint64_t watch_dropped_ = 0;  // events dropped since the last one delivered
  std::atomic<std::size_t> pending_requests_{0};
  std::chrono::steady_clock::time_point write_started_{};
  bool write_timer_armed_ = false;
  bool reading_ = false;
  bool read_paused_ = false;
  bool writing_ = false;
  bool corked_ = false;  // frames are being dispatched: replies queue up for one write after them
  bool close_after_write_ = false;
  bool closed_ = false;
  bool move_pending_ = false;  // a driver's hello was handled: dispatching stops until the session has moved
};

}  // namespace occgeo::service
