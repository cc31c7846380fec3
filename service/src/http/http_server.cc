#include "http_server.h"

#include <atomic>
#include <bit>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <deque>
#include <optional>
#include <stdexcept>
#include <thread>

#include "../core.h"
#include "../metrics.h"
#include "../secret_compare.h"
#include "foxglove.h"
#include "live_view.h"
#include "occgeo/service/log.h"
#include "web_assets.h"

namespace occgeo::service::http {

namespace {

namespace beast = boost::beast;
namespace bhttp = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using Request = bhttp::request<bhttp::string_body>;
using Response = bhttp::response<bhttp::string_body>;

// How often the page gets a frame: robot state at ~10 Hz, the map's changes with it.
constexpr auto kFramePeriod = std::chrono::milliseconds(100);
// Page messages queued for writing at most (replies to select/estop); more are refused.
constexpr std::size_t kMaxQueuedReplies = 16;

// The label a request's path gets in occgeo_http_requests_total: known paths only, so scans for random URLs cannot
// grow the registry.
std::string path_label(std::string_view target) {
  if (target == "/" || target == "/metrics" || target == "/ws") return std::string(target);
  for (const auto& asset : web_assets()) {
    if (asset.path == target) return std::string(target);
  }
  return "other";
}

Response make_response(const Request& request, bhttp::status status, std::string_view content_type, std::string body) {
  Response response{status, request.version()};
  response.set(bhttp::field::server, "occgeod");
  response.set(bhttp::field::content_type, beast::string_view(content_type.data(), content_type.size()));
  response.set(bhttp::field::cache_control, "no-store");
  response.keep_alive(request.keep_alive());
  response.body() = std::move(body);
  response.prepare_payload();
  return response;
}

// Brings the gauges read from the worlds up to date for a scrape: each world's model sizes and publications, and the
// process's resident memory.
void record_world_gauges(ServerCore& core) {
  for (const auto& world : core.worlds()) {
    core.metrics()
        .gauge("occgeo_world_publications", {{"world", world->name()}},
               "Versions of a world's grid, distance field and PTEM published together since the server started")
        .set(static_cast<std::int64_t>(world->publications()));
    core.metrics()
        .gauge("occgeo_world_merged_publications", {{"world", world->name()}},
               "Sensor messages of a world published with a later message's publication because the publish lane "
               "was behind, since the server started")
        .set(static_cast<std::int64_t>(world->merged_publications()));
    const WorldMemory memory = world->memory();
    for (const auto& [model, bytes] :
         {std::pair{"grid", memory.grid_bytes}, std::pair{"distance_field", memory.distance_field_bytes},
          std::pair{"octomap", memory.octomap_bytes}, std::pair{"ptem", memory.ptem_bytes}}) {
      core.metrics()
          .gauge("occgeo_world_model_bytes", {{"world", world->name()}, {"model", model}},
                 "Heap bytes of a world's model as of its latest snapshot, counted by the server")
          .set(static_cast<std::int64_t>(bytes));
    }
  }
  if (const auto resident = process_resident_bytes()) {
    core.metrics()
        .gauge("occgeo_process_resident_bytes", {}, "Resident memory of the server process (/proc/self/statm)")
        .set(static_cast<std::int64_t>(*resident));
  }
}

Response route(ServerCore& core, const Request& request) {
  std::string_view target(request.target().data(), request.target().size());
  if (const auto query = target.find('?'); query != std::string_view::npos) target = target.substr(0, query);
  if (request.method() != bhttp::verb::get) {
    auto response = make_response(request, bhttp::status::method_not_allowed, "text/plain; charset=utf-8",
                                  "only GET is served here\n");
    response.set(bhttp::field::allow, "GET");
    return response;
  }
  if (target == "/metrics") {
    record_world_gauges(core);
    return make_response(request, bhttp::status::ok, "text/plain; version=0.0.4; charset=utf-8",
                         core.metrics().render());
  }
  const std::string_view asset_path = target == "/" ? "/index.html" : target;
  for (const auto& asset : web_assets()) {
    if (asset.path == asset_path) {
      return make_response(request, bhttp::status::ok, asset.content_type, std::string(asset.body));
    }
  }
  if (target == "/ws") {
    return make_response(request, bhttp::status::upgrade_required, "text/plain; charset=utf-8",
                         "/ws is a WebSocket endpoint\n");
  }
  return make_response(request, bhttp::status::not_found, "text/plain; charset=utf-8",
                       "no such page; the live view is at /, metrics at /metrics\n");
}

// One of the http.max_connections places, held by a connection (and by the WebSocket it upgrades to) while it is
// open; the count drops when the last holder goes.
using ConnectionSlot = std::shared_ptr<void>;

// A message to write on a WebSocket.
struct Outgoing {
  std::string bytes;
  bool binary = false;
  std::optional<std::uint32_t> subscription;  // a subscription's data: replaced by a newer one while waiting
};

// What every WebSocket session here does alike: accept (counted in occgeo_web_clients), read messages one at a time,
// tick every kFramePeriod, and write one message at a time, asking the session for the next only when the previous is
// written (so a slow client gets fewer, newer messages rather than a queue). Derived provides on_accepted(),
// on_message(text), on_tick() and next_outgoing(); it calls pump() when it has something new to send.
template <typename Derived>
class WebSocketSession : public std::enable_shared_from_this<Derived> {
 public:
  WebSocketSession(metrics::Registry& metrics, tcp::socket socket)
      : metrics_(metrics),
        web_clients_(metrics.gauge("occgeo_web_clients")),
        ws_(std::move(socket)),
        timer_(ws_.get_executor()) {}
  ~WebSocketSession() {
    if (accepted_) web_clients_.dec();
  }

