#include "session.h"

#include <google/protobuf/arena.h>
#include <unistd.h>

#include <algorithm>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/write.hpp>

#include "metrics.h"
#include "occgeo/service/log.h"
#include "validation.h"

namespace occgeo::service {

namespace {

// How long a client told ERROR_BUSY should wait before asking again: long enough for the query pool to work off a
// good part of a full backlog, short enough that a polite client loses little.
constexpr double kBusyRetryAfter_s = 0.05;

// Query and observer sessions' requests may be refused when the backlog is full; a driver's or controller's never
// are (they query for the robot they drive).
bool may_be_refused_busy(v1::Role role) { return role == v1::ROLE_QUERY || role == v1::ROLE_OBSERVER; }

// The name of a message's kind as the schema has it, e.g. "collision_batch".
std::string kind_name(const v1::ClientMessage& message) {
  const auto* field = v1::ClientMessage::descriptor()->FindFieldByNumber(message.body_case());
  return field == nullptr ? std::string() : field->name();
}

std::chrono::steady_clock::duration seconds(double s) {
  return std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(s));
}

// Requests are parsed into an arena that is emptied after each round of frames, so a query's message costs no malloc
// or free. One per network thread; a handler copies what it keeps (sensor data moved out of an arena message is
// copied), as it did when the message lived on the stack of dispatch_frames.
class FrameArena {
 public:
  static FrameArena& for_this_thread() {
    thread_local FrameArena arena;
    return arena;
  }
  FrameArena(const FrameArena&) = delete;
  FrameArena& operator=(const FrameArena&) = delete;

  v1::ClientMessage* new_message() { return google::protobuf::Arena::CreateMessage<v1::ClientMessage>(&arena_); }
  // Frees every message of the round once no round is in progress any more on this thread; mid-round when a large
  // message made it grow beyond its first block.
  void end_message() {
    if (arena_.SpaceAllocated() > kFirstBlockBytes && rounds_in_progress_ == 1) arena_.Reset();
  }
  // Marks a round of dispatch_frames on this thread (they could nest if a handler ever ran another session's loop).
  class Round {
   public:
    explicit Round(FrameArena& arena) : arena_(arena) { ++arena_.rounds_in_progress_; }
    Round(const Round&) = delete;
    Round& operator=(const Round&) = delete;
    ~Round() {
      if (--arena_.rounds_in_progress_ == 0) arena_.arena_.Reset();
    }

   private:
    FrameArena& arena_;
  };

 private:
  static constexpr std::size_t kFirstBlockBytes = std::size_t{64} * 1024;
  static google::protobuf::ArenaOptions options(char* block) {
    google::protobuf::ArenaOptions options;
    options.initial_block = block;
    options.initial_block_size = kFirstBlockBytes;
    return options;
  }
  FrameArena() : arena_(options(first_block_.data())) {}

  std::array<char, kFirstBlockBytes> first_block_{};  // kept across Reset(): a round of queries allocates nothing
  google::protobuf::Arena arena_;
  int rounds_in_progress_ = 0;
};

}  // namespace

void WatchHub::subscribe(const std::shared_ptr<Session>& session, std::string world, std::string robot_id,
                         bool with_data) {
  const std::lock_guard lock(mutex_);
  std::erase_if(watchers_, [&](const Watcher& w) { return w.key == session.get() || w.session.expired(); });
  watchers_.push_back({session.get(), session, std::move(world), std::move(robot_id), with_data});
  count_data_watchers_locked();
}

void WatchHub::unsubscribe(const Session* session) {
  const std::lock_guard lock(mutex_);
  std::erase_if(watchers_, [&](const Watcher& w) { return w.key == session; });
  count_data_watchers_locked();
}

void WatchHub::count_data_watchers_locked() {
  data_watchers_.store(static_cast<std::size_t>(std::ranges::count_if(watchers_, &Watcher::with_data)),
                       std::memory_order_relaxed);
}

