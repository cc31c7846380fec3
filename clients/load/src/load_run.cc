#include "occgeo/load/load_run.h"
#include "occgeo/proto/protocol.h"

#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <mutex>
#include <numbers>
#include <random>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <unordered_map>

#include "occgeo/client/connection.h"
#include "occgeo/client/json.h"
#include "occgeo/client/pipeline.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/robot.h"
#include "occgeo/sim/sim_world.h"
#include "occgeo/sim/simulation.h"

extern char** environ;

namespace occgeo::load {

namespace {

namespace asio = boost::asio;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

constexpr std::size_t kMaxErrorSamples = 8;
constexpr auto kDrainLimit = std::chrono::seconds(5);
constexpr auto kLockstepAnswerTimeout = std::chrono::seconds(10);
constexpr const char* kSeedRobotId = "load-seed";

// Errors from every thread: a count and the first few messages.
class ErrorLog {
 public:
  void add(const std::string& text) {
    count_.fetch_add(1, std::memory_order_relaxed);
    const std::lock_guard lock(mutex_);
    if (samples_.size() < kMaxErrorSamples) samples_.push_back(text);
  }
  [[nodiscard]] std::uint64_t count() const { return count_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::vector<std::string> samples() const {
    const std::lock_guard lock(mutex_);
    return samples_;
  }

 private:
  std::atomic<std::uint64_t> count_{0};
  mutable std::mutex mutex_;
  std::vector<std::string> samples_;
};

// Latency samples, nanoseconds.
using Samples = std::vector<std::uint64_t>;

void add_sample(Samples& samples, std::chrono::nanoseconds latency) {
  samples.push_back(static_cast<std::uint64_t>(std::max<std::int64_t>(latency.count(), 0)));
}

// The q-quantile of sorted samples, microseconds.
double quantile_us(const Samples& sorted, double q) {
  if (sorted.empty()) return 0.0;
  const auto index = static_cast<std::size_t>(std::ceil(q * static_cast<double>(sorted.size()))) - 1;
  return static_cast<double>(sorted[std::min(index, sorted.size() - 1)]) / 1000.0;
}

// ---- the server process -------------------------------------------------------------------------------------------

// CPU ticks (user + system) of a process, or nullopt when it is gone.
std::optional<std::uint64_t> process_cpu_ticks(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text;
  if (!std::getline(in, text)) return std::nullopt;
  // Fields after the parenthesised command name, which may itself hold spaces.
  std::istringstream fields(text.substr(text.rfind(')') + 2));
  std::string field;
  std::uint64_t utime = 0;
  std::uint64_t stime = 0;
  for (int index = 3; fields >> field; ++index) {
    if (index == 14) utime = std::stoull(field);
    if (index == 15) {
      stime = std::stoull(field);
      return utime + stime;
    }
  }
  return std::nullopt;
}

// VmRSS and VmHWM of a process, kB.
std::pair<std::uint64_t, std::uint64_t> process_memory_kb(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  std::uint64_t rss = 0;
  std::uint64_t peak = 0;
  while (std::getline(in, line)) {
    if (line.starts_with("VmRSS:")) rss = std::stoull(line.substr(6));
    if (line.starts_with("VmHWM:")) peak = std::stoull(line.substr(6));
  }
  return {rss, peak};
}

double own_cpu_seconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const auto seconds = [](const timeval& t) {
    return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec);
  };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

// occgeod on a free 127.0.0.1 port with a temporary data directory; stopped and cleaned up on destruction.
class StartedServer {
 public:
  StartedServer(const std::filesystem::path& binary, const std::optional<std::filesystem::path>& config) {
    std::string pattern = (std::filesystem::temp_directory_path() / "occgeo-load-XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("cannot create a temporary directory");
    dir_ = pattern;
    const auto port_file = dir_ / "port";
    std::vector<std::string> argv = {binary.string(),    "--listen",   "127.0.0.1:0",           "--port-file",
                                     port_file.string(), "--data-dir", (dir_ / "data").string()};
    if (config) {
      argv.emplace_back("--config");
      argv.push_back(config->string());
    }
    std::vector<char*> raw;
    for (auto& arg : argv) raw.push_back(arg.data());
    raw.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    const std::string log = (dir_ / "occgeod.log").string();
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
    const int error = posix_spawn(&pid_, raw[0], &actions, nullptr, raw.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (error != 0) {
      cleanup();
      throw std::runtime_error("cannot start " + binary.string() + ": " + std::strerror(error));
    }
    const auto deadline = Clock::now() + std::chrono::seconds(20);
    while (Clock::now() < deadline) {
      std::ifstream in(port_file);
      unsigned port = 0;
      if (in >> port && port > 0 && port < 65536) {
        port_ = static_cast<std::uint16_t>(port);
        return;
      }
      if (!alive()) break;
      std::this_thread::sleep_for(milliseconds(20));
    }
    const std::string tail = log_tail();
    stop();
    cleanup();
    throw std::runtime_error("occgeod did not start listening within 20 s: " + tail);
  }
  StartedServer(const StartedServer&) = delete;
  StartedServer& operator=(const StartedServer&) = delete;
  ~StartedServer() {
    stop();
    cleanup();
  }

  [[nodiscard]] int pid() const { return pid_; }
  [[nodiscard]] std::uint16_t port() const { return port_; }
  bool alive() {
    if (exited_) return false;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      exited_ = true;
      exit_status_ = status;
      return false;
    }
    return true;
  }
  std::string log_tail() const {
    std::ifstream in(dir_ / "occgeod.log");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return text.size() > 2000 ? text.substr(text.size() - 2000) : text;
  }
  // SIGTERM, then SIGKILL after 20 s.
  void stop() {
    if (!alive()) return;
    kill(pid_, SIGTERM);
    const auto deadline = Clock::now() + std::chrono::seconds(20);
    while (Clock::now() < deadline && alive()) std::this_thread::sleep_for(milliseconds(10));
    if (alive()) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
      exited_ = true;
    }
  }

