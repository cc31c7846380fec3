#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "occgeo/geometry/pose.h"
#include "occgeo/replay/diagnostics.h"

namespace occgeo::replay {

// A planar pose: metres and radians.
// A planar pose in a log's odometry frame, metres and radians.
using LogPose = geometry::Pose2;

enum class LogFormat { carmen, dpslam, urg, mcap };

// Parses "carmen", "dpslam", "urg" or "mcap"; nullopt otherwise.
std::optional<LogFormat> parse_format(std::string_view name);
std::string format_name(LogFormat format);

// One laser scan of a log with the robot pose it was taken at.
struct ScanRecord {
  std::size_t line_number = 0;  // 1-based line of the scan in the log (MCAP: 1-based scan message number)
  // Raw log timestamp, seconds; nullopt when the format has none (DP-SLAM). May be zero, negative or out of order:
  // see TimestampSanitizer.
  std::optional<double> stamp_s;
  LogPose X_WB;  // base_link in the log's world frame
  LogPose X_BS;  // laser in base_link
  double angle_min_rad = 0.0;
  double angle_increment_rad = 0.0;
  // Ranges in metres; +infinity for a beam at the format's "no return" sentinel.
  std::vector<float> ranges_m;
  // The sensor's own limits when the log states them (ROS LaserScan), metres.
  std::optional<double> sensor_range_min_m;
  std::optional<double> sensor_range_max_m;
};

// Turns log lines into scans. Stateful (DP-SLAM pairs lines, URG integrates encoder ticks), so feed lines in order.
// Every quirk is reported to the Diagnostics: a malformed line is skipped whole, never half-used.
class LineParser {
 public:
  explicit LineParser(Diagnostics& diagnostics) : diagnostics_(diagnostics) {}
  virtual ~LineParser() = default;
  LineParser(const LineParser&) = delete;
  LineParser& operator=(const LineParser&) = delete;

  // The scan completed by this line, if any. `line_number` is 1-based and only used in warnings. Blank lines are
  // counted as ignored ("empty") here, for every format.
  std::optional<ScanRecord> parse_line(std::string_view line, std::size_t line_number);

 protected:
  // The format's reading of one non-blank line split at whitespace.
  virtual std::optional<ScanRecord> parse_tokens(const std::vector<std::string_view>& tokens,
                                                 std::size_t line_number) = 0;

  Diagnostics& diagnostics_;
};

std::unique_ptr<LineParser> make_parser(LogFormat format, Diagnostics& diagnostics);

// Per-format facts the replay needs beyond the scans themselves.
struct FormatTraits {
  double default_range_max_m;  // --max-range default: farther readings are sent as no return
  double range_min_m;          // readings below this are skipped by the server
  double nominal_period_s;     // scan period used to synthesize missing or broken timestamps
  double wrap_period_s;        // timestamp counter period (0: the clock does not wrap)
  double sensor_height_m;      // for the spec's 3D mount; does not affect 2D mapping
  const char* sensor_name;
};
FormatTraits traits_of(LogFormat format);

// Makes log timestamps usable: the server needs stamps that never go backwards, and pacing needs sane gaps.
// Zero, negative or non-finite stamps become previous + nominal period; a stamp that jumps back by more than half the
// counter's wrap period is unwrapped; any other non-increasing stamp becomes previous + 1 ms. Each case is a warning.
class TimestampSanitizer {
 public:
  TimestampSanitizer(double nominal_period_s, double wrap_period_s)
      : nominal_period_s_(nominal_period_s), wrap_period_s_(wrap_period_s) {}

  // The stamp to send for a scan whose raw stamp is `raw_s` (nullopt: synthesize at the nominal period).
  double sanitize(std::optional<double> raw_s, Diagnostics& diagnostics, std::size_t line_number);

 private:
  double nominal_period_s_;
  double wrap_period_s_;
  double wrap_offset_s_ = 0.0;
  std::optional<double> previous_raw_s_;
  std::optional<double> previous_s_;
};

}  // namespace occgeo::replay
