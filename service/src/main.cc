// occgeod: the occgeo occupancy and geometry server.
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "occgeo/service/config.h"
#include "occgeo/service/log.h"
#include "occgeo/service/server.h"

namespace {

constexpr const char* kUsage = R"(usage: occgeod [options]
  --listen HOST:PORT   address to serve (default 127.0.0.1:7700)
  --config FILE        YAML configuration (see docs/CONFIG.md); flags override it
  --data-dir DIR       where worlds are saved and restored (default ./occgeo-data)
  --log-level LEVEL    debug, info, warn or error (default info)
  --port-file FILE     write the bound port to FILE once listening (for scripts and tests)
  --http HOST:PORT     live web view and /metrics (default 127.0.0.1:7701); "off" disables
  --help               this text
)";

struct Flags {
  std::string config;
  std::string listen;
  std::string data_dir;
  std::string log_level;
  std::string port_file;
  std::string http;
};

int usage_error(const std::string& message) {
  std::fprintf(stderr, "occgeod: %s\n%s", message.c_str(), kUsage);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  Flags flags;
  const std::vector<std::string> args(argv + 1, argv + argc);
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    const std::map<std::string, std::string*> options = {
        {"--config", &flags.config},       {"--listen", &flags.listen},       {"--data-dir", &flags.data_dir},
        {"--log-level", &flags.log_level}, {"--port-file", &flags.port_file}, {"--http", &flags.http}};
    const auto option = options.find(arg);
    if (option == options.end()) return usage_error("unknown option '" + arg + "'");
    std::string* target = option->second;
    if (i + 1 >= args.size()) return usage_error("option '" + arg + "' needs a value");
    *target = args[++i];
  }

  try {
    occgeo::service::ServerConfig config;
    if (!flags.config.empty()) config = occgeo::service::load_config(flags.config);
    if (!flags.listen.empty()) config.listen = flags.listen;
    if (!flags.data_dir.empty()) config.data_dir = flags.data_dir;
    if (!flags.log_level.empty()) config.log_level = flags.log_level;
    if (flags.http == "off") {
      config.http.enabled = false;
    } else if (!flags.http.empty()) {
      config.http.enabled = true;
      config.http.listen = flags.http;
    }
    occgeo::service::Server server(config);
    if (!flags.port_file.empty()) {
      std::ofstream(flags.port_file) << server.port() << "\n";
    }
    server.run();
  } catch (const occgeo::service::ConfigError& e) {
    std::fprintf(stderr, "occgeod: configuration error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    occgeo::service::log::error("fatal", {{"error", e.what()}});
    return 1;
  }
  return 0;
}