  // subprotocol: answered in Sec-WebSocket-Protocol when not empty. slot: the connection's place, kept while open.
  void run(Request request, ConnectionSlot slot, std::string_view subprotocol = {}) {
    request_ = std::move(request);
    slot_ = std::move(slot);
    beast::get_lowest_layer(ws_).expires_never();
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    if (!subprotocol.empty()) {
      ws_.set_option(websocket::stream_base::decorator([subprotocol](websocket::response_type& response) {
        response.set(bhttp::field::sec_websocket_protocol, beast::string_view(subprotocol.data(), subprotocol.size()));
      }));
    }
    ws_.read_message_max(64 * 1024);
    ws_.async_accept(request_, [self = this->shared_from_this()](const beast::error_code& error) {
      if (error) return;
      self->accepted_ = true;
      self->web_clients_.inc();
      self->read();
      self->on_accepted();
      self->tick();
    });
  }

 protected:
  void pump() {
    if (writing_ || closed_) return;
    std::optional<Outgoing> next = derived().next_outgoing();
    if (!next) return;
    current_ = std::move(*next);
    writing_ = true;
    ws_.binary(current_.binary);
    ws_.async_write(asio::buffer(current_.bytes),
                    [self = this->shared_from_this()](const beast::error_code& error, std::size_t) {
                      self->writing_ = false;
                      if (error) {
                        self->close();
                        return;
                      }
                      self->pump();
                    });
  }

 private:
  Derived& derived() { return static_cast<Derived&>(*this); }

  void read() {
    ws_.async_read(read_buffer_, [self = this->shared_from_this()](const beast::error_code& error, std::size_t) {
      if (error) {
        self->close();
        return;
      }
      const std::string text = beast::buffers_to_string(self->read_buffer_.data());
      self->read_buffer_.consume(self->read_buffer_.size());
      self->on_message(text);
      self->read();
    });
  }

  void tick() {
    timer_.expires_after(kFramePeriod);
    timer_.async_wait([self = this->shared_from_this()](const beast::error_code& error) {
      if (error || self->closed_) return;
      self->on_tick();
      self->tick();
    });
  }

  void close() {
    closed_ = true;
    timer_.cancel();
  }

 protected:
  metrics::Registry& metrics() { return metrics_; }

 private:
  metrics::Registry& metrics_;
  metrics::Gauge& web_clients_;

