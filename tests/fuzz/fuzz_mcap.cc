// ROS 2 bags: any bytes as an MCAP file through McapReader and the CDR decoders into scans. Whatever the bytes, the
// reader either stops with an error (McapError, CdrError, or the replay's "no scan topic") or yields scans the replay
// can send as they are: finite poses and angles, a bounded beam count, no NaN range. Byte 0 bit 0 also runs each CDR
// decoder on the rest directly.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>

#include "fuzz_support.h"
#include "occgeo/replay/mcap.h"
#include "occgeo/replay/ros2_messages.h"
#include "occgeo/replay/scan_source.h"

namespace {

using occgeo::fuzz::require;

void decode_directly(const std::string& bytes) {
  try {
    const auto scan = occgeo::replay::decode_laser_scan(bytes);
    require(scan.ranges.size() * 4 <= bytes.size(), "a scan holds no more ranges than its bytes");
  } catch (const occgeo::replay::CdrError&) {
  }
  try {
    occgeo::replay::decode_odometry(bytes);
  } catch (const occgeo::replay::CdrError&) {
  }
  try {
    occgeo::replay::decode_tf_message(bytes);
  } catch (const occgeo::replay::CdrError&) {
  }
  try {
    const auto cloud = occgeo::replay::decode_point_cloud2(bytes);
    require(cloud.xyz.size() % 3 == 0, "a cloud holds whole points");
    for (const float v : cloud.xyz) require(std::isfinite(v), "cloud coordinates are finite");
  } catch (const occgeo::replay::CdrError&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::string bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  if ((data[0] & 1U) != 0) decode_directly(bytes);
  occgeo::replay::McapOptions options;
  if ((data[0] & 2U) != 0) options.laser_pose = std::array<double, 6>{0.1, 0.0, 0.2, M_PI, 0.0, 0.5};
  occgeo::replay::Diagnostics diagnostics;
  try {
    auto reader = std::make_unique<occgeo::replay::McapReader>(std::make_unique<std::istringstream>(bytes), "fuzz.mcap",
                                                               bytes.size());
    auto source = occgeo::replay::open_mcap_source(std::move(reader), options, diagnostics, nullptr);
    for (int scans = 0; scans < 10000; ++scans) {
      const auto scan = source->next();
      if (!scan) break;
      require(std::isfinite(scan->X_WB.x) && std::isfinite(scan->X_WB.y) && std::isfinite(scan->X_WB.theta),
              "a scan's pose is finite");
      require(std::isfinite(scan->X_BS.x) && std::isfinite(scan->X_BS.y), "a scan's mount is finite");
      require(!scan->ranges_m.empty() && scan->ranges_m.size() <= 100000, "a scan has 1..100000 beams");
      for (const float range : scan->ranges_m) require(!std::isnan(range), "no range is NaN");
      const double progress = source->progress();
      require(progress >= 0.0 && progress <= 1.0, "progress stays within 0..1");
    }
  } catch (const std::runtime_error&) {
    // A damaged file: the replay stops with this error naming the offset.
  }
  return 0;
}
