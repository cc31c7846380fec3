// ROS map_server maps (YAML metadata + PGM image): the input is the YAML text, a NUL byte, then the
// image's bytes, written as map.yaml and map.pgm. read_map_yaml either returns a consistent image or
// throws MapFileError naming the file and the problem.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz_support.h"
#include "occgeo/mapfile/map_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::size_t split = input.find('\0');
  if (split == std::string_view::npos) return 0;
  const std::string_view yaml = input.substr(0, split);
  // An image path naming a device would make the reader wait or read forever: not a map file problem.
  for (const std::string_view device : {"/dev", "/proc", "/sys"}) {
    if (yaml.find(device) != std::string_view::npos) return 0;
  }
  const auto& scratch = occgeo::fuzz::scratch();
  (void)scratch.write("map.pgm", input.substr(split + 1));
  try {
    const auto image = occgeo::mapfile::read_map_yaml(scratch.write("map.yaml", yaml));
    occgeo::fuzz::require(image.pixels.size() == static_cast<std::size_t>(image.width) * image.height,
                          "an image has width * height pixels");
    occgeo::fuzz::require(std::isfinite(image.resolution) && image.resolution > 0.0, "a map's resolution is positive");
    if (image.width > 0 && image.height > 0) {
      (void)image.state(image.width - 1, image.height - 1);
      (void)image.pixel_center(0, 0);
    }
  } catch (const occgeo::mapfile::MapFileError&) {
    // Refused with a message naming the file: what a bad map must get.
  }
  return 0;
}
