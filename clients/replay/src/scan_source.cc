#include "occgeo/replay/scan_source.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <utility>

#include "occgeo/replay/line_source.h"
#include "occgeo/replay/ros2_messages.h"

namespace occgeo::replay {
namespace {

// A text log: lines through the format's parser.
class TextScanSource : public ScanSource {
 public:
  TextScanSource(LogFormat format, const std::filesystem::path& file, Diagnostics& diagnostics)
      : source_(file), parser_(make_parser(format, diagnostics)) {}

  std::optional<ScanRecord> next() override {
    while (const auto line = source_.next()) {
      if (auto scan = parser_->parse_line(*line, source_.line_number())) return scan;
    }
    return std::nullopt;
  }
  [[nodiscard]] double progress() const override { return source_.progress(); }

 private:
  LineSource source_;
  std::unique_ptr<LineParser> parser_;
};

// A frame's pose in its parent frame, reduced to the plane, and whether it turns the plane over.
struct PlanarTransform {
  std::string parent;
  LogPose pose;
  bool flipped = false;  // rolled or pitched upside down: a laser mounted so sweeps clockwise
};

PlanarTransform planar(std::string parent, const RosPose& pose) {
  const RollPitchYaw rpy = to_roll_pitch_yaw(pose);
  return {std::move(parent), {pose.x, pose.y, rpy.yaw}, std::cos(rpy.roll) * std::cos(rpy.pitch) < 0.0};
}

constexpr std::size_t kMaxBeams = 100000;        // the server's default limit
constexpr std::size_t kMaxCloudPoints = 100000;  // the server's default limit

bool finite(const LogPose& pose) { return std::isfinite(pose.x) && std::isfinite(pose.y) && std::isfinite(pose.theta); }

// Why a decoded scan cannot be sent, or nullptr when it can.
const char* unusable(const RosLaserScan& scan, const LogPose& X_WB, const LogPose& X_BS) {
  if (scan.ranges.size() < 2 || scan.ranges.size() > kMaxBeams) return "has not 2..100000 beams";
  if (!std::isfinite(scan.angle_min) || !std::isfinite(scan.angle_increment) || scan.angle_increment <= 0.0F) {
    return "has a non-finite angle or an increment that is not positive";
  }
  if (!std::isfinite(scan.range_min) || !std::isfinite(scan.range_max) || scan.range_min < 0.0F ||
      scan.range_max <= scan.range_min) {
    return "has no valid range_min < range_max";
  }
  if (!finite(X_WB)) return "is placed at a non-finite robot pose";
  if (!finite(X_BS)) return "has a non-finite laser mount";
  return nullptr;
}

class McapScanSource : public ScanSource {
 public:
  McapScanSource(std::unique_ptr<McapReader> reader, McapOptions options, Diagnostics& diagnostics, std::ostream* notes)
      : reader_(std::move(reader)), options_(std::move(options)), diagnostics_(diagnostics), notes_(notes) {}

  std::optional<ScanRecord> next() override {
    while (const auto message = reader_->next()) {
      const std::string type = message->schema == nullptr ? std::string() : message->schema->name;
      const std::string& topic = message->channel->topic;
      try {
        if (wants(topic, type, kLaserScanType, options_.topic_scan, scan_topic_, "scans", *message)) {
          if (auto scan = to_record(decode_laser_scan(message->data), *message)) return scan;
        } else if (wants(topic, type, kOdometryType, options_.topic_odom, odom_topic_, "odometry", *message)) {
          const RosOdometry odometry = decode_odometry(message->data);
          base_frame_ = odometry.child_frame_id.empty() ? base_frame_ : odometry.child_frame_id;
          odometry_pose_ = LogPose{odometry.pose.x, odometry.pose.y, to_roll_pitch_yaw(odometry.pose).yaw};
        } else if (type == kTfMessageType && message->channel->message_encoding == "cdr") {
          for (const RosTransform& transform : decode_tf_message(message->data)) {
            transforms_[transform.child_frame_id] = planar(transform.header.frame_id, transform.transform);
          }
        } else if (wants(topic, type, kPointCloud2Type, options_.topic_cloud, cloud_topic_, "point clouds", *message)) {
          take_cloud(decode_point_cloud2(message->data), *message);
        } else if (seen_topics_.insert(topic).second && !type.empty()) {
          other_topics_.push_back(topic + " (" + type + ")");
        }
      } catch (const CdrError& e) {
        throw McapError(reader_->name() + ": offset " + std::to_string(message->offset) + ": topic '" + topic + "' (" +
                            type + "): " + e.what(),
                        message->offset);
      }
    }
    if (!options_.topic_scan.empty() && !scan_topic_) {
      throw std::runtime_error(reader_->name() + ": no topic '" + options_.topic_scan + "' in the file");
    }
    if (!scan_topic_) {
      std::string found;
      for (const auto& topic : other_topics_) found += (found.empty() ? "" : ", ") + topic;
      throw std::runtime_error(reader_->name() + ": no " + std::string(kLaserScanType) +
                               " topic in the file (topics of unsupported types: " + (found.empty() ? "none" : found) +
                               ")");
    }
    return std::nullopt;
  }

