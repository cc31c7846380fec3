#include "process.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

extern char** environ;

namespace occgeo::testing {

namespace {

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

pid_t spawn(const std::vector<std::string>& argv, const std::filesystem::path& out, const std::filesystem::path& err) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<char*> args;
  args.reserve(argv.size() + 1);
  for (const auto& arg : argv) args.push_back(const_cast<char*>(arg.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) throw std::runtime_error("cannot start " + argv[0] + ": " + std::strerror(rc));
  return pid;
}

// Waits up to `limit` for the child; nullopt if still running.
std::optional<int> wait_for(pid_t pid, std::chrono::milliseconds limit) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (true) {
    int status = 0;
    const pid_t done = waitpid(pid, &status, WNOHANG);
    if (done == pid) {
      if (WIFEXITED(status)) return WEXITSTATUS(status);
      return 128 + WTERMSIG(status);
    }
    if (std::chrono::steady_clock::now() >= deadline) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

}  // namespace

std::filesystem::path binary(const std::string& relative) {
  return std::filesystem::path(OCCGEO_BINARY_DIR) / relative;
}
std::filesystem::path source(const std::string& relative) {
  return std::filesystem::path(OCCGEO_SOURCE_DIR) / relative;
}

ProcessResult run_process(const std::vector<std::string>& argv, std::chrono::seconds limit) {
  TempDir io;
  const auto out = io.path() / "out";
  const auto err = io.path() / "err";
  const pid_t pid = spawn(argv, out, err);
  ProcessResult result;
  if (auto code = wait_for(pid, limit)) {
    result.exit_code = *code;
  } else {
    kill(pid, SIGKILL);
    wait_for(pid, std::chrono::seconds(5));
    result.timed_out = true;
  }
  result.out = read_file(out);
  result.err = read_file(err);
  return result;
}

BackgroundProcess::BackgroundProcess(const std::vector<std::string>& argv, const std::filesystem::path& stdout_file,
                                     const std::filesystem::path& stderr_file)
    : pid_(spawn(argv, stdout_file, stderr_file)) {}

BackgroundProcess::~BackgroundProcess() {
  if (running()) stop(SIGKILL, std::chrono::seconds(5));
}

bool BackgroundProcess::running() {
  if (exit_code_) return false;
  exit_code_ = wait_for(pid_, std::chrono::milliseconds(0));
  return !exit_code_;
}

std::optional<int> BackgroundProcess::stop(int signal, std::chrono::seconds limit) {
  if (!running()) return exit_code_;
  kill(pid_, signal);
  exit_code_ = wait_for(pid_, limit);
  if (!exit_code_) {
    kill(pid_, SIGKILL);
    wait_for(pid_, std::chrono::seconds(5));
  }
  return exit_code_;
}

ServerProcess::ServerProcess(const std::filesystem::path& data_dir, const std::vector<std::string>& extra_flags) {
  const auto port_file = data_dir / "occgeod.port";
  log_file_ = data_dir / "occgeod.log";
  std::filesystem::remove(port_file);
  std::vector<std::string> argv = {binary("service/occgeod").string(),
                                   "--listen",
                                   "127.0.0.1:0",
                                   "--data-dir",
                                   data_dir.string(),
                                   "--port-file",
                                   port_file.string()};
  argv.insert(argv.end(), extra_flags.begin(), extra_flags.end());
  // Tests run servers side by side: the web view's fixed default port would be taken by the first one.
  if (std::find(extra_flags.begin(), extra_flags.end(), "--http") == extra_flags.end()) {
    argv.insert(argv.end(), {"--http", "off"});
  }
  process_ = std::make_unique<BackgroundProcess>(argv, data_dir / "occgeod.out", log_file_);
  port_ = wait_for_port_file(*process_, port_file, log_file_, std::chrono::seconds(20));
}

std::uint16_t wait_for_port_file(BackgroundProcess& process, const std::filesystem::path& port_file,
                                 const std::filesystem::path& log_file, std::chrono::seconds limit) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < deadline) {
    std::ifstream in(port_file);
    unsigned port = 0;
    if (in >> port && port > 0 && port <= 65535) return static_cast<std::uint16_t>(port);
    if (!process.running()) throw std::runtime_error("occgeod exited at start: " + read_file(log_file));
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  throw std::runtime_error("occgeod did not start listening within " + std::to_string(limit.count()) +
                           " s: " + read_file(log_file));
}

std::string ServerProcess::log() const { return read_file(log_file_); }

}  // namespace occgeo::testing