std::vector<std::shared_ptr<Session>> WatchHub::matching_locked(const std::string& world, const std::string& robot_id,
                                                                bool with_data) const {
  std::vector<std::shared_ptr<Session>> targets;
  for (const Watcher& w : watchers_) {
    if (w.with_data != with_data) continue;
    if (!w.world.empty() && w.world != world) continue;
    if (!w.robot_id.empty() && w.robot_id != robot_id) continue;
    if (auto session = w.session.lock()) targets.push_back(std::move(session));
  }
  return targets;
}

void WatchHub::publish(const std::string& world, const std::string& robot_id, std::uint64_t seq,
                       std::uint64_t world_version) {
  std::vector<std::shared_ptr<Session>> targets;
  {
    const std::lock_guard lock(mutex_);
    targets = matching_locked(world, robot_id, false);
  }
  if (targets.empty()) return;
  auto event = std::make_shared<v1::WatchEvent>();
  event->set_world(world);
  event->set_robot_id(robot_id);
  event->set_seq(seq);
  event->set_world_version(world_version);
  for (const auto& session : targets) session->push_watch_event(event);
}

void WatchHub::publish_data(const std::shared_ptr<const v1::WatchEvent>& event) {
  std::vector<std::shared_ptr<Session>> targets;
  {
    const std::lock_guard lock(mutex_);
    targets = matching_locked(event->world(), event->robot_id(), true);
  }
  for (const auto& session : targets) session->push_watch_event(event);
}

Session::Session(ServerCore& core, SessionShared& shared, asio::io_context& loop, asio::ip::tcp::socket socket,
                 std::uint64_t id)
    : core_(core),
      shared_(shared),
      loop_(&loop),
      socket_(socket.get_executor()),
      write_timer_(socket.get_executor()),
      hello_timer_(socket.get_executor()),
      decoder_(core.config().limits.max_frame_bytes) {
  info_.id = id;
  boost::system::error_code ignored;
  const auto remote = socket.remote_endpoint(ignored);
  info_.peer_address = remote.address().to_string();
  peer_address_ = info_.peer_address;
  info_.peer = info_.peer_address + ":" + std::to_string(remote.port());
  if (shared_.tls) {
    tls_ = std::make_unique<asio::ssl::stream<asio::ip::tcp::socket>>(std::move(socket), *shared_.tls);
  } else {
    socket_ = std::move(socket);
  }
  ++core_.sessions;
}

Session::~Session() {
  // Requests never answered (none should be: every admitted one gets a reply or an error) leave the backlog here.
  core_.queries_in_flight.fetch_sub(pending_requests_.load(), std::memory_order_relaxed);
  --core_.sessions;
}

void Session::start() {
  boost::system::error_code ignored;
  tcp_socket().set_option(asio::ip::tcp::no_delay(true), ignored);
  log::info("session_open", {{"session", info_.id}, {"peer", info_.peer}, {"tls", tls_ != nullptr}});
  core_.metrics().counter("occgeo_sessions_opened_total").inc();
  // A connection that never says hello must not hold a session slot for good.
  hello_timer_.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(core_.config().limits.hello_timeout_s)));
  hello_timer_.async_wait([self = shared_from_this()](const boost::system::error_code& error) {
    if (error || self->closed_ || self->info_.greeted) return;
    log::warn("session_hello_timeout", {{"session", self->info_.id},
                                        {"peer", self->info_.peer},
                                        {"hello_timeout_s", self->core_.config().limits.hello_timeout_s}});
    self->shutdown();
  });
  if (!tls_) {
    read_more();
    return;
  }
  tls_->async_handshake(
      asio::ssl::stream_base::server, [self = shared_from_this()](const boost::system::error_code& error) {
        if (self->closed_) return;
        if (error) {
          log::warn("session_tls_failed",
                    {{"session", self->info_.id}, {"peer", self->info_.peer}, {"error", error.message()}});
          self->shutdown();
          return;
        }
        self->read_more();
      });
}

