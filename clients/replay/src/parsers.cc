#include "occgeo/replay/parsers.h"

#include "occgeo/geometry/dead_reckoning.h"

#include <charconv>
#include <cmath>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>

namespace occgeo::replay {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr float kNoReturn = std::numeric_limits<float>::infinity();
constexpr std::size_t kMaxBeams = 100000;

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i])) != 0) ++i;
    const std::size_t start = i;
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i])) == 0) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

// A finite number, or nullopt (also for "nan", "inf" and trailing junk).
std::optional<double> to_double(std::string_view token) {
  double value = 0.0;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  if (ec != std::errc() || ptr != end || !std::isfinite(value)) return std::nullopt;
  return value;
}

std::optional<std::int64_t> to_int(std::string_view token) {
  std::int64_t value = 0;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  if (ec != std::errc() || ptr != end) return std::nullopt;
  return value;
}

// Parses tokens[first, first + count) as finite numbers; nullopt if any is not.
std::optional<std::vector<double>> numbers(const std::vector<std::string_view>& tokens, std::size_t first,
                                           std::size_t count) {
  std::vector<double> values;
  values.reserve(count);
  for (std::size_t i = first; i < first + count; ++i) {
    const auto value = to_double(tokens[i]);
    if (!value) return std::nullopt;
    values.push_back(*value);
  }
  return values;
}

// Converts metres to the record's ranges: at/above `sentinel_m` is no return, negative becomes 0 (below range_min, so
// the server skips the beam) with one warning per line.
std::vector<float> to_ranges(const std::vector<double>& metres, double sentinel_m, Diagnostics& diagnostics,
                             std::size_t line_number) {
  std::vector<float> ranges;
  ranges.reserve(metres.size());
  std::size_t negative = 0;
  for (const double r : metres) {
    if (r < 0.0) {
      ++negative;
      ranges.push_back(0.0F);
    } else if (r >= sentinel_m) {
      diagnostics.count_no_return();
      ranges.push_back(kNoReturn);
    } else {
      ranges.push_back(static_cast<float>(r));
    }
  }
  if (negative > 0) {
    diagnostics.warn("negative_range", line_number,
                     std::to_string(negative) + " negative range(s) skipped (sent below range_min)");
  }
  return ranges;
}

std::string text(std::size_t n) { return std::to_string(n); }

// CARMEN logs: FLASER and ROBOTLASER1 scans; PARAM robot_frontlaser_offset; everything else is counted and ignored.
class CarmenParser : public LineParser {
 public:
  using LineParser::LineParser;

 protected:
  std::optional<ScanRecord> parse_tokens(const std::vector<std::string_view>& tokens,
                                         std::size_t line_number) override {
    if (tokens[0].front() == '#') {
      diagnostics_.ignore_line("comment");
      return std::nullopt;
    }
    const std::string type(tokens[0]);
    if (type == "FLASER") return parse_flaser(tokens, line_number);
    if (type == "ROBOTLASER1") return parse_robotlaser(tokens, line_number);
    if (type == "PARAM" && tokens.size() >= 3 && tokens[1] == "robot_frontlaser_offset") {
      if (const auto offset = to_double(tokens[2])) frontlaser_offset_m_ = *offset;
    }
    diagnostics_.ignore_line(type);
    static const std::set<std::string> kKnown = {
        "PARAM",     "SYNC",      "ODOM",      "RLASER",      "TRUEPOS",    "NEFF",     "RAWLASER1",
        "RAWLASER2", "RAWLASER3", "RAWLASER4", "ROBOTLASER2", "LASER1",     "LASER2",   "LASER3",
        "LASER4",    "SONAR",     "BUMPER",    "GPSNMEAGGA",  "GPSNMEARMC", "VELOCITY", "BASEVELOCITY"};
    if (kKnown.count(type) == 0) {
      diagnostics_.warn("unknown_line_type", line_number, "line type '" + type + "' is not a CARMEN message; ignored");
    }
    return std::nullopt;
  }

