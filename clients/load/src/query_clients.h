#pragma once

// The load tool's query clients (the --mix of requests, --depth in flight each) and observers, and the threads that
// run them on one io_context each.

#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <limits>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "load_common.h"
#include "occgeo/client/connection.h"
#include "occgeo/client/pipeline.h"
#include "occgeo/load/load_run.h"
#include "occgeo/proto/protocol.h"

namespace occgeo::load::internal {

namespace asio = boost::asio;

// ---- query clients and observers ----------------------------------------------------------------------------------

// What one client thread measured.
struct ThreadResult {
  std::vector<Samples> per_kind;  // indexed like the mix's kinds; the last one is the observers' polls
  std::vector<std::uint64_t> errors_per_kind;
  std::uint64_t watch_events = 0;   // WatchEvents the observers received
  std::uint64_t watch_dropped = 0;  // events the server says it dropped for them
};

// Everything shared by the client threads.
struct ClientShared {
  const LoadOptions& options;
  client::Endpoint endpoint;
  std::vector<QueryKind> kinds;           // the mix's kinds
  std::vector<std::uint32_t> cumulative;  // cumulative weights, for picking a kind
  ErrorLog& errors;
  std::atomic<bool> measuring{false};       // replies count while set
  std::atomic<bool> stopping{false};        // no new requests once set
  std::atomic<std::uint64_t> completed{0};  // replies counted, for the progress line
};

inline v1::Hello make_hello(v1::Role role, const std::string& name) {
  v1::Hello hello;
  hello.set_protocol_version(occgeo::proto::kProtocolVersion);
  hello.set_role(role);
  hello.set_client_name(name);
  return hello;
}

// SplitMix64 (Steele, Lea and Flood 2014): random enough for query poses, and a few instructions per number where a
// Mersenne twister's refills showed in the client's profile.
class SplitMix64 {
 public:
  using result_type = std::uint64_t;
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  static constexpr result_type min() { return 0; }
  static constexpr result_type max() { return std::numeric_limits<result_type>::max(); }
  result_type operator()() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31U);
  }

 private:
  std::uint64_t state_;
};

// A uniform double in [lo, hi) from the top 53 bits of one number: std::uniform_real_distribution works the engine's
// range out with long-double logarithms on every call.
struct UniformReal {
  UniformReal(double lo_in, double hi_in) : lo(lo_in), hi(hi_in) {}
  double operator()(SplitMix64& random) const {
    return lo + (hi - lo) * (static_cast<double>(random() >> 11U) * 0x1.0p-53);
  }
  double lo, hi;
};

// One query client: keeps `depth` requests of the mix in flight.
class QueryClient {
 public:
  QueryClient(ClientShared& shared, ThreadResult& result, asio::io_context& io, std::uint64_t seed)
      : shared_(shared), result_(result), random_(seed) {
    connection_ = client::PipelinedConnection::open(io, shared.endpoint, make_hello(v1::ROLE_QUERY, "occgeo-load"),
                                                    shared.options.depth);
  }

  void start() {
    while (connection_->healthy() && connection_->can_submit() && !shared_.stopping.load(std::memory_order_relaxed)) {
      submit_one();
    }
  }
  [[nodiscard]] bool idle() const { return !connection_->healthy() || connection_->in_flight() == 0; }
  void close() { connection_->close(); }

 private:
  void submit_one() {
    const std::size_t kind_index = pick_kind();
    fill_request(shared_.kinds[kind_index], request_);
    connection_->async_submit_in_place(
        request_, [this, kind_index](client::Reply&& reply) { on_reply(kind_index, std::move(reply)); });
  }

  void on_reply(std::size_t kind_index, client::Reply&& reply) {
    if (!reply.ok()) {
      ++result_.errors_per_kind[kind_index];
      shared_.errors.add(std::string(query_kind_name(shared_.kinds[kind_index])) + ": " + reply.error_text());
    } else if (shared_.measuring.load(std::memory_order_relaxed)) {
      add_sample(result_.per_kind[kind_index], reply.latency());
      // The shared count (for the progress line only) is updated in steps, not by every client thread per reply.
      if (++unreported_completions_ == kCompletionsPerReport) {
        shared_.completed.fetch_add(kCompletionsPerReport, std::memory_order_relaxed);
        unreported_completions_ = 0;
      }
    }
    if (connection_->healthy() && !shared_.stopping.load(std::memory_order_relaxed)) submit_one();
  }

  std::size_t pick_kind() {
    if (shared_.kinds.size() == 1) return 0;
    std::uniform_int_distribution<std::uint32_t> pick(0, shared_.cumulative.back() - 1);
    const std::uint32_t value = pick(random_);
    return static_cast<std::size_t>(std::upper_bound(shared_.cumulative.begin(), shared_.cumulative.end(), value) -
                                    shared_.cumulative.begin());
  }