 protected:
  websocket::stream<beast::tcp_stream> ws_;
  asio::steady_timer timer_;
  ConnectionSlot slot_;
  Request request_;
  beast::flat_buffer read_buffer_;
  Outgoing current_;
  bool accepted_ = false;
  bool writing_ = false;
  bool closed_ = false;
};

// One browser's live view over a WebSocket. At most one frame is being written and at most one more waits; a frame
// is built only when it is about to be written, so a slow browser gets fewer, newer frames (the older waiting one is
// dropped and counted) and never misses a map change (tile differences are computed against what it was sent).
class LiveViewSocket final : public WebSocketSession<LiveViewSocket> {
 public:
  LiveViewSocket(ServerCore& core, tcp::socket socket)
      : WebSocketSession(core.metrics(), std::move(socket)), state_(core) {}

 private:
  friend class WebSocketSession<LiveViewSocket>;

  void on_accepted() {
    frame_waiting_ = true;
    pump();
  }

  void on_message(const std::string& text) {
    if (replies_.size() < kMaxQueuedReplies) {
      replies_.push_back(state_.handle_message(text));
    } else {
      metrics().counter("occgeo_observer_messages_dropped_total", {{"channel", "web"}}).inc();
    }
    pump();
  }

  void on_tick() {
    if (frame_waiting_) metrics().counter("occgeo_observer_messages_dropped_total", {{"channel", "web"}}).inc();
    frame_waiting_ = true;
    pump();
  }

  std::optional<Outgoing> next_outgoing() {
    if (!replies_.empty()) {
      Outgoing reply{std::move(replies_.front()), false, std::nullopt};
      replies_.pop_front();
      return reply;
    }
    if (!frame_waiting_) return std::nullopt;
    frame_waiting_ = false;
    return Outgoing{state_.next_frame(), false, std::nullopt};
  }

  LiveViewState state_;
  std::deque<std::string> replies_;
  bool frame_waiting_ = false;
};

// One Foxglove WebSocket client (foxglove.websocket.v1, see foxglove.h): serverInfo and advertise on connecting, then
// the subscribed channels, checked ten times a second. One message is written at a time and at most one per channel
// waits, replaced by a newer one (counted as dropped), so a slow client costs no queue.
class FoxgloveSocket final : public WebSocketSession<FoxgloveSocket> {
 public:
  FoxgloveSocket(ServerCore& core, tcp::socket socket)
      : WebSocketSession(core.metrics(), std::move(socket)), core_(core) {}

 private:
  friend class WebSocketSession<FoxgloveSocket>;

  void on_accepted() {
    // Numbered with the protocol sessions, from the server's own counter.
    queue(foxglove::server_info(core_.next_session_id.fetch_add(1)), false);
    queue(foxglove::advertise(), false);
  }

  void on_message(const std::string& text) {
    const foxglove::ClientRequest request = foxglove::parse_client_request(text);
    if (!request.problem.empty()) {
      // Logged at the 1st, 2nd, 4th, 8th... of a connection's bad messages: a client sending nothing else cannot
      // fill the log.
      ++not_understood_;
      if (std::has_single_bit(not_understood_)) {
        log::warn("foxglove_message_not_understood",
                  {{"op", request.op}, {"problem", request.problem}, {"count", not_understood_}});
      }
    }
    for (const std::uint32_t id : request.unsubscribe) {
      std::erase_if(subscriptions_, [&](const Subscribed& s) { return s.id == id; });
    }
    for (const auto& subscription : request.subscribe) {
      if (subscription.channel != foxglove::kMapChannel && subscription.channel != foxglove::kScansChannel) continue;
      std::erase_if(subscriptions_, [&](const Subscribed& s) { return s.id == subscription.id; });
      subscriptions_.push_back({subscription.id, subscription.channel, {}, {}});
    }
    if (request.op == "subscribe") publish();
  }

  void on_tick() { publish(); }

  std::optional<Outgoing> next_outgoing() {
    if (outgoing_.empty()) return std::nullopt;
    Outgoing next = std::move(outgoing_.front());
    outgoing_.pop_front();
    return next;
  }