  [[nodiscard]] double progress() const override { return reader_->progress(); }

 private:
  // Whether a message of `topic` and `type` is the stream chosen for `kind`; chooses the first topic of `wanted_type`
  // unless one was named, and refuses a named topic of another type.
  bool wants(const std::string& topic, const std::string& type, std::string_view wanted_type, const std::string& named,
             std::optional<std::string>& chosen, const char* kind, const McapMessage& message) {
    if (chosen) return *chosen == topic && type == wanted_type;
    if (!named.empty()) {
      if (topic != named) return false;
      if (type != wanted_type) {
        throw McapError(reader_->name() + ": offset " + std::to_string(message.offset) + ": topic '" + topic +
                            "' is of type '" + type + "', not the " + std::string(wanted_type) + " asked for",
                        message.offset);
      }
    } else if (type != wanted_type) {
      return false;
    }
    if (message.channel->message_encoding != "cdr") {
      throw McapError(reader_->name() + ": offset " + std::to_string(message.offset) + ": topic '" + topic +
                          "' is encoded as '" + message.channel->message_encoding + "'; ROS 2 messages in CDR are read",
                      message.offset);
    }
    chosen = topic;
    if (notes_ != nullptr) *notes_ << "occgeo replay: " << kind << " from topic " << topic << " (" << type << ")\n";
    return true;
  }

  // The planar pose of `frame` in the frame `root`, following TF parents up from `frame`; nullopt when unreachable.
  std::optional<PlanarTransform> chain(const std::string& frame, const std::string& root) const {
    PlanarTransform out{root, {}, false};
    std::string at = frame;
    for (int hops = 0; hops < 64; ++hops) {
      if (at == root) return out;
      const auto it = transforms_.find(at);
      if (it == transforms_.end()) return std::nullopt;
      out.pose = it->second.pose.compose(out.pose);
      out.flipped = out.flipped != it->second.flipped;
      at = it->second.parent;
    }
    return std::nullopt;
  }

  // The base frame's pose from TF: up to the topmost frame it hangs from (odom, or map).
  std::optional<LogPose> tf_base_pose() const {
    std::string root = base_frame_;
    for (int hops = 0; hops < 64; ++hops) {
      const auto it = transforms_.find(root);
      if (it == transforms_.end()) break;
      root = it->second.parent;
    }
    if (root == base_frame_) return std::nullopt;
    return chain(base_frame_, root)->pose;
  }

  std::vector<CloudRecord> take_clouds() override { return std::exchange(clouds_, {}); }

  // The robot's latest pose: from odometry, or from TF when there is no odometry topic.
  std::optional<LogPose> robot_pose() const {
    if (odometry_pose_) return odometry_pose_;
    if (!odom_topic_ && options_.topic_odom.empty()) return tf_base_pose();
    return std::nullopt;
  }

  void take_cloud(RosPointCloud cloud, const McapMessage& message) {
    ++clouds_seen_;
    const auto X_WB = robot_pose();
    if (!X_WB || !finite(*X_WB)) {
      diagnostics_.warn(
          "no_pose", clouds_seen_,
          "point cloud at offset " + std::to_string(message.offset) + " has no robot pose; cloud skipped");
      return;
    }
    if (cloud.xyz.size() / 3 > kMaxCloudPoints) {
      diagnostics_.warn("cloud_too_large", clouds_seen_,
                        "point cloud at offset " + std::to_string(message.offset) + " has " +
                            std::to_string(cloud.xyz.size() / 3) + " points, more than the " +
                            std::to_string(kMaxCloudPoints) + " sent; cloud skipped");
      return;
    }
    PlanarTransform X_BC{base_frame_, {}, false};
    if (const auto mounted = chain(cloud.header.frame_id, base_frame_)) {
      X_BC = *mounted;
    } else if (cloud.header.frame_id != base_frame_) {
      diagnostics_.warn("cloud_pose_unknown", clouds_seen_,
                        "no TF from '" + base_frame_ + "' to the cloud's frame '" + cloud.header.frame_id +
                            "'; the cloud is taken to be in the base frame");
    }
    CloudRecord record{clouds_seen_, cloud.header.stamp_s, *X_WB, {}};
    record.xyz_B.reserve(cloud.xyz.size());
    const double c = std::cos(X_BC.pose.theta), s = std::sin(X_BC.pose.theta);
    for (std::size_t i = 0; i + 2 < cloud.xyz.size(); i += 3) {
      const double x = static_cast<double>(cloud.xyz[i]);
      const double y = static_cast<double>(X_BC.flipped ? -cloud.xyz[i + 1] : cloud.xyz[i + 1]);
      const double z = static_cast<double>(X_BC.flipped ? -cloud.xyz[i + 2] : cloud.xyz[i + 2]);
      record.xyz_B.push_back(static_cast<float>(X_BC.pose.x + c * x - s * y));
      record.xyz_B.push_back(static_cast<float>(X_BC.pose.y + s * x + c * y));
      record.xyz_B.push_back(static_cast<float>(z));
    }
    clouds_.push_back(std::move(record));
  }