 private:
  void cleanup() {
    std::error_code ignored;
    std::filesystem::remove_all(dir_, ignored);
  }
  std::filesystem::path dir_;
  pid_t pid_ = -1;
  std::uint16_t port_ = 0;
  bool exited_ = false;
  int exit_status_ = 0;
};

// ---- simulated robots ---------------------------------------------------------------------------------------------

struct RobotResult {
  std::uint64_t scans = 0;
  Samples ingest;   // send of a sensor batch to the ScanAck of its last sensor message
  Samples command;  // send of a steering scan to the MotionCommand answering it (the control loop)
};

// Drives one simulated robot until `stop` (or for `scan_limit` batches when set), recording ingest latency.
class RobotDriver {
 public:
  RobotDriver(const LoadOptions& options, const client::Endpoint& endpoint, std::string robot_id, std::uint64_t seed,
              double heading_rad, ErrorLog& errors)
      : options_(options), robot_id_(std::move(robot_id)), errors_(errors) {
    const sim::RobotPreset* preset = sim::find_robot_preset(options.robot_preset);
    if (preset == nullptr) {
      throw LoadArgsError("--robot: unknown preset '" + options.robot_preset + "' (" + sim::robot_preset_names() + ")");
    }
    const geometry::Pose2 start{0.0, 0.0, heading_rad};
    simulation_ = std::make_unique<sim::Simulation>(sim::load_sim_world(options.world_file), *preset, start, seed);
    connection_.emplace(client::Connection::open(endpoint));
    connection_->hello(sim::make_driver_hello(robot_id_, ""));
    v1::ClientMessage spec;
    *spec.mutable_robot_spec() = sim::make_robot_spec(*preset, start);
    connection_->send(spec);
  }

  // Lockstep batches until `batches` sensor batches were answered.
  void run_lockstep_batches(std::uint32_t batches, const std::atomic<bool>& stop) {
    std::uint32_t sent = 0;
    while (sent < batches && !stop.load()) {
      if (simulation_->batch_due()) {
        send_batch(true);
        ++sent;
      }
      simulation_->step();
    }
  }

  void run(const std::atomic<bool>& stop) {
    const bool lockstep = options_.robot_pace == RobotPace::lockstep;
    const auto wall_start = Clock::now();
    while (!stop.load()) {
      if (simulation_->batch_due()) send_batch(lockstep);
      if (!lockstep) {
        const auto step_end =
            wall_start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(
                             static_cast<double>(simulation_->robot().step_count() + 1) * sim::kPhysicsStep_s));
        do {
          const auto wait = std::chrono::duration_cast<milliseconds>(step_end - Clock::now());
          const auto message = connection_->receive(std::max(wait, milliseconds(0)));
          if (!message) break;
          handle(*message);
        } while (Clock::now() < step_end);
        std::this_thread::sleep_until(step_end);
      }
      simulation_->step();
    }
  }

  void close() { connection_->close(); }
  RobotResult& result() { return result_; }