  void queue(std::string bytes, bool binary, std::optional<std::uint32_t> subscription = std::nullopt) {
    if (subscription) {
      for (auto& waiting : outgoing_) {
        if (waiting.subscription == subscription) {
          metrics().counter("occgeo_observer_messages_dropped_total", {{"channel", "foxglove"}}).inc();
          waiting.bytes = std::move(bytes);
          return;
        }
      }
    }
    outgoing_.push_back({std::move(bytes), binary, subscription});
    pump();
  }

  // Sends each subscription what changed since it was last sent.
  void publish() {
    if (subscriptions_.empty()) return;
    const auto world = core_.find_world(foxglove::shown_world(core_));
    if (!world) return;
    const auto now = std::chrono::steady_clock::now();
    const auto time_ns = static_cast<std::uint64_t>(
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count());
    const double stamp_s = static_cast<double>(time_ns) * 1e-9;
    for (auto& subscription : subscriptions_) {
      if (subscription.channel == foxglove::kMapChannel) {
        const auto grid = world->snapshots().grid;
        if (subscription.sent_version == grid->version()) continue;
        if (subscription.sent_at && now - *subscription.sent_at < std::chrono::seconds(1)) continue;
        const auto message = foxglove::grid_message(*grid, stamp_s);
        if (!message) continue;
        subscription.sent_version = grid->version();
        subscription.sent_at = now;
        queue(foxglove::message_data(subscription.id, time_ns, *message), true, subscription.id);
      } else {
        std::vector<std::vector<Eigen::Vector2f>> scans_W;
        double newest_s = 0.0;
        for (const auto& robot : core_.robots()) {
          if (&robot->world() != world.get()) continue;
          const RobotState state = robot->state();
          if (!state.scan_stamp_s || !state.scan_W) continue;
          newest_s = std::max(newest_s, *state.scan_stamp_s);
          scans_W.push_back(*state.scan_W);
        }
        // The scans' newest stamp stands for their version: robots' stamps never go backwards.
        const auto version = static_cast<std::uint64_t>(std::llround(newest_s * 1e6)) + scans_W.size();
        if (scans_W.empty() || subscription.sent_version == version) continue;
        subscription.sent_version = version;
        queue(foxglove::message_data(subscription.id, time_ns, foxglove::scans_message(scans_W, stamp_s)), true,
              subscription.id);
      }
    }
  }

  struct Subscribed {
    std::uint32_t id = 0;
    std::uint32_t channel = 0;
    std::optional<std::uint64_t> sent_version;
    std::optional<std::chrono::steady_clock::time_point> sent_at;
  };

  std::uint64_t not_understood_ = 0;  // messages of this connection that were not understood
  ServerCore& core_;
  std::deque<Outgoing> outgoing_;
  std::vector<Subscribed> subscriptions_;
};

// Whether a WebSocket upgrade asks for the Foxglove protocol.
bool wants_foxglove(const Request& request) {
  const auto protocols = request[bhttp::field::sec_websocket_protocol];
  return std::string_view(protocols.data(), protocols.size()).find(foxglove::kSubprotocol) != std::string_view::npos;
}

// The request's path without its query.
std::string_view path_of(std::string_view target) {
  const auto query = target.find('?');
  return query == std::string_view::npos ? target : target.substr(0, query);
}

// The value of `token=` in the target's query, if any.
std::optional<std::string_view> query_token(std::string_view target) {
  const auto query = target.find('?');
  if (query == std::string_view::npos) return std::nullopt;
  std::string_view rest = target.substr(query + 1);
  while (!rest.empty()) {
    const auto amp = rest.find('&');
    const std::string_view pair = rest.substr(0, amp);
    if (pair.starts_with("token=")) return pair.substr(6);
    if (amp == std::string_view::npos) break;
    rest = rest.substr(amp + 1);
  }
  return std::nullopt;
}

// One HTTP/1.1 connection: requests in order, keep-alive; an upgrade on /ws hands the socket to a LiveViewSocket, and
// an upgrade asking for the foxglove.websocket.v1 subprotocol (on any path) to a FoxgloveSocket.
class HttpConnection : public std::enable_shared_from_this<HttpConnection> {
 public:
  HttpConnection(ServerCore& core, tcp::socket socket, ConnectionSlot slot)
      : core_(core), stream_(std::move(socket)), slot_(std::move(slot)) {}