void Session::close() {
  // Posted, never run inline: the caller may hold locks that closing takes (leases, the session list).
  post_here([self = shared_from_this()] { self->shutdown(); });
}

void Session::close_if_silent() {
  post_here([self = shared_from_this()] {
    if (self->info_.greeted) return;
    log::info("session_evicted", {{"session", self->info_.id}, {"peer", self->info_.peer}, {"reason", "no hello yet"}});
    self->shutdown();
  });
}

bool Session::on_session_thread() const {
  return loop_.load(std::memory_order_acquire)->get_executor().running_in_this_thread();
}

bool Session::should_move_to_driver_loop() const {
  return shared_.driver_loop != nullptr && !tls_ && info_.role == v1::ROLE_DRIVER && !writing_ && !reading_ &&
         !write_timer_armed_ && loop_.load(std::memory_order_relaxed) != shared_.driver_loop;
}

bool Session::move_to_driver_loop() {
  boost::system::error_code error;
  const auto protocol = socket_.local_endpoint(error).protocol();
  asio::ip::tcp::socket moved(*shared_.driver_loop);
  if (!error) {
    // release() takes the descriptor out of this loop's reactor; nothing is in flight on it (should_move...).
    const auto handle = socket_.release(error);
    if (!error) {
      moved.assign(protocol, handle, error);
      if (error) {
        // The descriptor is no longer owned by any socket object: close it rather than leak it, and end the session.
        ::close(handle);
        log::warn("session_move_failed", {{"session", info_.id}, {"error", error.message()}});
        shutdown();
        return true;  // nothing left to do on either loop
      }
    }
  }
  if (error) {
    log::warn("session_move_failed", {{"session", info_.id}, {"error", error.message()}});
    return false;
  }
  socket_ = std::move(moved);
  write_timer_ = asio::steady_timer(*shared_.driver_loop);
  hello_timer_ = asio::steady_timer(*shared_.driver_loop);  // the old one's wait was cancelled at the hello
  loop_.store(shared_.driver_loop, std::memory_order_release);
  log::debug("session_moved_to_driver_loop", {{"session", info_.id}, {"robot", info_.robot_id}});
  return true;
}

void Session::read_more() {
  reading_ = true;
  with_stream([&](auto& stream) {
    stream.async_read_some(asio::buffer(read_buffer_),
                           [self = shared_from_this()](const boost::system::error_code& error, std::size_t size) {
                             self->on_read(error, size);
                           });
  });
}

void Session::on_read(const boost::system::error_code& error, std::size_t size) {
  reading_ = false;
  if (closed_) return;
  if (error) {
    if (decoder_.buffered() > 0) {
      log::warn("session_truncated_frame", {{"session", info_.id}, {"buffered_bytes", decoder_.buffered()}});
    }
    shutdown();
    return;
  }
  decoder_.append(read_buffer_.data(), size);
  process_frames();
}

void Session::process_frames() {
  // Cheap queries are answered inline while the frames are handled: their replies go out together in one write
  // after the last frame of this read, not one write each.
  corked_ = true;
  const bool budget_spent = dispatch_frames();
  corked_ = false;
  if (closed_) return;
  if (move_pending_) {
    move_pending_ = false;
    if (move_to_driver_loop()) {
      // The welcome and any frames after the hello are written and handled on the driver loop.
      post_here([self = shared_from_this()] {
        if (!self->closed_) self->process_frames();
      });
      return;
    }
  }
  if (!writing_) write_next();
  if (closed_ || close_after_write_ || read_paused_) return;
  if (budget_spent) {
    // More frames are buffered: let other work on this network thread run first, then go on.
    post_here([self = shared_from_this()] {
      if (!self->closed_ && !self->read_paused_) self->process_frames();
    });
    return;
  }
  if (!reading_) read_more();
}

