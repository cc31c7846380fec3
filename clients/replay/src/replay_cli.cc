#include <array>
#include <cmath>
#include <stdexcept>

#include "occgeo/client/cli_options.h"
#include "occgeo/replay/replay.h"

namespace occgeo::replay {
namespace {

double positive_number(const std::string& option, const std::string& value) {
  const std::optional<double> number = client::finite_number(value);
  if (!number || *number <= 0.0) {
    throw client::UsageError("option '" + option + "' needs a positive number, got '" + value + "'");
  }
  return *number;
}

// "x,y,z,roll,pitch,yaw": six finite numbers.
std::array<double, 6> six_numbers(const std::string& option, const std::string& value) {
  std::array<double, 6> out{};
  std::size_t at = 0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    const std::size_t comma = value.find(',', at);
    if ((i + 1 < out.size()) == (comma == std::string::npos)) {
      throw client::UsageError("option '" + option + "' needs x,y,z,roll,pitch,yaw, got '" + value + "'");
    }
    const std::string part = value.substr(at, comma == std::string::npos ? std::string::npos : comma - at);
    const std::optional<double> number = client::finite_number(part);
    if (!number) {
      throw client::UsageError("option '" + option + "' needs six numbers x,y,z,roll,pitch,yaw, got '" + value + "'");
    }
    out[i] = *number;
    at = comma + 1;
  }
  return out;
}

}  // namespace

const char* const kReplayUsage = R"(usage: occgeo replay --format carmen|dpslam|urg|mcap FILE [options]
Streams a recorded laser log (gzip or plain text, or a ROS 2 bag in MCAP) to occgeod as a driver: a RobotSpec
matching the log's laser, then Odometry + LaserScan per scan, at most --in-flight scans ahead of their ScanAcks.
The robot asks for the "stop" behaviour: a log cannot be steered.
  --server HOST:PORT   server address (default 127.0.0.1:7700)
  --world W            world to map into (default "default")
  --id ROBOT           robot id (default "replay")
  --speed X            replay at X times the log's speed (default 1)
  --max                as fast as the server answers
  --in-flight N        scans sent ahead of their ScanAck, at most (default 8; 1 waits for each scan's answer)
  --max-range M        readings at or beyond M metres are sent as "no return"
                       (default: carmen 30, dpslam 8, urg 5.6)
  --consistency        first map the even scans into world W-even (robot ROBOT-even), then report the fraction of
                       the odd scans' beam endpoints within one cell of an occupied cell of that map
  --out PREFIX         write the final map of W as PREFIX.pgm + PREFIX.yaml (ROS map_server) and PREFIX.png
                       (the map as `map export --format png` draws it, with the replayed trajectory in red)
  --json               print one JSON summary object on stdout
  --topic-scan T       mcap: the sensor_msgs/msg/LaserScan topic (default: the first one in the file)
  --topic-odom T       mcap: the nav_msgs/msg/Odometry topic (default: the first one; without any, TF
                       odom -> base_link from tf2_msgs/msg/TFMessage topics)
  --topic-cloud T      mcap: the sensor_msgs/msg/PointCloud2 topic (default: the first); its x, y, z points are
                       sent in base_link as PointCloud messages of the sensor "cloud"
  --laser-pose x,y,z,roll,pitch,yaw
                       mcap: the laser in base_link, metres and radians (default: from TF, else at base_link)
Formats: carmen (FLASER / ROBOTLASER1 with their poses), dpslam (Odometry + Laser pairs, no timestamps: stamps are
synthesized every 0.2 s), urg (CoreSLAM exp1.dat: us stamps, encoder ticks integrated into odometry, 682 beams),
mcap (ROS 2 bag, chunks uncompressed, zstd or lz4; CDR LaserScan, Odometry, TFMessage, PointCloud2; the scan's own
range_min/range_max apply unless --max-range is given), or an `occgeo record` recording (protobuf topics): each
recorded robot drives under its own id into its recorded world (or --world W), with its recorded spec, and each
accepted sensor message is sent unchanged after an Odometry at the pose the live server placed it at, so the map
rebuilt equals the live one (--id, --max-range, --topic-* and --consistency do not apply). A damaged file stops the replay with an error naming the
topic and file offset; nothing of the damaged part is sent.
Exit code: 0 done, 1 failure or any server error, 2 usage.
)";

