#include "occgeo/client/connection.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/reflection.h>

#include <algorithm>
#include <array>
#include <boost/asio.hpp>
#include <charconv>
#include <cstdio>
#include <deque>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "occgeo/client/pipeline.h"
#include "occgeo/proto/framing.h"
#include "occgeo/proto/protocol.h"

namespace occgeo::client {

namespace asio = boost::asio;
using asio::ip::tcp;

namespace {
// Replies such as whole-map windows can be large; the client accepts up to this frame size.
constexpr std::size_t kClientMaxFrameBytes = std::size_t{256} * 1024 * 1024;

// The message set in `message`'s oneof `body`, or nullptr.
const google::protobuf::FieldDescriptor* body_field(const google::protobuf::Message& message) {
  const google::protobuf::OneofDescriptor* body = message.GetDescriptor()->FindOneofByName("body");
  if (body == nullptr) return nullptr;
  const google::protobuf::FieldDescriptor* field = message.GetReflection()->GetOneofFieldDescriptor(message, body);
  if (field == nullptr || field->type() != google::protobuf::FieldDescriptor::TYPE_MESSAGE) return nullptr;
  return field;
}

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
  text += ": " + error.message();
  if (error.code() == v1::ERROR_BUSY) {
    char hint[64];
    std::snprintf(hint, sizeof hint, " (server busy: retry in %g s)", error.retry_after_s());
    text += hint;
  }
  return text;
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

std::uint64_t reply_request_id(const v1::ServerMessage& message) { return message.request_id(); }

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

bool set_request_id(v1::ClientMessage& message, std::uint64_t request_id) {
  if (static_cast<int>(message.body_case()) < proto::kFirstRequestBodyField) return false;
  message.set_request_id(request_id);
  return true;
}

std::string Reply::error_text() const {
  if (!failure.empty()) return failure;
  if (message.has_error()) return describe(message.error());
  return {};
}

namespace {

// The requests awaiting an answer, by request_id. Ids are handed out in order, so id modulo a power of two at least
// twice the pipelining depth finds a free slot almost always: no node allocated and freed per request, as a hash map
// does. A request still waiting when its slot comes round again (a slow batch among fast singles) goes to the
// overflow map.
template <typename Value>
class RequestTable {
 public:
  explicit RequestTable(std::size_t max_in_flight) {
    std::size_t slots = 16;
    while (slots < 2 * max_in_flight && slots < kMaxSlots) slots *= 2;
    slots_.resize(slots);
    mask_ = slots - 1;
  }
  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] bool empty() const { return size_ == 0; }
  void insert(std::uint64_t request_id, Value value) {
    Slot& slot = slots_[request_id & mask_];
    if (slot.request_id == 0) {
      slot.request_id = request_id;
      slot.value = std::move(value);
    } else {
      overflow_.emplace(request_id, std::move(value));
    }
    ++size_;
  }
  // Removes and returns the request's entry; nullopt when it is not waiting.
  std::optional<Value> take(std::uint64_t request_id) {
    Slot& slot = slots_[request_id & mask_];
    if (slot.request_id == request_id && request_id != 0) {
      slot.request_id = 0;
      --size_;
      return std::move(slot.value);
    }
    const auto found = overflow_.find(request_id);
    if (found == overflow_.end()) return std::nullopt;
    std::optional<Value> value(std::move(found->second));
    overflow_.erase(found);
    --size_;
    return value;
  }
  // Removes and returns every entry.
  std::vector<std::pair<std::uint64_t, Value>> take_all() {
    std::vector<std::pair<std::uint64_t, Value>> all;
    all.reserve(size_);
    for (Slot& slot : slots_) {
      if (slot.request_id == 0) continue;
      all.emplace_back(slot.request_id, std::move(slot.value));
      slot.request_id = 0;
    }
    for (auto& [request_id, value] : overflow_) all.emplace_back(request_id, std::move(value));
    overflow_.clear();
    size_ = 0;
    return all;
  }
  void clear() { take_all(); }

 private:
  static constexpr std::size_t kMaxSlots = std::size_t{1} << 16;
  struct Slot {
    std::uint64_t request_id = 0;  // 0: free (ids start at 1)
    Value value{};
  };
  std::vector<Slot> slots_;
  std::size_t mask_ = 0;
  std::unordered_map<std::uint64_t, Value> overflow_;
  std::size_t size_ = 0;
};

}  // namespace

// Shared with the asynchronous operations in flight (they hold a shared_ptr), so the connection object may go away
// while the io_context still holds completions for its socket.
struct PipelinedConnection::Impl : std::enable_shared_from_this<PipelinedConnection::Impl> {
  using Clock = std::chrono::steady_clock;
  struct Outstanding {
    ReplyHandler handler;
    Clock::time_point submitted_at;
  };