bool Session::dispatch_frames() {
  const std::size_t max_pending = core_.config().limits.max_pending_requests;
  FrameArena& arena = FrameArena::for_this_thread();
  const FrameArena::Round round(arena);
  const SessionPtr self = shared_from_this();  // one reference for the round, not one per frame
  for (std::size_t dispatched = 0; !closed_ && !close_after_write_; ++dispatched) {
    if (dispatched == kMaxFramesPerRound) return true;
    if (pending_requests_.load() >= max_pending) {
      // Reading resumes when answers bring the count down (enqueue); until then TCP holds the client back.
      read_paused_ = true;
      return false;
    }
    v1::ClientMessage& message = *arena.new_message();
    const proto::FrameStatus status = decoder_.next(message);
    if (status == proto::FrameStatus::need_more) return false;
    if (status == proto::FrameStatus::too_large) {
      fail_stream(v1::ERROR_FRAME_TOO_LARGE, "frame of " + std::to_string(decoder_.rejected_frame_bytes()) +
                                                 " bytes is over the limit of " +
                                                 std::to_string(core_.config().limits.max_frame_bytes));
      return false;
    }
    if (status == proto::FrameStatus::malformed) {
      fail_stream(v1::ERROR_BAD_FRAME, "the frame does not decode as an occgeo.v1 ClientMessage");
      return false;
    }
    if (is_request(message.body_case())) {
      ++pending_requests_;
      const std::size_t backlog = core_.queries_in_flight.fetch_add(1, std::memory_order_relaxed);
      if (backlog >= core_.config().limits.max_query_backlog && info_.greeted && may_be_refused_busy(info_.role)) {
        refuse_busy(message, backlog);
        arena.end_message();
        continue;
      }
    }
    const bool was_greeted = info_.greeted;
    dispatch_message(self, message);
    arena.end_message();
    if (!was_greeted && info_.greeted) {
      core_.metrics().gauge("occgeo_sessions", {{"role", v1::Role_Name(info_.role)}}).inc();
      greeted_.store(true, std::memory_order_release);
      hello_timer_.cancel();
      if (should_move_to_driver_loop()) {
        move_pending_ = true;
        return false;
      }
    }
  }
  return false;
}

void Session::send(const v1::ServerMessage& message) {
  // A driver's ack is what watchers follow. The driver's role, robot and world are fixed at its hello, before any
  // scan is posted to an ingest strand, so reading them here (on that strand) is safe.
  if (message.has_scan_ack() && info_.role == v1::ROLE_DRIVER) {
    shared_.watch.publish(info_.world, info_.robot_id, message.scan_ack().seq(), message.scan_ack().world_version());
  }
  // Data watchers get a copy of every command sent to a driver (built only when some asked for data).
  if (message.has_motion_command() && info_.role == v1::ROLE_DRIVER && shared_.watch.has_data_watchers()) {
    auto event = std::make_shared<v1::WatchEvent>();
    event->set_seq(message.motion_command().seq());
    *event->mutable_motion_command() = message.motion_command();
    publish_data(std::move(event));
  }
  if (is_answer(message.body_case())) {
    std::size_t pending = pending_requests_.load();
    while (pending > 0 && !pending_requests_.compare_exchange_weak(pending, pending - 1)) {
    }
    // The server-wide backlog is the sum of the sessions' pending requests.
    if (pending > 0) core_.queries_in_flight.fetch_sub(1, std::memory_order_relaxed);
  }
  // An answer given inline while this session's frames are being handled is serialised straight into the outbox.
  // corked_ is read only on the session's own thread (the && stops before it elsewhere).
  if (on_session_thread() && corked_) {
    if (closed_) return;
    proto::append_frame(message, queued_);
    after_enqueue();
    return;
  }
  // Encoding happens on the caller's thread so the network thread only moves bytes. Posted (not run inline even on
  // this session's thread): the caller may be another session's handler holding locks that closing this one takes.
  std::string frame = proto::encode_frame(message);
  post_here([self = shared_from_this(), frame = std::move(frame)] { self->enqueue(frame); });
}