  // Makes `message` a fresh request of `kind`. Each kind's body is cleared rather than the whole message, so a
  // message refilled with the same kind keeps its allocations (strings, nested and repeated messages).
  void fill_request(QueryKind kind, v1::ClientMessage& message) {
    UniformReal coordinate(-shared_.options.area_half_size_m, shared_.options.area_half_size_m);
    UniformReal heading(-std::numbers::pi, std::numbers::pi);
    switch (kind) {
      case QueryKind::collision: {
        v1::CollisionQuery& query = *message.mutable_collision();
        query.Clear();
        query.set_robot_id(kSeedRobotId);
        query.mutable_pose()->set_x(coordinate(random_));
        query.mutable_pose()->set_y(coordinate(random_));
        query.mutable_pose()->set_theta(heading(random_));
        break;
      }
      case QueryKind::clearance: {
        v1::ClearanceQuery& query = *message.mutable_clearance();
        query.Clear();
        query.set_robot_id(kSeedRobotId);
        query.mutable_pose()->set_x(coordinate(random_));
        query.mutable_pose()->set_y(coordinate(random_));
        query.mutable_pose()->set_theta(heading(random_));
        query.set_max_distance_m(2.0);
        break;
      }
      case QueryKind::ptem: {
        v1::PtemQuery& query = *message.mutable_ptem();
        query.Clear();
        for (std::uint32_t i = 0; i < shared_.options.ptem_points; ++i) {
          v1::Point2D& point = *query.add_points();
          point.set_x(coordinate(random_));
          point.set_y(coordinate(random_));
        }
        break;
      }
      case QueryKind::status:
        message.mutable_status()->Clear();
        break;
      case QueryKind::grid:
        message.mutable_grid()->Clear();
        message.mutable_grid()->set_world("default");
        break;
      case QueryKind::octree:
        message.mutable_octree()->Clear();
        break;
      case QueryKind::collision_batch: {
        v1::CollisionBatchQuery& query = *message.mutable_collision_batch();
        query.Clear();
        query.set_robot_id(kSeedRobotId);
        for (std::uint32_t i = 0; i < shared_.options.batch; ++i) random_pose(*query.add_poses());
        break;
      }
      case QueryKind::clearance_batch: {
        v1::ClearanceBatchQuery& query = *message.mutable_clearance_batch();
        query.Clear();
        query.set_robot_id(kSeedRobotId);
        query.set_max_distance_m(2.0);
        for (std::uint32_t i = 0; i < shared_.options.batch; ++i) random_pose(*query.add_poses());
        break;
      }
      case QueryKind::raycast:
      case QueryKind::raycast_batch: {
        v1::RaycastQuery& query = *message.mutable_raycast();
        query.Clear();
        query.set_max_range_m(8.0);
        const std::uint32_t rays = kind == QueryKind::raycast ? 1 : shared_.options.batch;
        for (std::uint32_t i = 0; i < rays; ++i) random_pose(*query.add_rays());
        break;
      }
      case QueryKind::occupancy:
      case QueryKind::occupancy_batch: {
        v1::OccupancyQuery& query = *message.mutable_occupancy();
        query.Clear();
        const std::uint32_t points = kind == QueryKind::occupancy ? 1 : shared_.options.batch;
        for (std::uint32_t i = 0; i < points; ++i) {
          v1::Vector3& point = *query.add_points();
          point.set_x(coordinate(random_));
          point.set_y(coordinate(random_));
          point.set_z(0.3);
        }
        break;
      }
      case QueryKind::swept:
      case QueryKind::swept_batch: {
        v1::SweptQuery& query = *message.mutable_swept();
        query.Clear();
        query.set_robot_id(kSeedRobotId);
        const std::uint32_t motions =
            kind == QueryKind::swept ? 1 : std::min<std::uint32_t>(shared_.options.batch, 1000);
        for (std::uint32_t i = 0; i < motions; ++i) {
          v1::SweptMotion& motion = *query.add_motions();
          random_pose(*motion.mutable_start());
          motion.set_linear_mps(0.5);
          motion.set_angular_radps(0.2);
          motion.set_duration_s(2.0);
        }
        break;
      }
      case QueryKind::grid_window: {
        // A 4 m square somewhere in the area, fetched whole.
        v1::GridWindowRequest& request = *message.mutable_grid_window();
        request.Clear();
        const double x = coordinate(random_);
        const double y = coordinate(random_);
        request.mutable_min_corner()->set_x(x - 2.0);
        request.mutable_min_corner()->set_y(y - 2.0);
        request.mutable_max_corner()->set_x(x + 2.0);
        request.mutable_max_corner()->set_y(y + 2.0);
        break;
      }
      case QueryKind::octree_window: {
        v1::OctreeWindowRequest& request = *message.mutable_octree_window();
        request.Clear();
        const double x = coordinate(random_);
        const double y = coordinate(random_);
        request.mutable_min_corner()->set_x(x - 1.0);
        request.mutable_min_corner()->set_y(y - 1.0);
        request.mutable_min_corner()->set_z(0.0);
        request.mutable_max_corner()->set_x(x + 1.0);
        request.mutable_max_corner()->set_y(y + 1.0);
        request.mutable_max_corner()->set_z(1.0);
        break;
      }
    }
  }