  void read() {
    parser_.emplace();
    parser_->header_limit(16 * 1024);
    parser_->body_limit(64 * 1024);
    stream_.expires_after(std::chrono::seconds(30));
    bhttp::async_read(
        stream_, buffer_, *parser_,
        [self = shared_from_this()](const beast::error_code& error, std::size_t) { self->on_read(error); });
  }

 private:
  void on_read(const beast::error_code& error) {
    if (error) {
      beast::error_code ignored;
      stream_.socket().shutdown(tcp::socket::shutdown_both, ignored);
      return;
    }
    Request request = parser_->release();
    const std::string_view target(request.target().data(), request.target().size());
    if (auto refusal = refuse(request)) {
      auto response = std::make_shared<Response>(std::move(*refusal));
      core_.metrics()
          .counter("occgeo_http_requests_total",
                   {{"path", path_label(path_of(target))}, {"code", std::to_string(response->result_int())}})
          .inc();
      bhttp::async_write(stream_, *response,
                         [self = shared_from_this(), response](const beast::error_code&, std::size_t) {
                           beast::error_code ignored;
                           self->stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
                         });
      return;
    }
    if (websocket::is_upgrade(request) && wants_foxglove(request)) {
      core_.metrics().counter("occgeo_http_requests_total", {{"path", "foxglove"}, {"code", "101"}}).inc();
      std::make_shared<FoxgloveSocket>(core_, stream_.release_socket())
          ->run(std::move(request), slot_, foxglove::kSubprotocol);
      return;
    }
    if (websocket::is_upgrade(request) && path_of(target) == "/ws") {
      core_.metrics().counter("occgeo_http_requests_total", {{"path", "/ws"}, {"code", "101"}}).inc();
      std::make_shared<LiveViewSocket>(core_, stream_.release_socket())->run(std::move(request), slot_);
      return;
    }
    auto response = std::make_shared<Response>(route(core_, request));
    core_.metrics()
        .counter("occgeo_http_requests_total",
                 {{"path", path_label(target)}, {"code", std::to_string(response->result_int())}})
        .inc();
    bhttp::async_write(stream_, *response,
                       [self = shared_from_this(), response](const beast::error_code& write_error, std::size_t) {
                         if (write_error || response->need_eof()) {
                           beast::error_code ignored;
                           self->stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
                           return;
                         }
                         self->read();
                       });
  }

  // The answer to a request this server must not serve, or nullopt. With auth.observer_token set (required for an
  // address other than loopback), the page, /metrics and both WebSockets need it, as `?token=` or
  // `Authorization: Bearer`; the page's script and style carry no data and are served to anyone. The live view's
  // WebSocket (it can engage an e-stop) is refused to a browser page of another origin.
  std::optional<Response> refuse(const Request& request) const {
    const std::string_view target(request.target().data(), request.target().size());
    const std::string_view path = path_of(target);
    if (websocket::is_upgrade(request) && path == "/ws") {
      const auto origin = request.find(bhttp::field::origin);
      const auto host = request.find(bhttp::field::host);
      if (origin != request.end()) {
        const std::string_view origin_value(origin->value().data(), origin->value().size());
        const std::string_view host_value =
            host == request.end() ? std::string_view() : std::string_view(host->value().data(), host->value().size());
        const auto scheme_end = origin_value.find("://");
        const std::string_view origin_host =
            scheme_end == std::string_view::npos ? origin_value : origin_value.substr(scheme_end + 3);
        if (host_value.empty() || origin_host != host_value) {
          return make_response(request, bhttp::status::forbidden, "text/plain; charset=utf-8",
                               "the live view's WebSocket only serves pages of this server (Origin " +
                                   std::string(origin_value) + ")\n");
        }
      }
    }
    const std::string& token = core_.config().auth.observer_token;
    if (token.empty()) return std::nullopt;
    const bool open_asset =
        !websocket::is_upgrade(request) && path != "/" && path != "/index.html" && path != "/metrics" && path != "/ws";
    if (open_asset) return std::nullopt;
    std::optional<std::string_view> given = query_token(target);
    if (!given) {
      const auto authorization = request.find(bhttp::field::authorization);
      if (authorization != request.end()) {
        const std::string_view value(authorization->value().data(), authorization->value().size());
        if (value.starts_with("Bearer ")) given = value.substr(7);
      }
    }
    if (given && constant_time_equal(*given, token)) return std::nullopt;
    auto response = make_response(request, bhttp::status::unauthorized, "text/plain; charset=utf-8",
                                  "this server needs the observer token: add ?token=... to the address, or send "
                                  "Authorization: Bearer ...\n");
    response.set(bhttp::field::www_authenticate, "Bearer");
    return response;
  }