void Session::refuse_busy(const v1::ClientMessage& message, std::size_t backlog) {
  core_.queries_busy().inc();
  v1::ServerMessage reply;
  v1::Error& error = *reply.mutable_error();
  error.set_code(v1::ERROR_BUSY);
  error.set_field(kind_name(message));
  error.set_message("the server is busy: " + std::to_string(backlog) +
                    " queries are in flight (limits.max_query_backlog " +
                    std::to_string(core_.config().limits.max_query_backlog) +
                    "); nothing was done, send it again after retry_after_s");
  reply.set_request_id(message.request_id());
  error.set_retry_after_s(kBusyRetryAfter_s);
  send(reply);
}

void Session::close_after_send() {
  close_after_write_ = true;
  if (!writing_) write_next();  // writes what is queued, then shuts down
}

void Session::watch(std::uint64_t request_id, const v1::WatchRequest& request) {
  if (!request.world().empty() && !valid_name(request.world())) {
    send_error(v1::ERROR_INVALID_ARGUMENT, "watch.world", "a world name is 1-64 characters of A-Z a-z 0-9 _ . -",
               request_id);
    return;
  }
  if (!request.robot_id().empty() && !valid_name(request.robot_id())) {
    send_error(v1::ERROR_INVALID_ARGUMENT, "watch.robot_id", "a robot id is 1-64 characters of A-Z a-z 0-9 _ . -",
               request_id);
    return;
  }
  shared_.watch.subscribe(shared_from_this(), request.world(), request.robot_id(), request.with_data());
  v1::ServerMessage reply;
  reply.set_request_id(request_id);
  reply.mutable_watch();
  send(reply);
  if (request.with_data()) {
    // The specs of robots already registered, queued here (on this session's thread) ahead of any data event, which
    // reaches this session only through a post: a recording can always place what follows.
    for (const auto& robot : core_.robots()) {
      const std::string& world = robot->world().name();
      if (!request.world().empty() && request.world() != world) continue;
      if (!request.robot_id().empty() && request.robot_id() != robot->model().id) continue;
      auto event = std::make_shared<v1::WatchEvent>();
      event->set_world(world);
      event->set_robot_id(robot->model().id);
      *event->mutable_robot_spec() = robot->model().spec;
      enqueue_watch_event(std::move(event));
    }
  }
  log::info("session_watch", {{"session", info_.id},
                              {"world", request.world()},
                              {"robot", request.robot_id()},
                              {"with_data", request.with_data()}});
}

void Session::publish_data(std::shared_ptr<v1::WatchEvent> event) {
  // A driver's world and robot are fixed at its hello, before any of its messages reach a strand.
  event->set_world(info_.world);
  event->set_robot_id(info_.robot_id);
  shared_.watch.publish_data(event);
}

void Session::push_watch_event(std::shared_ptr<const v1::WatchEvent> event) {
  post_here(
      [self = shared_from_this(), event = std::move(event)]() mutable { self->enqueue_watch_event(std::move(event)); });
}

void Session::enqueue_watch_event(std::shared_ptr<const v1::WatchEvent> event) {
  if (closed_) return;
  if (watch_queue_.size() >= core_.config().limits.max_watch_queue_messages) {
    watch_queue_.pop_front();
    ++watch_dropped_;
  }
  watch_queue_.push_back(std::move(event));
  if (!writing_ && !corked_) write_next();
}

void Session::enqueue(const std::string& frame) {
  if (closed_) return;
  queued_ += frame;
  after_enqueue();
}

void Session::after_enqueue() {
  outbox_bytes_ = queued_.size() + writing_buffer_.size();
  if (outbox_bytes_ > core_.config().limits.max_send_queue_bytes) {
    log::warn("session_slow_client_dropped",
              {{"session", info_.id}, {"peer", info_.peer}, {"unsent_bytes", outbox_bytes_}});
    core_.metrics().counter("occgeo_slow_clients_dropped_total").inc();
    shutdown();
    return;
  }
  if (read_paused_ && pending_requests_.load() < core_.config().limits.max_pending_requests) {
    read_paused_ = false;
    post_here([self = shared_from_this()] {
      if (!self->closed_ && !self->read_paused_) self->process_frames();
    });
  }
  if (!writing_ && !corked_) write_next();
}

