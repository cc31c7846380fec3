#pragma once

#include <array>
#include <filesystem>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "occgeo/replay/diagnostics.h"
#include "occgeo/replay/mcap.h"
#include "occgeo/replay/parsers.h"

namespace occgeo::replay {

// Where an MCAP replay takes its scans and poses from.
struct McapOptions {
  std::string topic_scan;   // empty: the first sensor_msgs/msg/LaserScan topic
  std::string topic_odom;   // empty: the first nav_msgs/msg/Odometry topic, else TF odom -> base frame
  std::string topic_cloud;  // empty: the first sensor_msgs/msg/PointCloud2 topic
  // x, y, z, roll, pitch, yaw of the laser in base_link (metres, radians); nullopt: from TF.
  std::optional<std::array<double, 6>> laser_pose;
};

// A point cloud of a bag, in base_link (its frame's TF mount applied in the plane), with the robot pose it was taken
// at.
struct CloudRecord {
  std::uint64_t number = 0;  // 1-based cloud message number, for warnings
  double stamp_s = 0.0;
  LogPose X_WB;
  std::vector<float> xyz_B;  // x, y, z triples, metres
};

// The scans of a log, in order, each with the robot pose it was taken at.
class ScanSource {
 public:
  virtual ~ScanSource() = default;
  // The next scan, or nullopt at the end; throws std::runtime_error (McapError, CdrError) when the input is broken.
  virtual std::optional<ScanRecord> next() = 0;
  // Fraction of the input consumed, 0..1.
  [[nodiscard]] virtual double progress() const = 0;
  // The point clouds read since the last call (only bags have any), in file order.
  virtual std::vector<CloudRecord> take_clouds() { return {}; }
};

// Opens `file` in `format`; `notes` (nullptr: none) hears which topics an MCAP replay chose.
std::unique_ptr<ScanSource> open_scan_source(LogFormat format, const std::filesystem::path& file,
                                             const McapOptions& mcap, Diagnostics& diagnostics, std::ostream* notes);

// A ROS 2 bag (or an occgeo recording) as scans: reads the file with McapReader and decodes CDR.
std::unique_ptr<ScanSource> open_mcap_source(std::unique_ptr<McapReader> reader, const McapOptions& options,
                                             Diagnostics& diagnostics, std::ostream* notes);

}  // namespace occgeo::replay
