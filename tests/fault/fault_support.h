#pragma once
// What the durability fault tests share: a server they can kill -9 (or start under a file-size limit), two robots'
// deterministic odometry + laser scan streams, drivers that record what was acknowledged, and a cell-for-cell
// comparison of grids.

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "../integration/test_clients.h"
#include "../support/process.h"
#include "occgeo/client/connection.h"
#include "occgeo/proto/framing.h"
#include "occgeo/sim/messages.h"

namespace occgeo::testing {

// The server's configuration for a fault test: the durability section, everything else default.
inline std::filesystem::path write_durability_config(const std::filesystem::path& dir, const std::string& policy,
                                                     double snapshot_interval_s, double batch_interval_s = 0.005) {
  const auto file = dir / "occgeod.yaml";
  std::ofstream(file) << "durability:\n  policy: " << policy << "\n  batch_interval_s: " << batch_interval_s
                      << "\n  snapshot_interval_s: " << snapshot_interval_s << "\n";
  return file;
}

// occgeod on 127.0.0.1 that a test may kill -9; `prefix` runs it under another program (e.g. prlimit).
class FaultServer {
 public:
  FaultServer(const std::filesystem::path& data_dir, const std::filesystem::path& config,
              const std::vector<std::string>& prefix = {}, const std::string& log_name = "occgeod") {
    const auto port_file = data_dir / (log_name + ".port");
    log_file_ = data_dir / (log_name + ".log");
    std::filesystem::remove(port_file);
    std::vector<std::string> argv = prefix;
    for (const std::string& arg :
         {binary("service/occgeod").string(), std::string("--listen"), std::string("127.0.0.1:0"),
          std::string("--data-dir"), data_dir.string(), std::string("--port-file"), port_file.string(),
          std::string("--config"), config.string()}) {
      argv.push_back(arg);
    }
    process_ = std::make_unique<BackgroundProcess>(argv, data_dir / (log_name + ".out"), log_file_);
    port_ = wait_for_port_file(*process_, port_file, log_file_, std::chrono::seconds(30));
  }

  [[nodiscard]] std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  [[nodiscard]] std::uint16_t port() const { return port_; }
  [[nodiscard]] std::string log() const {
    std::ifstream in(log_file_);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }
  bool running() { return process_->running(); }
  void kill9() { process_->stop(SIGKILL, std::chrono::seconds(10)); }
  std::optional<int> terminate() { return process_->stop(SIGTERM, std::chrono::seconds(30)); }

 private:
  std::filesystem::path log_file_;
  std::unique_ptr<BackgroundProcess> process_;
  std::uint16_t port_ = 0;
};

// One message pair a driver sends: the pose, then a scan taken there.
struct Step {
  std::string robot;
  v1::ClientMessage odometry;
  v1::ClientMessage scan;
};

// The i-th step (i from 1) of robot `robot_index` (0 or 1): the robots drive along parallel lines 3 m apart, turning
// slowly, and see a random (seeded) room; some beams return nothing (range_max_m).
inline Step make_step(int robot_index, std::uint64_t i, std::mt19937& random) {
  Step step;
  step.robot = robot_index == 0 ? "alpha" : "beta";
  const double t = static_cast<double>(i);
  const geometry::Pose2 X_WB{0.04 * t, 3.0 * robot_index + 0.3 * std::sin(0.05 * t), 0.02 * t};
  step.odometry = sim::make_odometry_message(i, 0.1 * t, X_WB, {});
  std::uniform_real_distribution<float> range(0.3F, 9.0F);
  std::vector<float> ranges(181);
  for (float& r : ranges) r = std::min(range(random), 8.0F);
  step.scan = sim::make_laser_scan_message("front_laser", i, 0.1 * t, ranges);
  return step;
}

// The reply to sensor message `seq`: its ack or an error; nullopt when the connection died or nothing came.
inline std::optional<v1::ServerMessage> await_reply(client::Connection& connection, std::uint64_t seq,
                                                    std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  try {
    while (std::chrono::steady_clock::now() < deadline) {
      auto message = connection.receive(
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()));
      if (!message) return std::nullopt;
      if (message->has_scan_ack() && message->scan_ack().seq() == seq) return message;
      if (message->has_error() && message->error().seq() == seq) return message;
    }
  } catch (const std::exception&) {
    return std::nullopt;
  }
  return std::nullopt;
}

// The next ack or error answering a sensor message, skipping everything else (motion commands); nullopt when the
// connection died or nothing came in time.
inline std::optional<v1::ServerMessage> next_sensor_reply(client::Connection& connection,
                                                          std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  try {
    while (std::chrono::steady_clock::now() < deadline) {
      auto message = connection.receive(
          std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()));
      if (!message) return std::nullopt;
      if (message->has_scan_ack() || (message->has_error() && message->error().seq() != 0)) return message;
    }
  } catch (const std::exception&) {
    return std::nullopt;
  }
  return std::nullopt;
}