 private:
  void send_batch(bool await_answer) {
    const sim::SensorBatch batch = simulation_->take_batch();
    const auto sent_at = Clock::now();
    for (const v1::ClientMessage& message : batch.messages) connection_->send(message);
    if (batch.last_sensor_seq != 0) sent_at_[batch.last_sensor_seq] = sent_at;
    if (batch.steering_scan_seq) command_sent_at_[*batch.steering_scan_seq] = sent_at;
    if (!await_answer) return;
    // Lockstep: the ScanAck of the batch's last sensor message and the command answering the steering scan.
    answered_ = !batch.steering_scan_seq.has_value();
    awaited_command_seq_ = batch.steering_scan_seq.value_or(0);
    const auto deadline = Clock::now() + kLockstepAnswerTimeout;
    while ((sent_at_.contains(batch.last_sensor_seq) || !answered_) && Clock::now() < deadline) {
      const auto message = connection_->receive(std::chrono::duration_cast<milliseconds>(deadline - Clock::now()));
      if (message) handle(*message);
    }
    if (sent_at_.contains(batch.last_sensor_seq) || !answered_) {
      errors_.add(robot_id_ + ": no answer to sensor batch " + std::to_string(batch.last_sensor_seq) + " within " +
                  std::to_string(kLockstepAnswerTimeout.count()) + " s");
      sent_at_.clear();
      command_sent_at_.clear();
      answered_ = true;
    }
  }

  void handle(const v1::ServerMessage& message) {
    if (message.has_scan_ack()) {
      // A resend of a scan the server already journalled (a simulation replaying an earlier run's scans to a server
      // that outlived it) is acknowledged but not applied: no command will answer it.
      if (message.scan_ack().duplicate() && message.scan_ack().seq() == awaited_command_seq_) answered_ = true;
      const auto found = sent_at_.find(message.scan_ack().seq());
      if (found != sent_at_.end()) {
        add_sample(result_.ingest, Clock::now() - found->second);
        ++result_.scans;
        sent_at_.erase(found);
      }
    } else if (message.has_motion_command()) {
      const std::uint64_t answers = message.motion_command().answers_scan_seq();
      const auto found = command_sent_at_.find(answers);
      if (found != command_sent_at_.end()) add_sample(result_.command, Clock::now() - found->second);
      // Commands come in scan order: steering scans before this one that got none never will.
      if (answers != 0)
        std::erase_if(command_sent_at_, [answers](const auto& entry) { return entry.first <= answers; });
      simulation_->apply_command(message.motion_command());
      if (message.motion_command().answers_scan_seq() == awaited_command_seq_) answered_ = true;
    } else if (message.has_error()) {
      errors_.add(robot_id_ + ": " + client::describe(message.error()));
    }
  }

