// No client can lock the robots out: a connection that never says hello is closed after limits.hello_timeout_s, and
// silent connections, however many, give way to newer ones, so a robot's driver still registers and is driven and
// the CLI's status still answers.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <thread>
#include <vector>

#include "../support/process.h"
#include "../support/temp_dir.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

// A connected TCP socket that never sends anything; -1 when the connection failed.
int silent_connection(std::uint16_t port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return -1;
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(port);
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    close(fd);
    return -1;
  }
  return fd;
}

// True when the server closed the connection (orderly end of stream or reset) within `limit`.
bool closed_by_server(int fd, std::chrono::seconds limit) {
  timeval timeout{static_cast<time_t>(limit.count()), 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  char byte = 0;
  const ssize_t received = recv(fd, &byte, 1, 0);
  return received == 0 || (received < 0 && errno != EAGAIN && errno != EWOULDBLOCK);
}

// One odometry and one scan of the Bearcat's laser; the scan's MotionCommand is awaited for at most `limit`.
bool driven_within(client::Connection& driver, std::chrono::milliseconds limit) {
  v1::ClientMessage odometry;
  odometry.mutable_odometry()->set_seq(1);
  odometry.mutable_odometry()->set_stamp_s(0.1);
  odometry.mutable_odometry()->mutable_pose()->set_x(0.0);
  driver.send(odometry);
  v1::ClientMessage scan;
  scan.mutable_laser_scan()->set_sensor("front_laser");
  scan.mutable_laser_scan()->set_seq(2);
  scan.mutable_laser_scan()->set_stamp_s(0.2);
  for (int beam = 0; beam < 181; ++beam) scan.mutable_laser_scan()->add_ranges(5.0F);
  driver.send(scan);
  const auto deadline = std::chrono::steady_clock::now() + limit;
  for (int i = 0; i < 20; ++i) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return false;
    const auto reply = driver.receive(left);
    if (!reply) return false;
    if (reply->has_motion_command() && reply->motion_command().answers_scan_seq() == 2) return true;
  }
  return false;
}

TEST(Lockout, ConnectionThatNeverSaysHelloIsClosedAfterTheHelloTimeout) {
  TempDir dir;
  const auto config = dir.path() / "occgeod.yaml";
  std::ofstream(config) << "limits:\n  hello_timeout_s: 0.5\n";
  ServerProcess server(dir.path(), {"--config", config.string()});
  const int fd = silent_connection(server.port());
  ASSERT_GE(fd, 0);
  EXPECT_TRUE(closed_by_server(fd, std::chrono::seconds(5)));
  close(fd);
  EXPECT_NE(server.log().find("session_hello_timeout"), std::string::npos);
  // A client that says hello in time keeps its session well past the timeout.
  auto query = open_query_session(server.address());
  std::this_thread::sleep_for(std::chrono::milliseconds(1200));
  v1::ClientMessage status;
  status.mutable_status();
  status.set_request_id(1);
  EXPECT_TRUE(query.call(status, 1).has_status());
}

// True when the connection is still open after `wait`: nothing to read and no end of stream.
bool still_open_after(int fd, std::chrono::milliseconds wait) {
  pollfd watched{fd, POLLIN, 0};
  return poll(&watched, 1, static_cast<int>(wait.count())) == 0;
}

TEST(Lockout, SilentConnectionsBeyondThePerAddressCapGiveWayOldestFirstAndSessionsPastHelloStay) {
  TempDir dir;
  const auto config = dir.path() / "occgeod.yaml";
  std::ofstream(config) << "limits:\n  hello_timeout_s: 60\n  max_silent_per_address: 4\n";
  ServerProcess server(dir.path(), {"--config", config.string()});
  auto query = open_query_session(server.address());
  std::vector<int> silent;
  for (int i = 0; i < 10; ++i) {
    silent.push_back(silent_connection(server.port()));
    ASSERT_GE(silent.back(), 0);
    // One at a time, so that the server has taken each before the next: the order of eviction is the order here.
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  for (int i = 0; i < 6; ++i) {
    EXPECT_TRUE(closed_by_server(silent[static_cast<std::size_t>(i)], std::chrono::seconds(5)))
        << "silent connection " << i << " of 10 is still open beyond the cap of 4";
  }
  for (int i = 6; i < 10; ++i) {
    EXPECT_TRUE(still_open_after(silent[static_cast<std::size_t>(i)], std::chrono::milliseconds(200)))
        << "silent connection " << i << " of 10, within the cap of 4, was closed";
  }
  for (const int fd : silent) close(fd);
  // The session past its hello counts against no cap and still answers.
  v1::ClientMessage status;
  status.mutable_status();
  status.set_request_id(1);
  EXPECT_TRUE(query.call(status, 1).has_status());
  EXPECT_NE(server.log().find("session_evicted"), std::string::npos);
}

TEST(Lockout, TwoThousandIdleConnectionsDoNotKeepADriverOrTheCliOut) {
  // Two thousand sockets and the driver's need more descriptors than a shell's default soft limit of 1024.
  rlimit files{};
  getrlimit(RLIMIT_NOFILE, &files);
  if (files.rlim_cur < 4096) {
    files.rlim_cur = std::min<rlim_t>(files.rlim_max, 4096);
    setrlimit(RLIMIT_NOFILE, &files);
  }
  if (files.rlim_cur < 2100) GTEST_SKIP() << "needs 2100 file descriptors; the hard limit is " << files.rlim_max;
  TempDir dir;
  ServerProcess server(dir.path());
  std::vector<int> idle;
  for (int i = 0; i < 2000; ++i) {
    const int fd = silent_connection(server.port());
    if (fd >= 0) idle.push_back(fd);
  }
  EXPECT_EQ(idle.size(), 2000U) << "the kernel accepts the connections; the server closes the oldest silent ones";

  const auto started = std::chrono::steady_clock::now();
  auto driver = open_driver_session(server.address(), "robot-a");
  const bool driven = driven_within(driver, std::chrono::milliseconds(1000));
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  EXPECT_TRUE(driven) << "the driver got no motion command within 1 s of connecting (" << seconds << " s)";

  const ProcessResult status = run_process(
      {binary("clients/occgeo").string(), "--server", server.address(), "status", "--json"}, std::chrono::seconds(10));
  EXPECT_EQ(status.exit_code, 0) << status.err;
  EXPECT_NE(status.out.find("\"id\":\"robot-a\""), std::string::npos) << status.out;
  for (const int fd : idle) close(fd);
  EXPECT_NE(server.log().find("session_evicted"), std::string::npos);
}

}  // namespace
}  // namespace occgeo::testing