 private:
  // FLASER n r_1..r_n x y theta odom_x odom_y odom_theta ipc_timestamp [host logger_timestamp]
  std::optional<ScanRecord> parse_flaser(const std::vector<std::string_view>& tokens, std::size_t line_number) {
    const auto n = tokens.size() >= 2 ? to_int(tokens[1]) : std::nullopt;
    // One beam spans no angle (its increment would be pi / 0), so a scan needs two or more.
    if (!n || *n <= 1 || static_cast<std::size_t>(*n) > kMaxBeams) {
      diagnostics_.warn("bad_beam_count", line_number, "FLASER without a valid beam count (2-100000); line skipped");
      return std::nullopt;
    }
    const auto beams = static_cast<std::size_t>(*n);
    const std::size_t needed = 2 + beams + 7;
    if (tokens.size() < needed) {
      diagnostics_.warn("truncated_line", line_number,
                        "FLASER declares " + text(beams) + " beams but has " + text(tokens.size()) + " of at least " +
                            text(needed) + " fields; line skipped");
      return std::nullopt;
    }
    const auto ranges = numbers(tokens, 2, beams);
    const auto tail = numbers(tokens, 2 + beams, 7);
    if (!ranges || !tail) {
      diagnostics_.warn("non_numeric_field", line_number, "FLASER has a non-numeric field; line skipped");
      return std::nullopt;
    }
    ScanRecord scan;
    scan.line_number = line_number;
    scan.stamp_s = (*tail)[6];
    // CARMEN's FLASER pose is the laser's; base_link is frontlaser_offset behind it.
    const LogPose X_WS{(*tail)[0], (*tail)[1], (*tail)[2]};
    scan.X_BS = LogPose{frontlaser_offset_m_, 0.0, 0.0};
    scan.X_WB = X_WS.compose(scan.X_BS.inverse());
    // SICK LMS in CARMEN: 180 beams 1 deg apart from -90 deg (181 beams: -90..+90); other counts span 180 deg.
    scan.angle_min_rad = -kPi / 2.0;
    scan.angle_increment_rad = (beams == 180 || beams == 181) ? kPi / 180.0 : kPi / static_cast<double>(beams - 1);
    scan.ranges_m = to_ranges(*ranges, kCarmenSentinelM, diagnostics_, line_number);
    return scan;
  }

  // ROBOTLASER1 laser_type start_angle fov angular_res max_range accuracy remission_mode num_readings r_1..r_n
  //   num_remissions rem_1..rem_m laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv forward_safety
  //   side_safety turn_axis timestamp [host logger_timestamp]
  std::optional<ScanRecord> parse_robotlaser(const std::vector<std::string_view>& tokens, std::size_t line_number) {
    if (tokens.size() < 9) {
      diagnostics_.warn("truncated_line", line_number, "ROBOTLASER1 cut short before num_readings; line skipped");
      return std::nullopt;
    }
    const auto header = numbers(tokens, 1, 7);
    const auto n = to_int(tokens[8]);
    if (!header || !n) {
      diagnostics_.warn("non_numeric_field", line_number, "ROBOTLASER1 has a non-numeric field; line skipped");
      return std::nullopt;
    }
    if (*n <= 0 || static_cast<std::size_t>(*n) > kMaxBeams) {
      diagnostics_.warn("bad_beam_count", line_number, "ROBOTLASER1 with an invalid num_readings; line skipped");
      return std::nullopt;
    }
    const auto beams = static_cast<std::size_t>(*n);
    const std::size_t remissions_at = 9 + beams;
    if (tokens.size() <= remissions_at) {
      diagnostics_.warn("truncated_line", line_number,
                        "ROBOTLASER1 declares " + text(beams) + " readings but the line ends early; line skipped");
      return std::nullopt;
    }
    const auto m = to_int(tokens[remissions_at]);
    if (!m || *m < 0 || static_cast<std::size_t>(*m) > kMaxBeams) {
      diagnostics_.warn("non_numeric_field", line_number, "ROBOTLASER1 with an invalid num_remissions; line skipped");
      return std::nullopt;
    }
    const std::size_t poses_at = remissions_at + 1 + static_cast<std::size_t>(*m);
    const std::size_t needed = poses_at + 12;
    if (tokens.size() < needed) {
      diagnostics_.warn(
          "truncated_line", line_number,
          "ROBOTLASER1 has " + text(tokens.size()) + " of at least " + text(needed) + " fields; line skipped");
      return std::nullopt;
    }
    const auto ranges = numbers(tokens, 9, beams);
    const auto tail = numbers(tokens, poses_at, 12);
    if (!ranges || !tail) {
      diagnostics_.warn("non_numeric_field", line_number, "ROBOTLASER1 has a non-numeric field; line skipped");
      return std::nullopt;
    }
    const double max_range = (*header)[4];
    ScanRecord scan;
    scan.line_number = line_number;
    scan.stamp_s = (*tail)[11];
    const LogPose X_WS{(*tail)[0], (*tail)[1], (*tail)[2]};
    scan.X_WB = LogPose{(*tail)[3], (*tail)[4], (*tail)[5]};
    scan.X_BS = scan.X_WB.inverse().compose(X_WS);
    scan.angle_min_rad = (*header)[1];
    scan.angle_increment_rad = (*header)[3];
    scan.ranges_m = to_ranges(*ranges, max_range > 0.0 ? max_range : kCarmenSentinelM, diagnostics_, line_number);
    return scan;
  }