// Drivers for both robots on one server; sends steps in lockstep (each scan waits for its reply).
class Drivers {
 public:
  explicit Drivers(const std::string& address) {
    // A write to a server that was just killed must fail, not end the test.
    std::signal(SIGPIPE, SIG_IGN);
    for (const char* id : {"alpha", "beta"}) connections_.emplace(id, open_driver_session(address, id));
  }
  // Sends the step; returns its reply, or nullopt when the server went away.
  std::optional<v1::ServerMessage> send(const Step& step) {
    auto& connection = connections_.at(step.robot);
    try {
      connection.send(step.odometry);
      connection.send(step.scan);
    } catch (const std::exception&) {
      return std::nullopt;
    }
    return await_reply(connection, step.scan.laser_scan().seq());
  }

 private:
  std::map<std::string, client::Connection> connections_;
};

// The observed cells (certainty != 255) of the default world, by cell index.
using ObservedCells = std::map<std::pair<std::int64_t, std::int64_t>, int>;

inline ObservedCells observed_cells(const std::string& address) {
  auto query = open_query_session(address);
  v1::ClientMessage request;
  request.set_request_id(1);
  request.mutable_grid()->set_world("default");
  const v1::GridReply reply = query.call(request, 1).grid();
  ObservedCells cells;
  for (std::uint32_t row = 0; row < reply.height(); ++row) {
    for (std::uint32_t column = 0; column < reply.width(); ++column) {
      const auto value =
          static_cast<unsigned char>(reply.cells()[static_cast<std::size_t>(row) * reply.width() + column]);
      if (value == 255) continue;
      cells[{reply.min_cell().ix() + column, reply.min_cell().iy() + row}] = value;
    }
  }
  return cells;
}

// The grid a fresh server (no durability) builds from exactly these steps, in this order.
inline ObservedCells reference_cells(const std::filesystem::path& dir, const std::vector<Step>& steps) {
  std::filesystem::create_directories(dir);
  FaultServer reference(dir, write_durability_config(dir, "none", 0), {}, "reference");
  {
    Drivers drivers(reference.address());
    for (const Step& step : steps) {
      const auto reply = drivers.send(step);
      if (!reply || !reply->has_scan_ack()) {
        throw std::runtime_error("the reference server did not acknowledge a step: " +
                                 (reply ? reply->DebugString() : std::string("no reply")));
      }
    }
  }
  auto cells = observed_cells(reference.address());
  reference.terminate();
  return cells;
}

// How many cells differ between two grids (a cell observed in one only counts).
inline std::size_t differing_cells(const ObservedCells& a, const ObservedCells& b) {
  std::size_t differing = 0;
  for (const auto& [cell, value] : a) {
    const auto it = b.find(cell);
    if (it == b.end() || it->second != value) ++differing;
  }
  for (const auto& [cell, value] : b) {
    if (!a.contains(cell)) ++differing;
  }
  return differing;
}

// A driver speaking the protocol over a bare socket, so that it can stop in the middle of a frame.
class RawDriver {
 public:
  RawDriver(std::uint16_t port, const std::string& robot_id) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(port);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof(address)) != 0) {
      throw std::runtime_error("cannot connect to the server");
    }
    v1::ClientMessage hello;
    *hello.mutable_hello() = sim::make_driver_hello(robot_id, "default");
    send_bytes(proto::encode_frame(hello));
    v1::ClientMessage spec;
    *spec.mutable_robot_spec() = bearcat_spec();
    send_bytes(proto::encode_frame(spec));
  }
  ~RawDriver() { close(); }
  RawDriver(const RawDriver&) = delete;
  RawDriver& operator=(const RawDriver&) = delete;

  void send_bytes(const std::string& bytes) {
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::send(fd_, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL);
      if (n <= 0) throw std::runtime_error("send failed");
      done += static_cast<std::size_t>(n);
    }
  }
  // The reply (ack or error) to sensor message `seq`, reading past everything else; nullopt after 10 s.
  std::optional<v1::ServerMessage> await_reply(std::uint64_t seq) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (std::chrono::steady_clock::now() < deadline) {
      v1::ServerMessage message;
      while (decoder_.next(message) == proto::FrameStatus::frame) {
        if ((message.has_scan_ack() && message.scan_ack().seq() == seq) ||
            (message.has_error() && message.error().seq() == seq)) {
          return message;
        }
      }
      pollfd readable{fd_, POLLIN, 0};
      if (::poll(&readable, 1, 100) <= 0) continue;
      std::array<char, 65536> buffer{};
      const ssize_t n = ::recv(fd_, buffer.data(), buffer.size(), 0);
      if (n <= 0) return std::nullopt;
      decoder_.append(buffer.data(), static_cast<std::size_t>(n));
    }
    return std::nullopt;
  }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_ = -1;
  proto::FrameDecoder decoder_{std::size_t{64} << 20};
};

}  // namespace occgeo::testing
