// occgeo-load: loads an occgeod on this machine with simulated robots, query clients and observers for a bounded
// time and reports throughput, latency per query kind, errors and the server's CPU and memory.
#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <string_view>
#include <vector>

#include "occgeo/load/load_run.h"
#include "occgeo/load/options.h"

namespace {

// service/occgeod of the build this tool belongs to (it lives in clients/load/).
std::filesystem::path default_occgeod() {
  std::error_code error;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", error);
  if (error) return "occgeod";
  return self.parent_path().parent_path().parent_path() / "service" / "occgeod";
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string_view> args(argv + 1, argv + argc);
  occgeo::load::LoadOptions options;
  try {
    options = occgeo::load::parse_load_args(args);
  } catch (const occgeo::load::LoadArgsError& error) {
    std::cerr << "occgeo-load: " << error.what() << "\nrun 'occgeo-load --help' for usage\n";
    return 2;
  }
  if (options.help) {
    std::cout << occgeo::load::load_usage();
    return 0;
  }
  if (options.occgeod.empty()) options.occgeod = default_occgeod();
  if (options.world_file.empty()) options.world_file = OCCGEO_LOAD_DEFAULT_WORLD;
  try {
    const occgeo::load::LoadReport report = occgeo::load::run_load(options, std::cerr);
    if (options.json) {
      std::cout << occgeo::load::report_json(report) << std::endl;
    } else {
      std::cout << occgeo::load::report_text(report);
    }
    return report.errors == 0 && report.server_alive ? 0 : 1;
  } catch (const occgeo::load::LoadArgsError& error) {
    std::cerr << "occgeo-load: " << error.what() << "\nrun 'occgeo-load --help' for usage\n";
    return 2;
  } catch (const std::exception& error) {
    std::cerr << "occgeo-load: " << error.what() << '\n';
    return 1;
  }
}