  // SICK LMS reports "no return" as 8191 cm (81.91 m); gmapping-processed logs also hold 81.83. No real reading of an
  // LMS reaches 81 m.
  static constexpr double kCarmenSentinelM = 81.0;

  double frontlaser_offset_m_ = 0.0;
};

// DP-SLAM: "Odometry x y theta" then "Laser 181 r_1..r_181", no timestamps.
class DpSlamParser : public LineParser {
 public:
  using LineParser::LineParser;

 protected:
  std::optional<ScanRecord> parse_tokens(const std::vector<std::string_view>& tokens,
                                         std::size_t line_number) override {
    if (tokens[0] == "Odometry") {
      if (tokens.size() < 4) {
        diagnostics_.warn("truncated_line", line_number, "Odometry needs x y theta; line skipped");
        return std::nullopt;
      }
      const auto pose = numbers(tokens, 1, 3);
      if (!pose) {
        diagnostics_.warn("non_numeric_field", line_number, "Odometry has a non-numeric field; line skipped");
        return std::nullopt;
      }
      if (pending_) diagnostics_.warn("odometry_without_laser", line_number, "two Odometry lines in a row");
      pending_ = LogPose{(*pose)[0], (*pose)[1], (*pose)[2]};
      return std::nullopt;
    }
    if (tokens[0] != "Laser") {
      diagnostics_.ignore_line(std::string(tokens[0]));
      diagnostics_.warn("unknown_line_type", line_number, "line type '" + std::string(tokens[0]) + "' ignored");
      return std::nullopt;
    }
    const auto n = tokens.size() >= 2 ? to_int(tokens[1]) : std::nullopt;
    if (!n || *n <= 1 || static_cast<std::size_t>(*n) > kMaxBeams) {
      diagnostics_.warn("bad_beam_count", line_number, "Laser without a valid beam count; line skipped");
      return std::nullopt;
    }
    const auto beams = static_cast<std::size_t>(*n);
    if (tokens.size() < 2 + beams) {
      diagnostics_.warn(
          "truncated_line", line_number,
          "Laser declares " + text(beams) + " beams but has " + text(tokens.size() - 2) + "; line skipped");
      pending_.reset();
      return std::nullopt;
    }
    const auto ranges = numbers(tokens, 2, beams);
    if (!ranges) {
      diagnostics_.warn("non_numeric_field", line_number, "Laser has a non-numeric field; line skipped");
      pending_.reset();
      return std::nullopt;
    }
    if (!pending_) {
      diagnostics_.warn("laser_without_odometry", line_number, "Laser line without a preceding Odometry; skipped");
      return std::nullopt;
    }
    ScanRecord scan;
    scan.line_number = line_number;
    scan.X_WB = *pending_;
    pending_.reset();
    scan.angle_min_rad = -kPi / 2.0;
    scan.angle_increment_rad = kPi / static_cast<double>(beams - 1);
    scan.ranges_m = to_ranges(*ranges, kSentinelM, diagnostics_, line_number);
    return scan;
  }