  const LoadOptions& options_;
  std::string robot_id_;
  ErrorLog& errors_;
  std::unique_ptr<sim::Simulation> simulation_;
  std::optional<client::Connection> connection_;
  std::unordered_map<std::uint64_t, Clock::time_point> sent_at_;
  std::unordered_map<std::uint64_t, Clock::time_point> command_sent_at_;  // steering scans awaiting their command
  bool answered_ = true;
  std::uint64_t awaited_command_seq_ = 0;
  RobotResult result_;
};

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

v1::Hello make_hello(v1::Role role, const std::string& name) {
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
    if (shared.options.client_sched_batch) {
      // On Linux this sets the calling thread's policy only; the server and the robots' threads keep theirs.
      const sched_param no_priority{};
      if (sched_setscheduler(0, SCHED_BATCH, &no_priority) != 0) {
        shared.errors.add(std::string("--client-sched batch: ") + std::strerror(errno));
      }
    }
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
std::uint32_t entries_per_request(QueryKind kind, const LoadOptions& options) {
  switch (kind) {
    case QueryKind::collision_batch:
    case QueryKind::clearance_batch:
    case QueryKind::raycast_batch:
    case QueryKind::occupancy_batch:
      return options.batch;
    case QueryKind::swept_batch:
      return std::min<std::uint32_t>(options.batch, 1000);
    case QueryKind::ptem:
      return options.ptem_points;
    default:
      return 1;
  }
}

using client::json_string;

}  // namespace

LoadReport run_load(const LoadOptions& options, std::ostream& progress) {
  ErrorLog errors;
  std::unique_ptr<StartedServer> started;
  client::Endpoint endpoint;
  std::optional<int> server_pid = options.server_pid;
  if (options.server) {
    endpoint = *options.server;
  } else {
    started = std::make_unique<StartedServer>(options.occgeod, options.server_config);
    endpoint.host = "127.0.0.1";
    endpoint.port = started->port();
    server_pid = started->pid();
  }
  if (options.progress) progress << "occgeo-load: server " << endpoint.to_string() << '\n';

  // A robot that maps the world before measuring and whose footprint the queries use; its session stays open.
  std::atomic<bool> stop_robots{false};
  RobotDriver seeder(options, endpoint, kSeedRobotId, options.seed, 0.0, errors);
  const auto seed_start = Clock::now();
  seeder.run_lockstep_batches(options.warmup_scans, stop_robots);
  if (options.progress) {
    progress << "occgeo-load: " << options.warmup_scans << " warm-up scans in "
             << std::chrono::duration<double>(Clock::now() - seed_start).count() << " s\n";
  }

  std::vector<std::unique_ptr<RobotDriver>> robots;
  for (std::uint32_t i = 0; i < options.robots; ++i) {
    const double heading = 2.0 * std::numbers::pi * static_cast<double>(i) / std::max<double>(options.robots, 1.0);
    robots.push_back(std::make_unique<RobotDriver>(options, endpoint, "load-robot-" + std::to_string(i),
                                                   options.seed + 1 + i, heading, errors));
  }

  ClientShared shared{options, endpoint, {}, {}, errors};
  for (const auto& [kind, weight] : options.mix) {
    if (weight == 0) continue;
    shared.kinds.push_back(kind);
    shared.cumulative.push_back((shared.cumulative.empty() ? 0 : shared.cumulative.back()) + weight);
  }
  const std::size_t kind_slots = shared.kinds.size() + 1;  // + the observers' polls
  std::vector<std::unique_ptr<ClientThread>> threads;
  const std::uint32_t thread_count =
      std::max<std::uint32_t>(1, std::min(options.threads, std::max(options.clients, options.observers)));
  for (std::uint32_t t = 0; t < thread_count; ++t) {
    auto thread = std::make_unique<ClientThread>();
    thread->result.per_kind.resize(kind_slots);
    thread->result.errors_per_kind.resize(kind_slots);
    threads.push_back(std::move(thread));
  }
  for (std::uint32_t i = 0; i < options.clients; ++i) {
    ClientThread& thread = *threads[i % thread_count];
    thread.clients.push_back(std::make_unique<QueryClient>(shared, thread.result, thread.io, options.seed * 7919 + i));
  }
  for (std::uint32_t i = 0; i < options.observers; ++i) {
    ClientThread& thread = *threads[i % thread_count];
    thread.observers.push_back(std::make_unique<Observer>(shared, thread.result, thread.io));
  }

  // Go: robots and clients together; the window opens once everyone runs.
  std::atomic<bool> go{false};
  std::vector<std::thread> robot_threads;
  for (auto& robot : robots) {
    robot_threads.emplace_back([&robot, &stop_robots, &errors] {
      try {
        robot->run(stop_robots);
      } catch (const std::exception& error) {
        errors.add(std::string("robot: ") + error.what());
      }
    });
  }
  for (auto& thread : threads) {
    thread->thread = std::thread([&thread, &shared, &go] { thread->run(shared, go); });
  }
  const auto server_ticks_start = server_pid ? process_cpu_ticks(*server_pid) : std::nullopt;
  const double own_cpu_start = own_cpu_seconds();
  std::vector<std::uint64_t> robot_scans_start;
  for (auto& robot : robots) robot_scans_start.push_back(robot->result().scans);
  const auto window_start = Clock::now();
  shared.measuring = true;
  go = true;

  const auto window = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(options.duration_s));
  std::uint64_t last_completed = 0;
  auto last_tick = window_start;
  while (Clock::now() < window_start + window) {
    std::this_thread::sleep_until(std::min(window_start + window, last_tick + std::chrono::seconds(1)));
    const auto now = Clock::now();
    const std::uint64_t completed = shared.completed.load();
    if (options.progress) {
      char line[200];
      std::snprintf(
          line, sizeof line, "occgeo-load: t=%.0f s  queries/s=%.0f  errors=%llu\n",
          std::chrono::duration<double>(now - window_start).count(),
          static_cast<double>(completed - last_completed) / std::chrono::duration<double>(now - last_tick).count(),
          static_cast<unsigned long long>(errors.count()));
      progress << line << std::flush;
    }
    if (started && !started->alive()) {
      errors.add("the server exited during the run: " + started->log_tail());
      break;
    }
    last_completed = completed;
    last_tick = now;
  }
  shared.measuring = false;
  shared.stopping = true;
  const auto window_end = Clock::now();
  const double window_s = std::chrono::duration<double>(window_end - window_start).count();

