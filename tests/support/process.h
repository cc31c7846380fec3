#pragma once

#include <sys/types.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "temp_dir.h"

namespace occgeo::testing {

// Path of a built program, e.g. binary("service/occgeod").
std::filesystem::path binary(const std::string& relative);
// Path of a file in the source tree, e.g. source("clients/sim/worlds/open_field.yaml").
std::filesystem::path source(const std::string& relative);

struct ProcessResult {
  int exit_code = -1;  // -1 when killed for running past its time limit
  std::string out;     // standard output
  std::string err;     // standard error
  bool timed_out = false;
};

// Runs a program to completion, killing it after `limit`.
ProcessResult run_process(const std::vector<std::string>& argv, std::chrono::seconds limit);

// A child process running in the background, killed on destruction if still running.
class BackgroundProcess {
 public:
  BackgroundProcess(const std::vector<std::string>& argv, const std::filesystem::path& stdout_file,
                    const std::filesystem::path& stderr_file);
  ~BackgroundProcess();
  BackgroundProcess(const BackgroundProcess&) = delete;
  BackgroundProcess& operator=(const BackgroundProcess&) = delete;

  [[nodiscard]] bool running();
  [[nodiscard]] pid_t pid() const { return pid_; }
  // Sends `signal` and waits up to `limit` for exit; returns the exit code, or nullopt if it did
  // not exit in time (it is then killed).
  std::optional<int> stop(int signal, std::chrono::seconds limit);

 private:
  pid_t pid_ = -1;
  std::optional<int> exit_code_;
};

// Waits (up to `limit`) until the server `process` writes the port it listens on to `port_file` (its --port-file) and
// returns that port. Throws, quoting the server's log file, when the server exits first or the time runs out.
std::uint16_t wait_for_port_file(BackgroundProcess& process, const std::filesystem::path& port_file,
                                 const std::filesystem::path& log_file, std::chrono::seconds limit);

// occgeod on 127.0.0.1 with a port chosen by the kernel and its own data directory.
class ServerProcess {
 public:
  // Starts the server and waits (bounded) until it listens. Extra flags are appended.
  explicit ServerProcess(const std::filesystem::path& data_dir, const std::vector<std::string>& extra_flags = {});
  [[nodiscard]] std::uint16_t port() const { return port_; }
  [[nodiscard]] std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  [[nodiscard]] std::string log() const;
  [[nodiscard]] bool running() { return process_->running(); }
  [[nodiscard]] pid_t pid() const { return process_->pid(); }
  // SIGTERM and wait; returns the exit code.
  std::optional<int> stop() { return process_->stop(SIGTERM_VALUE, std::chrono::seconds(20)); }

 private:
  static constexpr int SIGTERM_VALUE = 15;
  std::filesystem::path log_file_;
  std::unique_ptr<BackgroundProcess> process_;
  std::uint16_t port_ = 0;
};

}  // namespace occgeo::testing
