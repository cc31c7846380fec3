#pragma once

// The occgeod the load tool starts when not given --server, and the CPU and memory of a process as /proc shows them.

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "load_common.h"
#include "occgeo/load/load_run.h"

extern char** environ;

namespace occgeo::load::internal {

// ---- the server process -------------------------------------------------------------------------------------------

// CPU ticks (user + system) of a process, or nullopt when it is gone.
inline std::optional<std::uint64_t> process_cpu_ticks(int pid) {
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

inline double own_cpu_seconds() {
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

}  // namespace occgeo::load::internal