  ServerCore& core_;
  beast::tcp_stream stream_;
  ConnectionSlot slot_;
  beast::flat_buffer buffer_;
  std::optional<bhttp::request_parser<bhttp::string_body>> parser_;
};

}  // namespace

struct HttpServer::Impl {
  Impl(ServerCore& server_core) : core(server_core) {}

  ServerCore& core;
  asio::io_context io{1};
  tcp::acceptor acceptor{io};
  std::thread thread;

  // Open connections; shared with the slots, which may outlive this (a session ending after stop()).
  std::shared_ptr<std::atomic<std::size_t>> open_connections = std::make_shared<std::atomic<std::size_t>>(0);

  void accept() {
    acceptor.async_accept([this](const beast::error_code& error, tcp::socket socket) {
      if (error) {
        if (error == asio::error::operation_aborted) return;
        log::warn("http_accept_failed", {{"error", error.message()}});
      } else if (open_connections->load() >= core.config().http.max_connections) {
        core.metrics()
            .counter("occgeo_http_refused_total", {}, "HTTP connections closed at once: http.max_connections were open")
            .inc();
        log::warn("http_connection_refused",
                  {{"open", open_connections->load()}, {"max_connections", core.config().http.max_connections}});
        beast::error_code ignored;
        socket.close(ignored);
      } else {
        ++*open_connections;
        ConnectionSlot slot(nullptr, [open = open_connections](void*) { --*open; });
        std::make_shared<HttpConnection>(core, std::move(socket), std::move(slot))->read();
      }
      accept();
    });
  }
};

HttpServer::HttpServer(ServerCore& core, const std::string& listen) : impl_(std::make_unique<Impl>(core)) {
  const auto [host, port] = split_host_port(listen, "http.listen");
  boost::system::error_code error;
  const auto address = asio::ip::make_address(host, error);
  if (error) throw ConfigError("http.listen address '" + host + "' is not an IP address");
  const tcp::endpoint endpoint(address, port);
  impl_->acceptor.open(endpoint.protocol());
  impl_->acceptor.set_option(tcp::acceptor::reuse_address(true));
  impl_->acceptor.bind(endpoint, error);
  if (error) throw std::runtime_error("cannot listen for HTTP on " + listen + ": " + error.message());
  impl_->acceptor.listen();
}

HttpServer::~HttpServer() { stop(); }

std::uint16_t HttpServer::port() const { return impl_->acceptor.local_endpoint().port(); }

void HttpServer::start() {
  impl_->accept();
  impl_->thread = std::thread([this] { impl_->io.run(); });
}

void HttpServer::stop() {
  if (!impl_) return;
  // Stopping the context abandons every connection's pending work; their sockets close when the context (and the
  // handlers it still holds) is destroyed with this object.
  asio::post(impl_->io, [this] {
    boost::system::error_code ignored;
    impl_->acceptor.close(ignored);
    impl_->io.stop();
  });
  if (impl_->thread.joinable()) {
    impl_->thread.join();
  } else {
    impl_->io.stop();
  }
}

}  // namespace occgeo::service::http