 private:
  // 8.191 m is the LMS "no return" in 8 m mode; the log also holds 8.183 and 8.187 for the same.
  static constexpr double kSentinelM = 8.18;
  std::optional<LogPose> pending_;
};

// CoreSLAM/tinySLAM exp1.dat: f[0] microseconds, f[2]/f[3] encoder ticks, f[24..705] ranges in mm (0: no return).
class UrgParser : public LineParser {
 public:
  using LineParser::LineParser;

 protected:
  std::optional<ScanRecord> parse_tokens(const std::vector<std::string_view>& tokens,
                                         std::size_t line_number) override {
    if (tokens.size() < kFirstRange + kBeams) {
      diagnostics_.warn(
          "truncated_line", line_number,
          "URG line has " + text(tokens.size()) + " of " + text(kFirstRange + kBeams) + " fields; line skipped");
      return std::nullopt;
    }
    std::vector<std::int64_t> fields;
    fields.reserve(kFirstRange + kBeams);
    for (std::size_t i = 0; i < kFirstRange + kBeams; ++i) {
      auto value = to_int(tokens[i]);
      if (!value && i > 3 && i < kFirstRange) value = 0;  // unused robot fields (one is a decimal, e.g. 170.1)
      if (!value) {
        diagnostics_.warn("non_numeric_field", line_number,
                          "field " + text(i) + " '" + std::string(tokens[i]) + "' is not an integer; line skipped");
        return std::nullopt;
      }
      fields.push_back(*value);
    }
    ScanRecord scan;
    scan.line_number = line_number;
    scan.stamp_s = static_cast<double>(fields[0]) * 1e-6;
    // Only the pose is used; the raw stamp (sanitised later) affects nothing but the odometry's velocity.
    scan.X_WB = odometry_.update(geometry::EncoderReading{.left_ticks = static_cast<std::int64_t>(fields[2]),
                                                          .right_ticks = static_cast<std::int64_t>(fields[3]),
                                                          .time_s = scan.stamp_s.value_or(0.0)});
    scan.X_BS = LogPose{0.145, 0.0, 0.0};
    scan.angle_min_rad = -kFovRad / 2.0;
    scan.angle_increment_rad = kFovRad / static_cast<double>(kBeams - 1);
    std::vector<double> metres;
    metres.reserve(kBeams);
    // The URG-04LX reports failed measurements as codes below 20 mm, 0 included (about half the beams of exp1.dat:
    // dark or glancing surfaces as well as open space). They are not "no return up to max range": clearing along
    // them erases real walls, so they are sent as 0 m, below range_min, and the server skips them.
    std::uint64_t invalid = 0;
    for (std::size_t i = 0; i < kBeams; ++i) {
      const std::int64_t mm = fields[kFirstRange + i];
      if (mm >= 0 && mm < kFirstValidMm) {
        ++invalid;
        metres.push_back(0.0);
      } else {
        metres.push_back(static_cast<double>(mm) * 1e-3);
      }
    }
    diagnostics_.count_invalid_reading(invalid);
    scan.ranges_m = to_ranges(metres, std::numeric_limits<double>::infinity(), diagnostics_, line_number);
    return scan;
  }

 private:
  static constexpr std::size_t kFirstRange = 24;
  static constexpr std::size_t kBeams = 682;
  static constexpr std::int64_t kFirstValidMm = 20;  // URG-04LX: 0-19 are error codes, 20 mm is range_min
  static constexpr double kFovRad = 240.0 * kPi / 180.0;
  geometry::EncoderOdometry odometry_{geometry::minesrover_encoder_params()};
};

}  // namespace