  Impl(asio::io_context& io_in, std::unique_ptr<asio::io_context> own_in, std::size_t max_in_flight_in)
      : own_io(std::move(own_in)),
        io(io_in),
        socket(io_in),
        outstanding(max_in_flight_in),
        max_in_flight(max_in_flight_in) {}

  std::unique_ptr<asio::io_context> own_io;  // set when the connection runs its own io_context
  asio::io_context& io;
  tcp::socket socket;
  proto::FrameDecoder decoder{kClientMaxFrameBytes};
  std::array<char, std::size_t{64} * 1024> read_buffer{};
  std::string queued;   // frames waiting for the write in progress to finish
  std::string writing;  // the frames of the write in progress
  bool write_in_progress = false;
  // Set while the frames of one read are handled: requests their handlers submit go out in one write after.
  bool corked = false;
  // When that read completed, while corked: the completion time of every answer in it, and the submission time of
  // every request its handlers submit (a little early, so latencies err long), one clock read for the lot.
  Clock::time_point read_completed_at;
  RequestTable<Outstanding> outstanding;
  std::uint64_t next_request_id = 1;
  std::size_t max_in_flight;
  bool failed = false;
  std::string failure_text;
  bool awaiting_welcome = false;
  std::optional<v1::Welcome> welcome;
  std::string hello_refusal;
  std::deque<Reply> completed;  // answers of blocking submit()s
  std::function<void(v1::ServerMessage&&)> unsolicited_handler;
  std::deque<v1::ServerMessage> unsolicited;

  // Runs the io_context until `done()` or the deadline; false on timeout.
  template <typename Done>
  bool run_until(Done done, Clock::time_point deadline) {
    while (!done()) {
      const auto now = Clock::now();
      if (now >= deadline) return false;
      if (io.stopped()) io.restart();
      io.run_one_for(deadline - now);
    }
    return true;
  }

  void enqueue(const v1::ClientMessage& message) {
    const std::size_t size = message.ByteSizeLong();
    // Varint length prefix, then the message, serialised straight into the write queue.
    std::size_t prefix = size;
    do {
      const auto byte = static_cast<char>((prefix & 0x7F) | (prefix > 0x7F ? 0x80 : 0));
      queued.push_back(byte);
      prefix >>= 7;
    } while (prefix != 0);
    const std::size_t start = queued.size();
    queued.resize(start + size);
    message.SerializeWithCachedSizesToArray(reinterpret_cast<std::uint8_t*>(queued.data() + start));
    if (!write_in_progress && !corked) start_write();
  }

  void start_write() {
    writing.clear();
    writing.swap(queued);
    write_in_progress = true;
    asio::async_write(socket, asio::buffer(writing),
                      [self = shared_from_this()](const boost::system::error_code& error, std::size_t) {
                        self->write_in_progress = false;
                        if (error) {
                          self->fail("send failed: " + error.message());
                          return;
                        }
                        if (!self->queued.empty() && !self->failed) self->start_write();
                      });
  }

  void start_read() {
    socket.async_read_some(asio::buffer(read_buffer),
                           [self = shared_from_this()](const boost::system::error_code& error, std::size_t size) {
                             if (self->failed) return;
                             if (error) {
                               self->fail(error == asio::error::eof ? std::string("server closed the connection")
                                                                    : "receive failed: " + error.message());
                               return;
                             }
                             self->decoder.append(self->read_buffer.data(), size);
                             self->read_completed_at = Clock::now();
                             self->corked = true;
                             self->drain_decoder();
                             self->corked = false;
                             if (self->failed) return;
                             if (!self->queued.empty() && !self->write_in_progress) self->start_write();
                             self->start_read();
                           });
  }

  void drain_decoder() {
    while (!failed) {
      v1::ServerMessage message;
      switch (decoder.next(message)) {
        case proto::FrameStatus::frame:
          deliver(std::move(message));
          continue;
        case proto::FrameStatus::need_more:
          return;
        case proto::FrameStatus::too_large:
          fail("server sent a frame over " + std::to_string(kClientMaxFrameBytes) + " bytes");
          return;
        case proto::FrameStatus::malformed:
          fail("server sent an undecodable frame");
          return;
      }
    }
  }

  void deliver(v1::ServerMessage&& message) {
    const std::uint64_t request_id = reply_request_id(message);
    if (request_id != 0) {
      if (std::optional<Outstanding> waiting = outstanding.take(request_id)) {
        Reply reply;
        reply.request_id = request_id;
        reply.message = std::move(message);
        reply.submitted_at = waiting->submitted_at;
        reply.completed_at = corked ? read_completed_at : Clock::now();
        waiting->handler(std::move(reply));
        return;
      }
    }
    if (awaiting_welcome) {
      if (message.has_welcome()) {
        welcome = message.welcome();
        awaiting_welcome = false;
        return;
      }
      if (message.has_error()) {
        hello_refusal = describe(message.error());
        awaiting_welcome = false;
        return;
      }
    }
    if (unsolicited_handler) {
      unsolicited_handler(std::move(message));
    } else {
      unsolicited.push_back(std::move(message));
    }
  }