ReplayOptions parse_replay_args(const std::vector<std::string>& args) {
  ReplayOptions options;
  bool help = false;
  std::vector<std::string> files;
  CLI::App app{"occgeo replay", "occgeo replay"};
  client::configure_cli(app, help);
  app.add_option_function<std::string>("--format", [&options](const std::string& name) {
    const auto format = parse_format(name);
    if (!format) throw client::UsageError("option '--format' needs carmen, dpslam, urg or mcap, got '" + name + "'");
    options.format = *format;
  });
  app.add_option("--server", options.server);
  app.add_option("--world", options.world);
  app.add_option("--id", options.robot_id);
  app.add_option_function<std::string>(
      "--speed", [&options](const std::string& text) { options.speed = positive_number("--speed", text); });
  app.add_flag("--max", options.as_fast_as_possible);
  app.add_option_function<std::string>("--in-flight", [&options](const std::string& text) {
    const double count = positive_number("--in-flight", text);
    if (count != std::floor(count) || count > 1024) {
      throw client::UsageError("option '--in-flight' needs a whole number from 1 to 1024, got '" + text + "'");
    }
    options.in_flight = static_cast<std::size_t>(count);
  });
  app.add_option_function<std::string>("--max-range", [&options](const std::string& text) {
    options.max_range_m = positive_number("--max-range", text);
  });
  app.add_option("--out", options.out_prefix);
  app.add_flag("--json", options.json);
  app.add_option("--topic-scan", options.mcap.topic_scan);
  app.add_option("--topic-odom", options.mcap.topic_odom);
  app.add_option("--topic-cloud", options.mcap.topic_cloud);
  app.add_option_function<std::string>("--laser-pose", [&options](const std::string& text) {
    options.mcap.laser_pose = six_numbers("--laser-pose", text);
  });
  app.add_flag("--consistency", options.consistency);
  app.add_option("FILE", files);
  try {
    client::parse_command_line(app, args);
  } catch (const client::UsageError& e) {
    throw std::invalid_argument(e.what());
  }
  if (files.size() > 1) throw std::invalid_argument("unexpected argument '" + files[1] + "' (one log file only)");
  if (app.count("--format") == 0) throw std::invalid_argument("option '--format' is required");
  if (files.empty()) throw std::invalid_argument("missing the log FILE");
  options.file = files.front();
  if (app.count("--speed") > 0 && options.as_fast_as_possible)
    throw std::invalid_argument("options '--speed' and '--max' exclude each other");
  return options;
}

int run_cli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  ReplayOptions options;
  try {
    options = parse_replay_args(args);
  } catch (const std::invalid_argument& e) {
    err << "occgeo replay: " << e.what() << "\nrun 'occgeo replay --help' for usage\n";
    return 2;
  }
  if (options.format != LogFormat::mcap && (!options.mcap.topic_scan.empty() || !options.mcap.topic_odom.empty() ||
                                            !options.mcap.topic_cloud.empty() || options.mcap.laser_pose)) {
    err << "occgeo replay: options '--topic-scan', '--topic-odom', '--topic-cloud' and '--laser-pose' need --format "
           "mcap\nrun 'occgeo replay --help' for usage\n";
    return 2;
  }
  Diagnostics diagnostics(&err);
  ReplaySummary summary;
  try {
    summary = run_replay(options, diagnostics, err);
  } catch (const McapError& e) {
    err << "occgeo replay: " << e.what() << "\n";
    return 1;
  }
  if (options.json) {
    out << summary_json(options, summary, diagnostics) << "\n";
  } else {
    out << summary.scans << " scans (" << summary.scans_acked << " accepted) in " << summary.duration_s << " s, "
        << summary.scans_per_s << " scans/s; " << summary.errors << " server error(s), " << diagnostics.warnings()
        << " warning(s)";
    for (const auto& [kind, count] : diagnostics.warnings_by_kind()) out << " " << kind << "=" << count;
    out << "\n";
    if (!summary.scans_per_s_by_tenth.empty()) {
      out << "scans/s per tenth of the log:";
      for (const double rate : summary.scans_per_s_by_tenth) out << " " << std::llround(rate);
      out << "\n";
    }
    if (summary.consistency) {
      out << "consistency: " << *summary.consistency << " of " << summary.consistency_endpoints
          << " odd-scan endpoints lie within one cell of an occupied cell of the even-scan map\n";
    }
    for (const auto& file : summary.files_written) out << "wrote " << file << "\n";
  }
  return summary.errors == 0 ? 0 : 1;
}

}  // namespace occgeo::replay
