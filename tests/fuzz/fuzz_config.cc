// occgeod's YAML configuration: whatever the file holds, load_config either returns a configuration
// or throws ConfigError naming the problem; a configuration it returns is one the server can run
// with: it validates again and builds a world's models (grid, PTEM, OctoMap, distance field).
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core.h"
#include "fuzz_support.h"
#include "occgeo/service/config.h"
#include "occgeo/service/log.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool quiet = [] {
    occgeo::service::log::set_level(occgeo::service::log::Level::error);
    return true;
  }();
  (void)quiet;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  occgeo::service::ServerConfig config;
  try {
    config = occgeo::service::load_config(occgeo::fuzz::scratch().write("occgeod.yaml", text));
  } catch (const occgeo::service::ConfigError&) {
    return 0;  // refused with a message naming the key: what a bad file must get
  }
  try {
    config.validate();
  } catch (const occgeo::service::ConfigError&) {
    occgeo::fuzz::require(false, "a loaded configuration validates again");
  }
  config.data_dir = occgeo::fuzz::scratch().path() / "data";  // never the working directory's
  occgeo::service::ServerCore core(config);
  occgeo::fuzz::require(core.world(config.default_world) != nullptr, "a loaded configuration builds its default world");
  return 0;
}