void Session::write_next() {
  if (queued_.empty() && !close_after_write_) {
    // Replies first; watch events are encoded only when they are about to be written, the first carrying the drop
    // count.
    v1::ServerMessage message;
    for (std::size_t events = 0; !watch_queue_.empty() && events < kMaxWatchEventsPerWrite; ++events) {
      *message.mutable_watch_event() = *watch_queue_.front();
      message.mutable_watch_event()->set_dropped_since_last(watch_dropped_);
      watch_dropped_ = 0;
      watch_queue_.pop_front();
      proto::append_frame(message, queued_);
    }
  }
  if (queued_.empty()) {
    writing_ = false;
    if (close_after_write_) shutdown();
    return;
  }
  writing_ = true;
  write_started_ = std::chrono::steady_clock::now();
  arm_write_timer();
  // Every queued frame in one write: one system call for a burst of replies.
  if (writing_buffer_.capacity() > kKeptWriteBufferBytes) std::string().swap(writing_buffer_);
  writing_buffer_.clear();
  writing_buffer_.swap(queued_);
  outbox_bytes_ = writing_buffer_.size();
  with_stream([&](auto& stream) {
    asio::async_write(stream, asio::buffer(writing_buffer_),
                      [self = shared_from_this()](const boost::system::error_code& error, std::size_t) {
                        if (self->closed_) return;
                        if (error) {
                          self->shutdown();
                          return;
                        }
                        self->writing_buffer_.clear();
                        self->outbox_bytes_ = self->queued_.size();
                        self->write_next();
                      });
  });
}

void Session::arm_write_timer() {
  if (write_timer_armed_) return;
  write_timer_armed_ = true;
  write_timer_.expires_at(write_started_ + seconds(core_.config().limits.write_timeout_s));
  write_timer_.async_wait([self = shared_from_this()](const boost::system::error_code& error) {
    self->write_timer_armed_ = false;
    if (error || self->closed_ || !self->writing_) return;
    const auto deadline = self->write_started_ + seconds(self->core_.config().limits.write_timeout_s);
    if (std::chrono::steady_clock::now() < deadline) {
      self->arm_write_timer();  // a later write started since; wait for its own deadline
      return;
    }
    log::warn("session_write_timeout", {{"session", self->info_.id},
                                        {"peer", self->info_.peer},
                                        {"unsent_bytes", self->outbox_bytes_},
                                        {"timeout_s", self->core_.config().limits.write_timeout_s}});
    self->shutdown();
  });
}

void Session::fail_stream(v1::ErrorCode code, const std::string& message) {
  log::warn("session_bad_stream", {{"session", info_.id}, {"peer", info_.peer}, {"error", message}});
  v1::ServerMessage reply;
  reply.mutable_error()->set_code(code);
  reply.mutable_error()->set_message(message + "; closing the connection");
  if (!closed_) {
    proto::append_frame(reply, queued_);
    outbox_bytes_ = queued_.size() + writing_buffer_.size();
  }
  close_after_write_ = true;
  if (!writing_) write_next();  // writes the error, then shuts down
}

void Session::shutdown() {
  if (closed_) return;
  closed_ = true;
  shared_.watch.unsubscribe(this);
  boost::system::error_code ignored;
  write_timer_.cancel();
  hello_timer_.cancel();
  tcp_socket().shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
  tcp_socket().close(ignored);
  queued_.clear();
  outbox_bytes_ = 0;
  watch_queue_.clear();
  handle_disconnect(core_, info_);
  if (info_.greeted) core_.metrics().gauge("occgeo_sessions", {{"role", v1::Role_Name(info_.role)}}).dec();
  log::info("session_closed", {{"session", info_.id}, {"peer", info_.peer}});
}

}  // namespace occgeo::service
