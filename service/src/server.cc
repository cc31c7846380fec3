#include "occgeo/service/server.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "core.h"
#include "durability/world_store.h"
#include "http/http_server.h"
#include "occgeo/mapfile/map_file.h"
#include "occgeo/service/log.h"
#include "session.h"
#include "tls.h"
#include "validation.h"

namespace occgeo::service {

using asio::ip::tcp;

namespace {

// Every world of the data directory: its snapshot plus the replay of its journal (durability/world_store.h). A damaged
// snapshot, or a journal damaged in its middle, stops the start with the file's name.
void restore_worlds(ServerCore& core) {
  // A journal write beyond RLIMIT_FSIZE must fail with EFBIG (reported, not acknowledged), not kill the server.
  std::signal(SIGXFSZ, SIG_IGN);
  durability::restore_worlds(core);
}

// Runs one network thread's event loop until it stops or runs out of work, as io_context::run() does, but looks for
// the next event for a short while before sleeping in epoll_wait. A client asking again as soon as it has its answer
// (one sequential client) would otherwise find the thread asleep every time, and on a virtual machine an idle vCPU
// halts: waking it costs tens of microseconds, more than the query itself, and the caches come back cold. The window
// adapts as the kernel's guest halt polling does: it doubles (up to kMaxPoll) when a sleep ended within kMaxPoll of
// going idle (polling would have caught that event) and halves when sleeps are longer, so a server whose clients pause
// between requests sleeps at once and costs no CPU while idle. Each poll yields first, so a thread that has work on
// the same core (the client, another network thread) runs before this one looks again; and when a yield did hand the
// core to another process, the core would not have gone idle anyway: the window closes for the next 256 sleeps, so on
// a busy machine the loop behaves as run() does.
void run_network_loop(asio::io_context& loop, double max_poll_us) {
  using Clock = std::chrono::steady_clock;
  const auto kMaxPoll =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double, std::micro>(max_poll_us));
  const Clock::duration kFirstPoll = std::min<Clock::duration>(std::chrono::microseconds(25), kMaxPoll);
  // A yield that took longer than this ran another thread.
  constexpr Clock::duration kYieldRanOther = std::chrono::microseconds(20);
  // After such a yield, sleeps before the window may open again.
  constexpr std::uint32_t kSleepsAfterBusyYield = 256;
  Clock::duration poll_window{0};
  std::uint32_t sleeps_before_polling = 0;
  while (!loop.stopped()) {
    if (loop.poll() > 0) continue;
    if (loop.stopped()) return;  // out of work, as run() returns
    if (kMaxPoll == Clock::duration{0}) {
      if (loop.run_one() == 0) return;
      continue;
    }
    const auto idle_since = Clock::now();
    bool caught = false;
    while (Clock::now() - idle_since < poll_window) {
      const auto yield_start = Clock::now();
      std::this_thread::yield();
      if (Clock::now() - yield_start > kYieldRanOther) {
        poll_window = Clock::duration{0};
        sleeps_before_polling = kSleepsAfterBusyYield;
      }
      if (loop.poll() > 0) {
        caught = true;
        break;
      }
      if (loop.stopped()) return;
    }
    if (caught) continue;
    if (loop.run_one() == 0) return;
    if (sleeps_before_polling > 0) {
      --sleeps_before_polling;
    } else if (Clock::now() - idle_since <= kMaxPoll) {
      poll_window = std::clamp(poll_window * 2, kFirstPoll, kMaxPoll);
    } else {
      poll_window = poll_window / 2 < kFirstPoll ? Clock::duration{0} : poll_window / 2;
    }
  }
}

// Snapshots every world and empties its journal. Runs after the worker pools have been joined, so no strand is
// mutating the worlds any more.
void save_worlds(ServerCore& core) {
  for (const auto& world : core.worlds()) durability::snapshot_world(core, *world);
}

}  // namespace

struct Server::Impl {
  explicit Impl(ServerConfig config) : core(std::move(config)) {}