  std::optional<ScanRecord> to_record(RosLaserScan scan, const McapMessage& message) {
    ++scans_seen_;
    const std::optional<LogPose> X_WB = robot_pose();
    if (!X_WB) {
      diagnostics_.warn("no_pose", scans_seen_,
                        "scan at offset " + std::to_string(message.offset) +
                            " comes before any odometry or TF pose of '" + base_frame_ + "'; scan skipped");
      return std::nullopt;
    }
    PlanarTransform X_BS{base_frame_, {}, false};
    if (options_.laser_pose) {
      const auto& p = *options_.laser_pose;
      X_BS.pose = {p[0], p[1], p[5]};
      X_BS.flipped = std::cos(p[3]) * std::cos(p[4]) < 0.0;
    } else if (const auto mounted = chain(scan.header.frame_id, base_frame_)) {
      X_BS = *mounted;
    } else if (scan.header.frame_id != base_frame_) {
      diagnostics_.warn("laser_pose_unknown", scans_seen_,
                        "no TF from '" + base_frame_ + "' to the scan's frame '" + scan.header.frame_id +
                            "' and no --laser-pose; the laser is taken to sit at the base frame");
    }
    if (const char* problem = unusable(scan, *X_WB, X_BS.pose)) {
      diagnostics_.warn("bad_scan", scans_seen_,
                        "scan at offset " + std::to_string(message.offset) + " " + problem + "; scan skipped");
      return std::nullopt;
    }
    ScanRecord record;
    record.line_number = scans_seen_;
    record.stamp_s = scan.header.stamp_s > 0.0 ? scan.header.stamp_s : static_cast<double>(message.log_time_ns) * 1e-9;
    record.X_WB = *X_WB;
    record.X_BS = X_BS.pose;
    record.angle_min_rad = static_cast<double>(scan.angle_min);
    record.angle_increment_rad = static_cast<double>(scan.angle_increment);
    record.sensor_range_min_m = static_cast<double>(scan.range_min);
    record.sensor_range_max_m = static_cast<double>(scan.range_max);
    record.ranges_m.reserve(scan.ranges.size());
    std::size_t invalid = 0;
    for (const float r : scan.ranges) {
      // REP 117: +inf is no return, NaN and -inf an invalid reading; both are sent so they neither clear nor mark.
      if (std::isnan(r) || r < 0.0F || r == -std::numeric_limits<float>::infinity()) {
        ++invalid;
        record.ranges_m.push_back(0.0F);
      } else if (r >= scan.range_max) {
        diagnostics_.count_no_return();
        record.ranges_m.push_back(std::numeric_limits<float>::infinity());
      } else {
        record.ranges_m.push_back(r);
      }
    }
    if (invalid > 0) diagnostics_.count_invalid_reading(invalid);
    if (X_BS.flipped) {
      // Upside down, the beams sweep the other way in base_link: the same fan from -angle_max, reversed.
      std::reverse(record.ranges_m.begin(), record.ranges_m.end());
      record.angle_min_rad = -(static_cast<double>(scan.angle_min) +
                               static_cast<double>(scan.angle_increment) * static_cast<double>(scan.ranges.size() - 1));
    }
    return record;
  }

  std::unique_ptr<McapReader> reader_;
  McapOptions options_;
  Diagnostics& diagnostics_;
  std::ostream* notes_;
  std::optional<std::string> scan_topic_, odom_topic_, cloud_topic_;
  std::set<std::string> seen_topics_;
  std::vector<std::string> other_topics_;
  std::map<std::string, PlanarTransform> transforms_;  // child frame -> its pose in its parent
  std::string base_frame_ = "base_link";
  std::optional<LogPose> odometry_pose_;
  std::uint64_t scans_seen_ = 0;
  std::uint64_t clouds_seen_ = 0;
  std::vector<CloudRecord> clouds_;
};

}  // namespace

std::unique_ptr<ScanSource> open_mcap_source(std::unique_ptr<McapReader> reader, const McapOptions& options,
                                             Diagnostics& diagnostics, std::ostream* notes) {
  return std::make_unique<McapScanSource>(std::move(reader), options, diagnostics, notes);
}

std::unique_ptr<ScanSource> open_scan_source(LogFormat format, const std::filesystem::path& file,
                                             const McapOptions& mcap, Diagnostics& diagnostics, std::ostream* notes) {
  if (format == LogFormat::mcap) {
    return open_mcap_source(std::make_unique<McapReader>(file), mcap, diagnostics, notes);
  }
  return std::make_unique<TextScanSource>(format, file, diagnostics);
}

}  // namespace occgeo::replay