  void random_pose(v1::Pose2D& pose) {
    UniformReal coordinate(-shared_.options.area_half_size_m, shared_.options.area_half_size_m);
    UniformReal heading(-std::numbers::pi, std::numbers::pi);
    pose.set_x(coordinate(random_));
    pose.set_y(coordinate(random_));
    pose.set_theta(heading(random_));
  }

  ClientShared& shared_;
  ThreadResult& result_;
  static constexpr std::uint64_t kCompletionsPerReport = 64;
  SplitMix64 random_;
  std::uint64_t unreported_completions_ = 0;
  v1::ClientMessage request_;  // refilled for every request (fill_request)
  std::unique_ptr<client::PipelinedConnection> connection_;
};

// One observer: polls the server's status every interval.
class Observer {
 public:
  Observer(ClientShared& shared, ThreadResult& result, asio::io_context& io)
      : shared_(shared), result_(result), timer_(io) {
    connection_ = client::PipelinedConnection::open(io, shared.endpoint,
                                                    make_hello(v1::ROLE_OBSERVER, "occgeo-load-observer"), 1);
  }
  void start() {
    connection_->set_unsolicited_handler([this](v1::ServerMessage&& message) {
      if (message.has_watch_event()) {
        if (shared_.measuring.load(std::memory_order_relaxed)) ++result_.watch_events;
        result_.watch_dropped += message.watch_event().dropped_since_last();
      } else if (message.has_error()) {
        shared_.errors.add("observer: " + client::describe(message.error()));
      }
    });
    if (shared_.options.observer_watch) {
      v1::ClientMessage watch;
      watch.mutable_watch();  // every world, every robot
      connection_->async_submit(std::move(watch), [this](client::Reply&& reply) {
        if (!reply.ok()) shared_.errors.add("observer watch: " + reply.error_text());
        poll();
      });
    } else {
      poll();
    }
  }
  [[nodiscard]] bool idle() const { return !connection_->healthy() || connection_->in_flight() == 0; }
  void close() {
    timer_.cancel();
    connection_->close();
  }

 private:
  void poll() {
    if (shared_.stopping.load() || !connection_->healthy()) return;
    if (connection_->can_submit()) {
      v1::ClientMessage request;
      request.mutable_status();
      connection_->async_submit(std::move(request), [this](client::Reply&& reply) {
        const std::size_t index = result_.per_kind.size() - 1;
        if (!reply.ok()) {
          ++result_.errors_per_kind[index];
          shared_.errors.add("observer status: " + reply.error_text());
        } else if (shared_.measuring.load(std::memory_order_relaxed)) {
          add_sample(result_.per_kind[index], reply.latency());
        }
      });
    }
    timer_.expires_after(std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(shared_.options.observer_interval_s)));
    timer_.async_wait([this](const boost::system::error_code& error) {
      if (!error) poll();
    });
  }

  ClientShared& shared_;
  ThreadResult& result_;
  asio::steady_timer timer_;
  std::unique_ptr<client::PipelinedConnection> connection_;
};

// One thread's io_context, its clients and observers.
struct ClientThread {
  asio::io_context io;
  ThreadResult result;
  std::vector<std::unique_ptr<QueryClient>> clients;
  std::vector<std::unique_ptr<Observer>> observers;
  std::thread thread;

  [[nodiscard]] bool idle() const {
    return std::all_of(clients.begin(), clients.end(), [](const auto& c) { return c->idle(); }) &&
           std::all_of(observers.begin(), observers.end(), [](const auto& o) { return o->idle(); });
  }

  void run(ClientShared& shared, const std::atomic<bool>& go) {
    if (shared.options.client_sched_batch)
      set_this_threads_policy(SCHED_BATCH, 0, "--client-sched batch", shared.errors);
    while (!go.load()) std::this_thread::sleep_for(milliseconds(1));
    for (auto& client : clients) client->start();
    for (auto& observer : observers) observer->start();
    std::optional<Clock::time_point> drain_deadline;
    // Keeps run_for waiting out its 20 ms while the thread has nothing to do (no clients, or all waiting for timers):
    // without it an empty io_context returns at once and the loop would spin a core the server needs.
    auto keep_waiting = asio::make_work_guard(io);
    while (true) {
      io.run_for(milliseconds(20));
      if (io.stopped()) io.restart();
      if (shared.stopping.load()) {
        keep_waiting.reset();
        if (!drain_deadline) drain_deadline = Clock::now() + kDrainLimit;
        if (idle()) break;
        if (Clock::now() > *drain_deadline) {
          shared.errors.add("requests still unanswered " + std::to_string(kDrainLimit.count()) +
                            " s after the end of the run");
          break;
        }
      }
    }
    for (auto& client : clients) client->close();
    for (auto& observer : observers) observer->close();
    io.poll();
  }
};

// Poses, rays, points or motions one request of `kind` carries.

}  // namespace occgeo::load::internal