  ServerCore core;
  SessionShared session_shared;  // watch subscriptions, hello throttle, TLS context
  // One event loop per network thread (queries.network_threads): `net`, run by the thread calling run(), and one
  // more each, and every session lives on one of them (round robin). A session's reads, inline answers and writes
  // then stay on one thread; a loop shared by several threads would hand every event from the thread waiting in
  // epoll to another. The acceptor, the signals and the snapshot timer share the strand `control` of `net`.
  asio::io_context net{1};
  std::vector<std::unique_ptr<asio::io_context>> more_loops;
  std::vector<asio::executor_work_guard<asio::io_context::executor_type>> more_loops_work;  // kept until shutdown
  std::size_t next_loop = 0;                                                                // on control
  asio::strand<asio::io_context::executor_type> control = asio::make_strand(net);
  // Robot drivers' sessions, once they said hello: a loop of their own, run by a thread at the process's priority
  // that answers no client's queries, so a driver's scans are read and its commands written without waiting behind
  // the query sessions sharing a network thread (queries.driver_loop).
  std::unique_ptr<asio::io_context> driver_loop;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> driver_loop_work;
  tcp::acceptor acceptor{control};
  asio::signal_set signals{control, SIGINT, SIGTERM};
  std::mutex sessions_mutex;
  std::vector<std::weak_ptr<Session>> sessions;
  std::unique_ptr<http::HttpServer> http;      // live view and /metrics; after core, so it is destroyed first
  asio::steady_timer snapshot_timer{control};  // durability.snapshot_interval_s

  // Snapshots every world whose journal grew, each on its own strand, every durability.snapshot_interval_s.
  void schedule_snapshots() {
    const double interval_s = core.config().durability.snapshot_interval_s;
    if (interval_s <= 0) return;
    snapshot_timer.expires_after(
        std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(interval_s)));
    snapshot_timer.async_wait([this](const boost::system::error_code& error) {
      if (error) return;
      for (const auto& world : core.worlds()) durability::snapshot_world_if_changed(core, world);
      schedule_snapshots();
    });
  }

  asio::io_context& loop_for_next_session() {
    const std::size_t index = next_loop++ % (more_loops.size() + 1);
    return index == 0 ? net : *more_loops[index - 1];
  }

  // Connections that have not said hello yet from `address`.
  std::size_t silent_sessions_from(const std::string& address) {
    const std::lock_guard lock(sessions_mutex);
    std::size_t count = 0;
    for (const auto& weak : sessions) {
      if (auto session = weak.lock(); session && !session->greeted() && session->peer_address() == address) ++count;
    }
    return count;
  }

  // Closes the oldest connection that has not said hello yet (from `address`, or from anywhere when null), so that
  // silent connections never keep a robot's driver or anyone else out; false when there is none. Sessions are in
  // accept order.
  bool evict_silent_session(const std::string* address) {
    const std::lock_guard lock(sessions_mutex);
    for (auto it = sessions.begin(); it != sessions.end(); ++it) {
      auto session = it->lock();
      if (!session || session->greeted() || (address != nullptr && session->peer_address() != *address)) continue;
      session->close_if_silent();
      sessions.erase(it);
      return true;
    }
    return false;
  }

  void accept() {
    // Each loop is run by one thread, so a session on it needs no strand: its handlers never run concurrently.
    asio::io_context& loop = loop_for_next_session();
    acceptor.async_accept(loop, [this, &loop](const boost::system::error_code& error, tcp::socket socket) {
      if (error) {
        if (error != asio::error::operation_aborted) {
          log::warn("accept_failed", {{"error", error.message()}});
          accept();
        }
        return;
      }
      if (core.sessions.load() >= core.config().limits.max_clients && !evict_silent_session(nullptr)) {
        log::warn("session_refused", {{"reason", "client limit reached"}});
        boost::system::error_code ignored;
        socket.close(ignored);
      } else {
        boost::system::error_code ignored;
        const std::string address = socket.remote_endpoint(ignored).address().to_string();
        if (silent_sessions_from(address) >= core.config().limits.max_silent_per_address) {
          evict_silent_session(&address);
        }
        auto session = std::make_shared<Session>(core, session_shared, loop, std::move(socket), core.next_session_id++);
        {
          const std::lock_guard lock(sessions_mutex);
          std::erase_if(sessions, [](const auto& weak) { return weak.expired(); });
          sessions.push_back(session);
        }
        session->start();
      }
      accept();
    });
  }

  void shutdown() {
    boost::system::error_code ignored;
    acceptor.close(ignored);
    signals.cancel(ignored);
    snapshot_timer.cancel();
    {
      const std::lock_guard lock(sessions_mutex);
      for (const auto& weak : sessions) {
        if (auto session = weak.lock()) session->close();
      }
    }
    // The other loops end once the closes just posted to them have run.
    for (auto& work : more_loops_work) work.reset();
    driver_loop_work.reset();
  }
};