  LoadReport report;
  report.duration_s = window_s;
  report.robots = options.robots;
  report.clients = options.clients;
  report.depth = options.depth;
  report.observers = options.observers;
  report.client_threads = static_cast<std::uint32_t>(threads.size());
  report.client_sched_batch = options.client_sched_batch;
  if (server_pid) {
    const auto ticks_end = process_cpu_ticks(*server_pid);
    if (server_ticks_start && ticks_end) {
      report.server_measured = true;
      report.server_cpu_cores =
          static_cast<double>(*ticks_end - *server_ticks_start) / static_cast<double>(sysconf(_SC_CLK_TCK)) / window_s;
      const auto [rss, peak] = process_memory_kb(*server_pid);
      report.server_rss_kb = rss;
      report.server_peak_rss_kb = peak;
    }
  }
  report.client_cpu_cores = (own_cpu_seconds() - own_cpu_start) / window_s;

  stop_robots = true;
  for (auto& thread : robot_threads) thread.join();
  for (auto& thread : threads) thread->thread.join();

  // The server must still answer after the run.
  try {
    auto check = client::PipelinedConnection::open(endpoint, make_hello(v1::ROLE_QUERY, "occgeo-load-check"), 1);
    v1::ClientMessage status;
    status.mutable_status();
    check->call(std::move(status));
  } catch (const client::ClientError& error) {
    report.server_alive = false;
    errors.add(std::string("the server does not answer after the run: ") + error.what());
  }
  if (started && !started->alive()) {
    report.server_alive = false;
    errors.add("the server exited: " + started->log_tail());
  }

  Samples all_queries;
  for (std::size_t k = 0; k < kind_slots; ++k) {
    Samples samples;
    KindReport kind;
    kind.kind = k < shared.kinds.size() ? std::string(query_kind_name(shared.kinds[k])) : "observer_status";
    for (auto& thread : threads) {
      samples.insert(samples.end(), thread->result.per_kind[k].begin(), thread->result.per_kind[k].end());
      kind.errors += thread->result.errors_per_kind[k];
    }
    if (k == shared.kinds.size()) {
      report.observer_polls = samples.size();
      for (auto& thread : threads) {
        report.observer_events += thread->result.watch_events;
        if (options.observer_watch && options.observers > 0) {
          report.observer_dropped = report.observer_dropped.value_or(0) + thread->result.watch_dropped;
        }
      }
      if (options.observers == 0) break;
    } else {
      all_queries.insert(all_queries.end(), samples.begin(), samples.end());
    }
    std::sort(samples.begin(), samples.end());
    kind.completed = samples.size();
    kind.per_s = static_cast<double>(samples.size()) / window_s;
    kind.entries_per_s = kind.per_s * (k < shared.kinds.size() ? entries_per_request(shared.kinds[k], options) : 1.0);
    kind.p50_us = quantile_us(samples, 0.5);
    kind.p99_us = quantile_us(samples, 0.99);
    kind.p999_us = quantile_us(samples, 0.999);
    kind.max_us = samples.empty() ? 0.0 : static_cast<double>(samples.back()) / 1000.0;
    report.kinds.push_back(kind);
  }
  std::sort(all_queries.begin(), all_queries.end());
  report.queries = all_queries.size();
  report.queries_per_s = static_cast<double>(all_queries.size()) / window_s;
  report.p50_us = quantile_us(all_queries, 0.5);
  report.p99_us = quantile_us(all_queries, 0.99);
  report.p999_us = quantile_us(all_queries, 0.999);

  Samples ingest;
  Samples command;
  for (std::size_t i = 0; i < robots.size(); ++i) {
    report.scans += robots[i]->result().scans - robot_scans_start[i];
    ingest.insert(ingest.end(), robots[i]->result().ingest.begin(), robots[i]->result().ingest.end());
    command.insert(command.end(), robots[i]->result().command.begin(), robots[i]->result().command.end());
    robots[i]->close();
  }
  seeder.close();
  std::sort(ingest.begin(), ingest.end());
  report.scans_per_s = static_cast<double>(report.scans) / window_s;
  double ingest_sum_ns = 0.0;
  for (const std::uint64_t sample : ingest) ingest_sum_ns += static_cast<double>(sample);
  report.ingest_mean_us = ingest.empty() ? 0.0 : ingest_sum_ns / static_cast<double>(ingest.size()) / 1000.0;
  report.ingest_p50_us = quantile_us(ingest, 0.5);
  report.ingest_p99_us = quantile_us(ingest, 0.99);
  std::sort(command.begin(), command.end());
  report.commands = command.size();
  report.command_p50_us = quantile_us(command, 0.5);
  report.command_p99_us = quantile_us(command, 0.99);

  report.errors = errors.count();
  report.error_samples = errors.samples();
  return report;
}

}  // namespace occgeo::load