  // fail(), then, on an io_context of its own, runs the aborted read and write, which hold this Impl (or the two
  // would keep each other alive).
  void abandon(const std::string& reason) {
    fail(reason);
    if (own_io) {
      own_io->restart();
      own_io->poll();
    }
  }

  // Marks the connection failed and completes every outstanding request with the reason.
  void fail(const std::string& reason) {
    if (failed) return;
    failed = true;
    failure_text = reason;
    boost::system::error_code ignored;
    socket.close(ignored);
    auto orphans = outstanding.take_all();
    for (auto& [request_id, entry] : orphans) {
      Reply reply;
      reply.request_id = request_id;
      reply.failure = reason;
      reply.submitted_at = entry.submitted_at;
      reply.completed_at = Clock::now();
      entry.handler(std::move(reply));
    }
  }
};

std::unique_ptr<PipelinedConnection> PipelinedConnection::open(asio::io_context& io, const Endpoint& endpoint,
                                                               const v1::Hello& hello, std::size_t max_in_flight,
                                                               std::chrono::milliseconds timeout) {
  if (max_in_flight == 0) throw ClientError("max_in_flight must be at least 1");
  return open_on(std::make_shared<Impl>(io, nullptr, max_in_flight), endpoint, hello, timeout);
}

std::unique_ptr<PipelinedConnection> PipelinedConnection::open(const Endpoint& endpoint, const v1::Hello& hello,
                                                               std::size_t max_in_flight,
                                                               std::chrono::milliseconds timeout) {
  if (max_in_flight == 0) throw ClientError("max_in_flight must be at least 1");
  auto own = std::make_unique<asio::io_context>();
  asio::io_context& io = *own;
  return open_on(std::make_shared<Impl>(io, std::move(own), max_in_flight), endpoint, hello, timeout);
}

std::unique_ptr<PipelinedConnection> PipelinedConnection::open_on(std::shared_ptr<Impl> impl, const Endpoint& endpoint,
                                                                  const v1::Hello& hello,
                                                                  std::chrono::milliseconds timeout) {
  const auto deadline = Impl::Clock::now() + timeout;
  boost::system::error_code resolve_error;
  tcp::resolver resolver(impl->io);
  const auto endpoints = resolver.resolve(endpoint.host, std::to_string(endpoint.port), resolve_error);
  if (resolve_error) {
    throw ClientError("cannot resolve " + endpoint.to_string() + ": " + resolve_error.message());
  }
  auto connected = std::make_shared<std::optional<boost::system::error_code>>();
  asio::async_connect(
      impl->socket, endpoints,
      [connected](const boost::system::error_code& error, const tcp::endpoint&) { *connected = error; });
  if (!impl->run_until([&] { return connected->has_value(); }, deadline)) {
    impl->socket.close();
    throw ClientError("timed out connecting to " + endpoint.to_string());
  }
  if (**connected) throw ClientError("cannot connect to " + endpoint.to_string() + ": " + (**connected).message());
  impl->socket.set_option(tcp::no_delay(true));
  impl->awaiting_welcome = true;
  v1::ClientMessage message;
  *message.mutable_hello() = hello;
  impl->enqueue(message);
  impl->start_read();
  const bool answered = impl->run_until([&] { return !impl->awaiting_welcome || impl->failed; }, deadline);
  if (!impl->hello_refusal.empty()) {
    impl->abandon("server refused hello");
    throw ClientError("server refused hello: " + impl->hello_refusal);
  }
  if (impl->failed) {
    impl->abandon(impl->failure_text);
    throw ClientError(impl->failure_text);
  }
  if (!answered || !impl->welcome) {
    impl->abandon("timed out waiting for the server's welcome");
    throw ClientError("timed out waiting for the server's welcome");
  }
  return std::unique_ptr<PipelinedConnection>(new PipelinedConnection(std::move(impl)));
}

PipelinedConnection::PipelinedConnection(std::shared_ptr<Impl> impl) : impl_(std::move(impl)) {}

PipelinedConnection::~PipelinedConnection() {
  // Handlers must not run after their owner is gone: drop them, then close.
  impl_->outstanding.clear();
  impl_->unsolicited_handler = nullptr;
  impl_->abandon("connection closed by the client");
}

const v1::Welcome& PipelinedConnection::welcome() const { return *impl_->welcome; }
std::size_t PipelinedConnection::max_in_flight() const { return impl_->max_in_flight; }
std::size_t PipelinedConnection::in_flight() const { return impl_->outstanding.size(); }
bool PipelinedConnection::healthy() const { return !impl_->failed; }

std::uint64_t PipelinedConnection::async_submit(v1::ClientMessage request, ReplyHandler on_reply) {
  return async_submit_in_place(request, std::move(on_reply));
}

std::uint64_t PipelinedConnection::async_submit_in_place(v1::ClientMessage& request, ReplyHandler on_reply) {
  if (impl_->failed) throw ClientError("connection failed: " + impl_->failure_text);
  if (impl_->outstanding.size() >= impl_->max_in_flight) {
    throw ClientError("already " + std::to_string(impl_->max_in_flight) + " requests in flight");
  }
  const std::uint64_t request_id = impl_->next_request_id;
  if (!set_request_id(request, request_id)) {
    throw ClientError("a " + std::string(body_field(request) ? body_field(request)->name() : "empty") +
                      " message carries no request_id: send it with Connection::send");
  }
  ++impl_->next_request_id;
  const auto submitted_at = impl_->corked ? impl_->read_completed_at : Impl::Clock::now();
  impl_->outstanding.insert(request_id, Impl::Outstanding{std::move(on_reply), submitted_at});
  impl_->enqueue(request);
  return request_id;
}

std::uint64_t PipelinedConnection::submit(v1::ClientMessage request, std::chrono::milliseconds timeout) {
  const auto deadline = Impl::Clock::now() + timeout;
  if (!impl_->run_until([&] { return impl_->failed || can_submit(); }, deadline)) {
    throw ClientError("timed out waiting for room to submit a request");
  }
  return async_submit(std::move(request),
                      [impl = impl_.get()](Reply&& reply) { impl->completed.push_back(std::move(reply)); });
}

std::optional<Reply> PipelinedConnection::next(std::chrono::milliseconds timeout) {
  const auto deadline = Impl::Clock::now() + timeout;
  impl_->run_until([&] { return !impl_->completed.empty() || (impl_->failed && impl_->outstanding.empty()); },
                   deadline);
  if (impl_->completed.empty()) return std::nullopt;
  Reply reply = std::move(impl_->completed.front());
  impl_->completed.pop_front();
  return reply;
}

std::vector<Reply> PipelinedConnection::wait_all(std::chrono::milliseconds timeout) {
  const auto deadline = Impl::Clock::now() + timeout;
  if (!impl_->run_until([&] { return impl_->outstanding.empty(); }, deadline)) {
    throw ClientError("timed out with " + std::to_string(impl_->outstanding.size()) + " requests unanswered");
  }
  std::vector<Reply> replies(std::make_move_iterator(impl_->completed.begin()),
                             std::make_move_iterator(impl_->completed.end()));
  impl_->completed.clear();
  return replies;
}

std::vector<Reply> PipelinedConnection::run_batch(std::vector<v1::ClientMessage> requests,
                                                  std::chrono::milliseconds timeout) {
  const auto deadline = Impl::Clock::now() + timeout;
  std::vector<Reply> replies(requests.size());
  std::size_t answered = 0;
  std::size_t next_request = 0;
  while (answered < requests.size()) {
    while (next_request < requests.size() && can_submit() && !impl_->failed) {
      async_submit(std::move(requests[next_request]), [&replies, &answered, index = next_request](Reply&& reply) {
        replies[index] = std::move(reply);
        ++answered;
      });
      ++next_request;
    }
    if (impl_->failed && next_request < requests.size()) {
      throw ClientError("connection failed: " + impl_->failure_text);
    }
    const std::size_t before = answered;
    if (!impl_->run_until([&] { return answered != before || impl_->failed; }, deadline)) {
      // The handlers refer to this frame's locals: drop them before leaving.
      impl_->fail("timed out");
      throw ClientError("timed out with " + std::to_string(requests.size() - answered) + " requests unanswered");
    }
  }
  return replies;
}

v1::ServerMessage PipelinedConnection::call(v1::ClientMessage request, std::chrono::milliseconds timeout) {
  std::vector<v1::ClientMessage> one;
  one.push_back(std::move(request));
  Reply reply = std::move(run_batch(std::move(one), timeout).front());
  if (!reply.ok()) throw ClientError(reply.error_text());
  return std::move(reply.message);
}

void PipelinedConnection::set_unsolicited_handler(std::function<void(v1::ServerMessage&&)> handler) {
  impl_->unsolicited_handler = std::move(handler);
}

std::deque<v1::ServerMessage> PipelinedConnection::take_unsolicited() { return std::exchange(impl_->unsolicited, {}); }

void PipelinedConnection::close() { impl_->fail("connection closed by the client"); }

}  // namespace occgeo::client