Server::Server(ServerConfig config) {
  config.validate();
  log::set_level(log::parse_level(config.log_level));
  impl_ = std::make_unique<Impl>(std::move(config));
  for (std::size_t i = 1; i < impl_->core.config().queries.network_threads; ++i) {
    impl_->more_loops.push_back(std::make_unique<asio::io_context>(1));
    impl_->more_loops_work.push_back(asio::make_work_guard(*impl_->more_loops.back()));
  }
  if (impl_->core.config().queries.driver_loop) {
    impl_->driver_loop = std::make_unique<asio::io_context>(1);
    impl_->driver_loop_work.emplace(asio::make_work_guard(*impl_->driver_loop));
    impl_->session_shared.driver_loop = impl_->driver_loop.get();
  }
  restore_worlds(impl_->core);
  impl_->core.world(impl_->core.config().default_world);

  const auto [host, port] = split_host_port(impl_->core.config().listen, "listen");
  boost::system::error_code error;
  const auto address = asio::ip::make_address(host, error);
  if (error) throw ConfigError("listen address '" + host + "' is not an IP address");
  const tcp::endpoint endpoint(address, port);
  impl_->acceptor.open(endpoint.protocol());
  impl_->acceptor.set_option(tcp::acceptor::reuse_address(true));
  impl_->acceptor.bind(endpoint, error);
  if (error) throw std::runtime_error("cannot listen on " + impl_->core.config().listen + ": " + error.message());
  impl_->acceptor.listen();
  // The web view is an aid, not the service: a busy HTTP port is logged and the server runs without it.
  if (impl_->core.config().http.enabled) {
    try {
      impl_->http = std::make_unique<http::HttpServer>(impl_->core, impl_->core.config().http.listen);
    } catch (const std::runtime_error& e) {
      if (dynamic_cast<const ConfigError*>(&e) != nullptr) throw;
      log::error("http_listen_failed", {{"address", impl_->core.config().http.listen}, {"error", e.what()}});
    }
  }
  if (impl_->core.config().tls.enabled()) impl_->session_shared.tls = make_tls_context(impl_->core.config().tls);
}

Server::~Server() = default;

std::uint16_t Server::port() const { return impl_->acceptor.local_endpoint().port(); }

void Server::run() {
  impl_->signals.async_wait([this](const boost::system::error_code& error, int signal) {
    if (error) return;
    log::info("signal_received", {{"signal", signal}});
    impl_->shutdown();
  });
  impl_->accept();
  impl_->schedule_snapshots();
  log::info("server_listening", {{"address", impl_->core.config().listen},
                                 {"port", static_cast<unsigned>(port())},
                                 {"tls", impl_->core.config().tls.enabled()},
                                 {"data_dir", impl_->core.config().data_dir.string()}});
  if (impl_->http) {
    impl_->http->start();
    log::info("http_listening",
              {{"address", impl_->core.config().http.listen}, {"port", static_cast<unsigned>(impl_->http->port())}});
  }
  std::vector<std::thread> more_network_threads;
  const double poll_us = impl_->core.config().queries.network_poll_us;
  const int nice = impl_->core.config().queries.network_nice;
  for (auto& loop : impl_->more_loops) {
    more_network_threads.emplace_back([&loop, poll_us, nice] {
      lower_this_threads_priority(nice, "network_nice_not_applied");
      run_network_loop(*loop, poll_us);
    });
  }
  // Started before the calling thread lowers its priority, so the driver loop keeps the process's niceness (under
  // SCHED_FIFO at control.realtime_priority where the process may).
  std::thread driver_thread;
  if (impl_->driver_loop) {
    driver_thread = std::thread(
        [loop = impl_->driver_loop.get(), poll_us, priority = impl_->core.config().control.realtime_priority] {
          make_this_thread_realtime(priority, "driver_loop_realtime_not_applied");
          run_network_loop(*loop, poll_us);
        });
  }
  // The calling thread serves `net` too. Threads it starts later inherit its niceness; every pool exists by now.
  lower_this_threads_priority(nice, "network_nice_not_applied");
  run_network_loop(impl_->net, poll_us);
  for (std::thread& thread : more_network_threads) thread.join();
  if (driver_thread.joinable()) driver_thread.join();
  if (impl_->http) impl_->http->stop();
  impl_->core.drain();
  save_worlds(impl_->core);
  log::info("server_stopped");
}

void Server::stop() {
  asio::post(impl_->control, [this] { impl_->shutdown(); });
}

}  // namespace occgeo::service