std::optional<ScanRecord> LineParser::parse_line(std::string_view line, std::size_t line_number) {
  const auto tokens = split(line);
  if (tokens.empty()) {
    diagnostics_.ignore_line("empty");
    return std::nullopt;
  }
  return parse_tokens(tokens, line_number);
}

std::optional<LogFormat> parse_format(std::string_view name) {
  if (name == "carmen") return LogFormat::carmen;
  if (name == "dpslam") return LogFormat::dpslam;
  if (name == "urg") return LogFormat::urg;
  if (name == "mcap") return LogFormat::mcap;
  return std::nullopt;
}

std::string format_name(LogFormat format) {
  switch (format) {
    case LogFormat::carmen:
      return "carmen";
    case LogFormat::dpslam:
      return "dpslam";
    case LogFormat::urg:
      return "urg";
    case LogFormat::mcap:
      return "mcap";
  }
  return "?";
}

std::unique_ptr<LineParser> make_parser(LogFormat format, Diagnostics& diagnostics) {
  switch (format) {
    case LogFormat::carmen:
      return std::make_unique<CarmenParser>(diagnostics);
    case LogFormat::dpslam:
      return std::make_unique<DpSlamParser>(diagnostics);
    case LogFormat::urg:
      return std::make_unique<UrgParser>(diagnostics);
    case LogFormat::mcap:
      throw std::invalid_argument("MCAP files are not read line by line (see open_scan_source)");
  }
  return nullptr;
}

FormatTraits traits_of(LogFormat format) {
  switch (format) {
    case LogFormat::carmen:
      // Intel's corrected log: readings beyond ~30 m are rare and unreliable; 81.x is no return.
      return {30.0, 0.05, 0.2, 0.0, 0.3, "sick_lms"};
    case LogFormat::dpslam:
      // 8 m mode: everything from 8.0 m up is at or past the sensor's limit. Stamps are synthesized every 0.2 s.
      return {8.0, 0.05, 0.2, 0.0, 0.3, "sick_lms"};
    case LogFormat::urg:
      // URG-04LX: readings up to ~5.6 m occur; values below 20 mm are error codes. Stamps are a 32-bit us counter.
      return {5.6, 0.02, 0.1, 4294.967296, 0.2, "urg04lx"};
    case LogFormat::mcap:
      // ROS 2 LaserScans carry their own range_min and range_max, which the replay uses instead of these.
      return {30.0, 0.0, 0.1, 0.0, 0.3, "laser"};
  }
  return {30.0, 0.05, 0.2, 0.0, 0.3, "laser"};
}

double TimestampSanitizer::sanitize(std::optional<double> raw_s, Diagnostics& diagnostics, std::size_t line_number) {
  const double previous = previous_s_.value_or(0.0);
  double stamp = 0.0;
  if (!raw_s) {
    stamp = previous + nominal_period_s_;
  } else if (!std::isfinite(*raw_s) || *raw_s <= 0.0) {
    std::ostringstream message;
    message << "timestamp " << *raw_s << " is not positive; using the previous one + " << nominal_period_s_ << " s";
    diagnostics.warn("timestamp_not_positive", line_number, message.str());
    stamp = previous + nominal_period_s_;
  } else {
    if (previous_raw_s_ && wrap_period_s_ > 0.0 && *previous_raw_s_ - *raw_s > wrap_period_s_ / 2.0) {
      wrap_offset_s_ += wrap_period_s_;
      diagnostics.warn("timestamp_wrapped", line_number, "timestamp counter wrapped; unwrapped");
    }
    previous_raw_s_ = *raw_s;
    stamp = *raw_s + wrap_offset_s_;
    if (previous_s_ && stamp <= previous) {
      std::ostringstream message;
      message << "timestamp " << *raw_s << " does not increase (previous " << previous << "); using previous + 1 ms";
      diagnostics.warn("timestamp_not_increasing", line_number, message.str());
      stamp = previous + 1e-3;
    }
  }
  previous_s_ = stamp;
  return stamp;
}

}  // namespace occgeo::replay
