#include "occgeo/replay/replay.h"
#include "occgeo/proto/protocol.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <iostream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "occgeo/client/connection.h"
#include "occgeo/client/grid.h"
#include "occgeo/client/json.h"
#include "occgeo/mapfile/certainty_image.h"
#include "occgeo/mapfile/map_file.h"
#include "occgeo/mapfile/map_picture.h"
#include "occgeo/replay/line_source.h"

namespace occgeo::replay {
namespace {

namespace v1 = occgeo::v1;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

std::string fmt(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", v);
  return buffer;
}

using client::json_string;

std::string json_counts(const std::map<std::string, std::uint64_t>& counts) {
  std::string out = "{";
  bool first = true;
  for (const auto& [kind, count] : counts) {
    out += (first ? "" : ",") + json_string(kind) + ":" + std::to_string(count);
    first = false;
  }
  return out + "}";
}

// Progress on stderr: a bar redrawn at most 4 times a second on a terminal, otherwise a line every 10 %.
class Progress {
 public:
  Progress(std::ostream& err, bool tty, std::string label) : err_(err), tty_(tty), label_(std::move(label)) {}

  void update(double fraction, std::uint64_t scans, double elapsed_s) {
    mark_tenths(fraction, scans, elapsed_s);
    const double rate = elapsed_s > 0.0 ? static_cast<double>(scans) / elapsed_s : 0.0;
    if (tty_) {
      const auto now = Clock::now();
      if (drawn_ && now - last_draw_ < std::chrono::milliseconds(250)) return;
      last_draw_ = now;
      drawn_ = true;
      constexpr int kWidth = 30;
      const int filled = static_cast<int>(fraction * kWidth);
      char line[160];
      std::snprintf(line, sizeof line, "\r%s [%-*s] %3.0f%% %llu scans %.0f scans/s", label_.c_str(), kWidth,
                    std::string(static_cast<std::size_t>(std::max(0, filled)), '#').c_str(), fraction * 100.0,
                    static_cast<unsigned long long>(scans), rate);
      err_ << line << std::flush;
    } else {
      const int decile = static_cast<int>(fraction * 10.0);
      if (decile <= last_decile_ || decile >= 10) return;
      last_decile_ = decile;
      err_ << label_ << ": " << decile * 10 << "% (" << scans << " scans, " << fmt(rate) << " scans/s)\n";
    }
  }

  // Scans per second within each tenth of the log (by position in the file), once finished. A tenth the reader
  // jumped over at once (an MCAP chunk spanning it) gets the rate of the stretch that covered it.
  [[nodiscard]] std::vector<double> scans_per_s_by_tenth() const {
    std::vector<double> rates;
    for (std::size_t i = 0; i + 1 < marks_.size(); ++i) {
      const double dt = marks_[i + 1].elapsed_s - marks_[i].elapsed_s;
      const auto ds = static_cast<double>(marks_[i + 1].scans - marks_[i].scans);
      rates.push_back(dt > 0.0 ? ds / dt : (rates.empty() ? 0.0 : rates.back()));
    }
    // Leading tenths that took no time at all (a first chunk read at once) take the first measured rate.
    const auto first = std::find_if(rates.begin(), rates.end(), [](double r) { return r > 0.0; });
    if (first != rates.end()) std::fill(rates.begin(), first, *first);
    return rates;
  }

  void finish(std::uint64_t scans, double elapsed_s) {
    mark_tenths(1.0, scans, elapsed_s);
    if (tty_ && drawn_) {
      drawn_ = false;  // draw the final state regardless of the rate limit
      update(1.0, scans, elapsed_s);
      err_ << "\n";
    }
    err_ << label_ << ": done, " << scans << " scans in " << fmt(elapsed_s) << " s ("
         << fmt(elapsed_s > 0.0 ? static_cast<double>(scans) / elapsed_s : 0.0) << " scans/s)\n";
  }

 private:
  std::ostream& err_;
  bool tty_;
  std::string label_;
  // Where each tenth of the log began: marks_[i] is the count and time when the reader passed i/10 of it.
  void mark_tenths(double fraction, std::uint64_t scans, double elapsed_s) {
    if (marks_.empty()) marks_.push_back({0, 0.0});
    const auto reached = static_cast<std::size_t>(std::clamp(fraction, 0.0, 1.0) * 10.0);
    while (marks_.size() <= reached && marks_.size() <= 10) marks_.push_back({scans, elapsed_s});
  }

  struct Mark {
    std::uint64_t scans = 0;
    double elapsed_s = 0.0;
  };
  Clock::time_point last_draw_;
  bool drawn_ = false;
  int last_decile_ = 0;
  std::vector<Mark> marks_;
};

constexpr const char* kCloudSensor = "cloud";

v1::RobotSpec make_spec(LogFormat format, const ScanRecord& first, const FormatTraits& traits, double range_min_m,
                        double range_max_m) {
  v1::RobotSpec spec;
  spec.set_model("replay-" + format_name(format));
  const bool urg = format == LogFormat::urg;
  auto& drive = *spec.mutable_kinematics()->mutable_differential();
  drive.set_wheel_separation_m(urg ? 0.33 : 0.5);
  drive.set_wheel_radius_m(urg ? 0.077 : 0.1);
  drive.set_max_wheel_speed_mps(1.0);
  auto& box = *spec.mutable_footprint()->mutable_box();
  box.set_length_m(0.5);
  box.set_width_m(urg ? 0.4 : 0.5);
  box.set_height_m(0.4);
  box.set_center_x_m(0.0);
  auto& sensor = *spec.add_sensors();
  sensor.set_name(traits.sensor_name);
  auto& mount = *sensor.mutable_mount();
  mount.mutable_position()->set_x(first.X_BS.x);
  mount.mutable_position()->set_y(first.X_BS.y);
  mount.mutable_position()->set_z(traits.sensor_height_m);
  mount.set_yaw(first.X_BS.theta);
  auto& laser = *sensor.mutable_laser();
  laser.set_angle_min_rad(first.angle_min_rad);
  laser.set_angle_increment_rad(first.angle_increment_rad);
  laser.set_beam_count(static_cast<std::uint32_t>(first.ranges_m.size()));
  laser.set_range_min_m(range_min_m);
  laser.set_range_max_m(range_max_m);
  laser.set_scan_period_s(traits.nominal_period_s);
  if (format == LogFormat::mcap) {
    // A bag's PointCloud2 topic: points are sent already in base_link (their TF mount applied), so the sensor sits
    // at base_link's origin.
    auto& cloud = *spec.add_sensors();
    cloud.set_name(kCloudSensor);
    cloud.mutable_mount()->mutable_position();
    auto& model = *cloud.mutable_point_cloud();
    model.set_range_max_m(range_max_m);
    model.set_max_points(100000);
  }
  spec.set_command_timeout_s(1.0);
  // A log cannot be steered: the server need not plan motion for it.
  spec.set_default_behaviour(v1::BEHAVIOUR_STOP);
  return spec;
}

bool same_geometry(const ScanRecord& a, const ScanRecord& b) {
  return a.ranges_m.size() == b.ranges_m.size() && std::abs(a.angle_min_rad - b.angle_min_rad) < 1e-6 &&
         std::abs(a.angle_increment_rad - b.angle_increment_rad) < 1e-9 && std::abs(a.X_BS.x - b.X_BS.x) < 1e-3 &&
         std::abs(a.X_BS.y - b.X_BS.y) < 1e-3 && std::abs(a.X_BS.theta - b.X_BS.theta) < 1e-3;
}

// One pass over the log into one world.
struct PassConfig {
  std::string world;
  std::string robot_id;
  bool even_only = false;
  std::string label;
  const mapfile::CertaintyWindow* consistency_grid = nullptr;  // count odd scans' endpoints against this grid
};

struct PassResult {
  std::uint64_t scans = 0;
  std::uint64_t acked = 0;
  std::uint64_t clouds = 0;
  std::uint64_t clouds_acked = 0;
  std::uint64_t errors = 0;
  double duration_s = 0.0;
  std::vector<double> scans_per_s_by_tenth;
  ConsistencyCounter consistency;
  std::optional<v1::GridReply> grid;
  std::vector<mapfile::PicturePose> trajectory;  // base_link of every scan sent, world frame
};

class Pass {
 public:
  Pass(const ReplayOptions& options, const PassConfig& config, Diagnostics& diagnostics, std::ostream& err)
      : options_(options),
        config_(config),
        diagnostics_(diagnostics),
        err_(err),
        traits_(traits_of(options.format)),
        range_min_m_(traits_.range_min_m),
        range_max_m_(options.max_range_m.value_or(traits_.default_range_max_m)),
        stamps_(traits_.nominal_period_s, traits_.wrap_period_s) {}

  PassResult run() {
    auto source = open_scan_source(options_.format, options_.file, options_.mcap, diagnostics_,
                                   config_.even_only ? nullptr : &err_);
    std::optional<ScanRecord> spec_scan;
    std::optional<client::Connection> connection;
    Progress progress(err_, ::isatty(STDERR_FILENO) == 1 && &err_ == &std::cerr, config_.label);
    const auto start = Clock::now();
    std::optional<double> first_stamp;
    std::uint64_t index = 0;  // scan number in the log, 0-based
    while (auto scan = source->next()) {
      send_clouds(*source, connection, index);
      if (!spec_scan) {
        spec_scan = *scan;
        // A ROS LaserScan states its own limits; an explicit --max-range still wins.
        if (scan->sensor_range_min_m) range_min_m_ = *scan->sensor_range_min_m;
        if (scan->sensor_range_max_m && !options_.max_range_m) range_max_m_ = *scan->sensor_range_max_m;
        connection.emplace(connect(*spec_scan));
      } else if (!same_geometry(*spec_scan, *scan)) {
        diagnostics_.warn("scan_geometry_mismatch", scan->line_number,
                          "beam count, angles or laser mount differ from the first scan's; scan skipped");
        continue;
      }
      const double stamp = stamps_.sanitize(scan->stamp_s, diagnostics_, scan->line_number);
      const std::uint64_t this_index = index++;
      const bool even = this_index % 2 == 0;
      if (config_.consistency_grid != nullptr && !even) {
        result_.consistency.add_scan(*config_.consistency_grid, *scan, range_min_m_, range_max_m_);
      }
      if (config_.even_only && !even) continue;
      if (!first_stamp) first_stamp = stamp;
      if (!options_.as_fast_as_possible) {
        const auto due = start + std::chrono::duration_cast<Clock::duration>(
                                     std::chrono::duration<double>((stamp - *first_stamp) / options_.speed));
        std::this_thread::sleep_until(due);
      }
      last_stamp_ = stamp;
      send_scan(*connection, this_index + 1 + clouds_sent_, stamp, *scan);
      result_.trajectory.push_back({scan->X_WB.x, scan->X_WB.y, scan->X_WB.theta});
      ++result_.scans;
      progress.update(source->progress(), result_.scans, seconds_since(start));
    }
    send_clouds(*source, connection, index);
    if (connection) await_answers(*connection, 0);
    result_.duration_s = seconds_since(start);
    progress.finish(result_.scans, result_.duration_s);
    result_.scans_per_s_by_tenth = progress.scans_per_s_by_tenth();
    if (!connection) throw std::runtime_error("no usable scan in '" + options_.file.string() + "'");
    v1::ClientMessage request;
    request.mutable_grid();
    request.set_request_id(1);
    request.mutable_grid()->set_world(config_.world);
    result_.grid = connection->call(request, 1, std::chrono::seconds(60)).grid();
    return std::move(result_);
  }

 private:
  client::Connection connect(const ScanRecord& first) {
    auto connection = client::Connection::open(client::Endpoint::parse(options_.server));
    v1::Hello hello;
    hello.set_protocol_version(occgeo::proto::kProtocolVersion);
    hello.set_role(v1::ROLE_DRIVER);
    hello.set_robot_id(config_.robot_id);
    hello.set_world(config_.world);
    hello.set_client_name("occgeo-replay");
    connection.hello(hello);
    v1::ClientMessage spec;
    *spec.mutable_robot_spec() = make_spec(options_.format, first, traits_, range_min_m_, range_max_m_);
    connection.send(spec);
    return connection;
  }

  void send_scan(client::Connection& connection, std::uint64_t seq, double stamp, const ScanRecord& scan) {
    v1::ClientMessage odometry;
    auto& odom = *odometry.mutable_odometry();
    odom.set_seq(seq);
    odom.set_stamp_s(stamp);
    odom.mutable_pose()->set_x(scan.X_WB.x);
    odom.mutable_pose()->set_y(scan.X_WB.y);
    odom.mutable_pose()->set_theta(scan.X_WB.theta);
    connection.send(odometry);
    v1::ClientMessage message;
    auto& laser = *message.mutable_laser_scan();
    laser.set_sensor(traits_.sensor_name);
    laser.set_seq(seq);
    laser.set_stamp_s(stamp);
    auto& ranges = *laser.mutable_ranges();
    ranges.Reserve(static_cast<int>(scan.ranges_m.size()));
    const auto range_max = static_cast<float>(range_max_m_);
    for (const float r : scan.ranges_m) ranges.Add(r >= range_max ? range_max : r);  // +inf and far: no return
    connection.send(message);
    unanswered_.push_back(seq);
    await_answers(connection, options_.in_flight - 1);
  }

  // Sends the clouds the source read so far (full pass only: the consistency check is about scans). Each goes after
  // the scan before it with the next seq, the stamp of that scan and an odometry message with its own pose.
  void send_clouds(ScanSource& source, std::optional<client::Connection>& connection, std::uint64_t scans_so_far) {
    for (CloudRecord& cloud : source.take_clouds()) {
      if (config_.even_only) continue;
      if (!connection) {
        diagnostics_.warn("cloud_before_first_scan", cloud.number,
                          "point cloud comes before the first laser scan (which starts the robot); cloud skipped");
        continue;
      }
      const std::uint64_t seq = scans_so_far + ++clouds_sent_;
      v1::ClientMessage odometry;
      auto& odom = *odometry.mutable_odometry();
      odom.set_seq(seq);
      odom.set_stamp_s(last_stamp_);
      odom.mutable_pose()->set_x(cloud.X_WB.x);
      odom.mutable_pose()->set_y(cloud.X_WB.y);
      odom.mutable_pose()->set_theta(cloud.X_WB.theta);
      await_answers(*connection, 0);  // the scans' answers first, so that the counts below are the cloud's
      connection->send(odometry);
      v1::ClientMessage message;
      auto& points = *message.mutable_point_cloud();
      points.set_sensor(kCloudSensor);
      points.set_seq(seq);
      points.set_stamp_s(last_stamp_);
      points.mutable_xyz()->Assign(cloud.xyz_B.begin(), cloud.xyz_B.end());
      connection->send(message);
      ++result_.clouds;
      const std::uint64_t acked_before = result_.acked;
      unanswered_.push_back(seq);
      await_answers(*connection, 0);
      if (result_.acked > acked_before) {
        --result_.acked;  // counted as a cloud, not a scan
        ++result_.clouds_acked;
      }
    }
  }

  // Reads the server's answers until at most `keep` messages are unanswered: a ScanAck answers its message, and so
  // does an Error naming it (other than its odometry's); motion commands are read and dropped (a log cannot obey
  // them). Gives up when no answer comes for ack_timeout_s.
  void await_answers(client::Connection& connection, std::size_t keep) {
    const auto timeout =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(options_.ack_timeout_s));
    auto deadline = Clock::now() + timeout;
    while (unanswered_.size() > keep) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
      if (left.count() <= 0) {
        throw std::runtime_error("no answer to scan " + std::to_string(unanswered_.front()) + " within " +
                                 fmt(options_.ack_timeout_s) + " s");
      }
      const auto message = connection.receive(left);
      if (!message) continue;
      if (message->has_scan_ack()) {
        if (answer(message->scan_ack().seq())) {
          ++result_.acked;
          deadline = Clock::now() + timeout;
        }
        continue;
      }
      if (!message->has_error()) continue;
      const v1::Error& error = message->error();
      if (error.field().rfind("robot_spec", 0) == 0 || error.field().rfind("hello", 0) == 0) {
        throw std::runtime_error("the server refused the robot spec: " + client::describe(error));
      }
      ++result_.errors;
      if (result_.errors <= 5) err_ << "occgeo replay: server error: " << client::describe(error) << "\n";
      if (result_.errors == 5) err_ << "occgeo replay: further server errors are counted but not printed\n";
      if (error.field().rfind("odometry", 0) != 0 && answer(error.seq())) deadline = Clock::now() + timeout;
    }
  }

  // Removes seq from the unanswered messages; false when it was not one of them.
  bool answer(std::uint64_t seq) {
    const auto it = std::find(unanswered_.begin(), unanswered_.end(), seq);
    if (it == unanswered_.end()) return false;
    unanswered_.erase(it);
    return true;
  }

  const ReplayOptions& options_;
  PassConfig config_;
  Diagnostics& diagnostics_;
  std::ostream& err_;
  FormatTraits traits_;
  double range_min_m_;
  double range_max_m_;
  TimestampSanitizer stamps_;
  PassResult result_;
  std::uint64_t clouds_sent_ = 0;         // clouds take seqs between the scans'
  std::deque<std::uint64_t> unanswered_;  // seqs sent and not yet answered, oldest first
  double last_stamp_ = 0.0;               // of the last scan sent
};

// Whether `file` is an occgeo recording (`occgeo record`): its first message is protobuf with an occgeo.v1 schema.
bool is_occgeo_recording(const std::filesystem::path& file) {
  McapReader reader(file);
  const auto first = reader.next();
  return first && first->schema != nullptr && first->channel->message_encoding == "protobuf" &&
         first->schema->name.rfind("occgeo.v1.", 0) == 0;
}

// Replays an occgeo recording: each recorded robot connects as a driver under its recorded id, into its recorded
// world (or --world when given), sends its recorded RobotSpec, then per accepted sensor message an Odometry at the
// pose the live server placed it at and the message itself, unchanged, each waiting for its ScanAck. So the server
// applies what the live one applied, in the same order, and builds the same map.
class RecordingPass {
 public:
  RecordingPass(const ReplayOptions& options, Diagnostics& diagnostics, std::ostream& err)
      : options_(options), diagnostics_(diagnostics), err_(err) {}

  PassResult run() {
    McapReader reader(options_.file);
    Progress progress(err_, ::isatty(STDERR_FILENO) == 1 && &err_ == &std::cerr, "recording -> server");
    const auto start = Clock::now();
    std::optional<double> first_stamp;
    std::uint64_t sensor_messages = 0;
    while (const auto message = reader.next()) {
      const std::string& topic = message->channel->topic;
      auto fail = [&](const std::string& what) -> void {
        throw McapError(
            reader.name() + ": offset " + std::to_string(message->offset) + ": topic '" + topic + "' " + what,
            message->offset);
      };
      if (message->schema == nullptr || message->channel->message_encoding != "protobuf" ||
          message->schema->name.rfind("occgeo.v1.", 0) != 0) {
        if (foreign_topics_.insert(topic).second) {
          diagnostics_.warn("foreign_topic", sensor_messages,
                            "topic '" + topic + "' is not an occgeo recording's; its messages are skipped");
        }
        continue;
      }
      // /WORLD/ROBOT/KIND
      const std::size_t second = topic.find('/', 1);
      const std::size_t third = second == std::string::npos ? std::string::npos : topic.find('/', second + 1);
      if (topic.empty() || topic[0] != '/' || second == std::string::npos) fail("is not /WORLD/ROBOT/KIND");
      if (third == std::string::npos) continue;  // /WORLD/grid: the live grid's changes, rebuilt here from the scans
      const std::string world = topic.substr(1, second - 1);
      const std::string robot = topic.substr(second + 1, third - second - 1);
      const std::string kind = topic.substr(third + 1);
      v1::ClientMessage sensor;
      google::protobuf::Message* body = nullptr;
      if (kind == "robot_spec") {
        v1::RobotSpec spec;
        if (!spec.ParseFromArray(message->data.data(), static_cast<int>(message->data.size()))) {
          fail("does not decode as occgeo.v1.RobotSpec");
        }
        spec.set_default_behaviour(v1::BEHAVIOUR_STOP);  // a recording replayed cannot be steered either
        if (drivers_.count(world + "/" + robot) == 0) connect(world, robot, spec);
        continue;
      }
      Driver* driver = nullptr;
      if (const auto it = drivers_.find(world + "/" + robot); it != drivers_.end()) driver = &it->second;
      if (kind == "placement") {
        v1::WatchEvent placement;
        if (!placement.ParseFromArray(message->data.data(), static_cast<int>(message->data.size()))) {
          fail("does not decode as occgeo.v1.WatchEvent");
        }
        if (driver != nullptr) driver->placement = placement;
        continue;
      }
      if (kind == "laser_scan") {
        body = sensor.mutable_laser_scan();
      } else if (kind == "range_array") {
        body = sensor.mutable_range_array();
      } else if (kind == "servo_range") {
        body = sensor.mutable_servo_range();
      } else if (kind == "point_cloud") {
        body = sensor.mutable_point_cloud();
      } else {
        continue;  // odometry and motion commands: the placements carry the poses, and a log cannot obey commands
      }
      if (!body->ParseFromArray(message->data.data(), static_cast<int>(message->data.size()))) {
        fail("does not decode as occgeo.v1." + std::string(body->GetDescriptor()->name()));
      }
      const auto* fields = body->GetDescriptor();
      const auto* reflection = body->GetReflection();
      const std::uint64_t seq = reflection->GetUInt64(*body, fields->FindFieldByName("seq"));
      const double stamp = reflection->GetDouble(*body, fields->FindFieldByName("stamp_s"));
      ++sensor_messages;
      if (driver == nullptr) {
        diagnostics_.warn("no_robot_spec", sensor_messages,
                          "topic '" + topic + "' has a message before the robot's spec; message skipped");
        continue;
      }
      if (!driver->placement || driver->placement->seq() != seq) {
        diagnostics_.warn("no_placement", sensor_messages,
                          "topic '" + topic + "' message " + std::to_string(seq) +
                              " has no placement (the recorder lost events); message skipped");
        continue;
      }
      if (!first_stamp) first_stamp = stamp;
      if (!options_.as_fast_as_possible) {
        const auto due = start + std::chrono::duration_cast<Clock::duration>(
                                     std::chrono::duration<double>((stamp - *first_stamp) / options_.speed));
        std::this_thread::sleep_until(due);
      }
      v1::ClientMessage odometry;
      auto& odom = *odometry.mutable_odometry();
      odom.set_seq(seq);
      odom.set_stamp_s(stamp);
      *odom.mutable_pose() = driver->placement->pose();
      driver->connection.send(odometry);
      driver->connection.send(sensor);
      const bool cloud = kind == "point_cloud";
      ++(cloud ? result_.clouds : result_.scans);
      if (await_answer(*driver, seq)) ++(cloud ? result_.clouds_acked : result_.acked);
      if (drivers_.size() > 1 && ++since_drain_ >= kDrainEvery) drain_others(*driver);
      if (world == grid_world_) {
        result_.trajectory.push_back(
            {driver->placement->pose().x(), driver->placement->pose().y(), driver->placement->pose().theta()});
      }
      progress.update(reader.progress(), result_.scans + result_.clouds, seconds_since(start));
    }
    result_.duration_s = seconds_since(start);
    progress.finish(result_.scans + result_.clouds, result_.duration_s);
    result_.scans_per_s_by_tenth = progress.scans_per_s_by_tenth();
    if (drivers_.empty()) throw std::runtime_error("no robot spec in the recording '" + options_.file.string() + "'");
    v1::ClientMessage request;
    request.mutable_grid();
    request.set_request_id(1);
    request.mutable_grid()->set_world(grid_world_);
    result_.grid = drivers_.begin()->second.connection.call(request, 1, std::chrono::seconds(60)).grid();
    return std::move(result_);
  }

  [[nodiscard]] const std::string& grid_world() const { return grid_world_; }

 private:
  struct Driver {
    client::Connection connection;
    std::optional<v1::WatchEvent> placement;  // of the sensor message that follows it
  };

  void connect(const std::string& recorded_world, const std::string& robot, const v1::RobotSpec& spec) {
    const std::string world = options_.world == "default" ? recorded_world : options_.world;
    auto connection = client::Connection::open(client::Endpoint::parse(options_.server));
    v1::Hello hello;
    hello.set_protocol_version(occgeo::proto::kProtocolVersion);
    hello.set_role(v1::ROLE_DRIVER);
    hello.set_robot_id(robot);
    hello.set_world(world);
    hello.set_client_name("occgeo-replay");
    connection.hello(hello);
    v1::ClientMessage message;
    *message.mutable_robot_spec() = spec;
    connection.send(message);
    if (drivers_.empty()) grid_world_ = world;
    err_ << "occgeo replay: robot " << robot << " of the recording -> world " << world << "\n";
    drivers_.emplace(recorded_world + "/" + robot, Driver{std::move(connection), std::nullopt});
  }

  // Lockstep: the message's ScanAck (true) or its Error (false); motion commands are read and dropped.
  bool await_answer(Driver& driver, std::uint64_t seq) {
    const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                             std::chrono::duration<double>(options_.ack_timeout_s));
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
      if (left.count() <= 0) {
        throw std::runtime_error("no answer to message " + std::to_string(seq) + " within " +
                                 fmt(options_.ack_timeout_s) + " s");
      }
      const auto message = driver.connection.receive(left);
      if (!message) continue;
      if (message->has_scan_ack() && message->scan_ack().seq() == seq) return true;
      if (!message->has_error()) continue;
      const v1::Error& error = message->error();
      if (error.field().rfind("robot_spec", 0) == 0 || error.field().rfind("hello", 0) == 0) {
        throw std::runtime_error("the server refused the recorded robot spec: " + client::describe(error));
      }
      ++result_.errors;
      if (result_.errors <= 5) err_ << "occgeo replay: server error: " << client::describe(error) << "\n";
      if (result_.errors == 5) err_ << "occgeo replay: further server errors are counted but not printed\n";
      if (error.seq() == seq && error.field().rfind("odometry", 0) != 0) return false;
    }
  }

  // The robots not being sent to also get commands (and the watchdog's stops): read and dropped now and then, so their
  // unread replies never pile up on the server.
  void drain_others(Driver& current) {
    since_drain_ = 0;
    for (auto& [key, driver] : drivers_) {
      if (&driver == &current) continue;
      while (const auto message = driver.connection.receive(std::chrono::milliseconds(0))) {
        if (message->has_error()) {
          ++result_.errors;
          if (result_.errors <= 5)
            err_ << "occgeo replay: server error: " << client::describe(message->error()) << "\n";
        }
      }
    }
  }

  static constexpr std::uint64_t kDrainEvery = 32;
  const ReplayOptions& options_;
  Diagnostics& diagnostics_;
  std::ostream& err_;
  std::uint64_t since_drain_ = 0;
  std::map<std::string, Driver> drivers_;  // by recorded "world/robot"
  std::string grid_world_;                 // the first robot's: --out and the summary's map
  std::set<std::string> foreign_topics_;
  PassResult result_;
};

}  // namespace

bool occupied_near(const mapfile::CertaintyWindow& grid, double x, double y) {
  if (grid.width == 0 || grid.height == 0 || grid.cells.size() != static_cast<std::size_t>(grid.width) * grid.height) {
    return false;
  }
  const auto ix = static_cast<std::int64_t>(std::floor(x / grid.cell_size_m)) - grid.min_ix;
  const auto iy = static_cast<std::int64_t>(std::floor(y / grid.cell_size_m)) - grid.min_iy;
  for (std::int64_t dy = -1; dy <= 1; ++dy) {
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      const std::int64_t cx = ix + dx, cy = iy + dy;
      if (cx < 0 || cy < 0 || cx >= grid.width || cy >= grid.height) continue;
      const std::uint8_t value = grid.cells[static_cast<std::size_t>(cy * grid.width + cx)];
      if (value != mapfile::kUnobservedCertainty && value >= grid.occupied_threshold) return true;
    }
  }
  return false;
}

void ConsistencyCounter::add_scan(const mapfile::CertaintyWindow& grid, const ScanRecord& scan, double range_min_m,
                                  double range_max_m) {
  const LogPose X_WS = scan.X_WB.compose(scan.X_BS);
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    const double r = static_cast<double>(scan.ranges_m[i]);
    if (!(r >= range_min_m && r < range_max_m)) continue;
    const double angle = X_WS.theta + scan.angle_min_rad + static_cast<double>(i) * scan.angle_increment_rad;
    ++endpoints_;
    if (occupied_near(grid, X_WS.x + r * std::cos(angle), X_WS.y + r * std::sin(angle))) ++hits_;
  }
}

namespace {
ReplaySummary finish_summary(const ReplayOptions& options, PassResult full, std::ostream& err);
}  // namespace

ReplaySummary run_replay(const ReplayOptions& options, Diagnostics& diagnostics, std::ostream& err) {
  ReplaySummary summary;
  if (options.format == LogFormat::mcap && is_occgeo_recording(options.file)) {
    if (options.consistency)
      err << "occgeo replay: --consistency is for laser logs and bags; a recording is replayed once\n";
    ReplayOptions once = options;
    once.consistency = false;
    return finish_summary(once, RecordingPass(once, diagnostics, err).run(), err);
  }
  std::optional<mapfile::CertaintyWindow> even_grid;
  if (options.consistency) {
    Diagnostics quiet;  // the full pass reports the log's quirks; do not count them twice
    PassConfig config{.world = options.world + "-even",
                      .robot_id = options.robot_id + "-even",
                      .even_only = true,
                      .label = "even scans -> " + options.world + "-even",
                      .consistency_grid = nullptr};
    PassResult even = Pass(options, config, quiet, err).run();
    summary.errors += even.errors;
    even_grid = client::certainty_window(*even.grid);
  }
  PassConfig config{.world = options.world,
                    .robot_id = options.robot_id,
                    .even_only = false,
                    .label = "scans -> " + options.world,
                    .consistency_grid = even_grid ? &*even_grid : nullptr};
  PassResult full = Pass(options, config, diagnostics, err).run();
  const std::uint64_t even_errors = summary.errors;
  summary = finish_summary(options, std::move(full), err);
  summary.errors += even_errors;
  return summary;
}

namespace {

// The summary of the full pass, and the map files --out asks for.
ReplaySummary finish_summary(const ReplayOptions& options, PassResult full, std::ostream& err) {
  ReplaySummary summary;
  summary.scans = full.scans;
  summary.scans_acked = full.acked;
  summary.clouds = full.clouds;
  summary.clouds_acked = full.clouds_acked;
  summary.errors += full.errors;
  summary.duration_s = full.duration_s;
  summary.scans_per_s = full.duration_s > 0.0 ? static_cast<double>(full.scans) / full.duration_s : 0.0;
  summary.scans_per_s_by_tenth = full.scans_per_s_by_tenth;
  if (options.consistency) {
    summary.consistency = full.consistency.fraction();
    summary.consistency_endpoints = full.consistency.endpoints();
  }
  if (!options.out_prefix.empty()) {
    const v1::GridReply& grid = *full.grid;
    if (grid.width() == 0 || grid.height() == 0) {
      err << "occgeo replay: world '" << options.world << "' has no observed cells; no map written\n";
    } else {
      const mapfile::OccupancyImage image = mapfile::image_from_certainty(client::certainty_window(grid));
      mapfile::write_map(options.out_prefix, image);
      // The picture `occgeo map export --format png` draws, with the replayed trajectory and its final pose on it.
      mapfile::MapPicture picture = mapfile::render_certainty(client::certainty_window(grid), 1);
      mapfile::PictureOverlays overlays;
      for (const auto& pose : full.trajectory) overlays.trajectory.push_back({pose.x, pose.y});
      if (!full.trajectory.empty()) overlays.markers.push_back(full.trajectory.back());
      mapfile::draw_overlays(picture, overlays);
      picture.write_png(options.out_prefix + ".png");
      summary.files_written = {options.out_prefix + ".pgm", options.out_prefix + ".yaml", options.out_prefix + ".png"};
    }
  }
  return summary;
}

}  // namespace

std::string summary_json(const ReplayOptions& options, const ReplaySummary& summary, const Diagnostics& diagnostics) {
  std::ostringstream out;
  out << "{\"format\":" << json_string(format_name(options.format))
      << ",\"file\":" << json_string(options.file.string()) << ",\"world\":" << json_string(options.world)
      << ",\"scans\":" << summary.scans << ",\"scans_acked\":" << summary.scans_acked
      << ",\"errors\":" << summary.errors << ",\"warnings\":" << diagnostics.warnings()
      << ",\"warnings_by_kind\":" << json_counts(diagnostics.warnings_by_kind())
      << ",\"ignored_lines\":" << json_counts(diagnostics.ignored_lines())
      << ",\"no_return_beams\":" << diagnostics.no_return_beams()
      << ",\"invalid_beams\":" << diagnostics.invalid_beams() << ",\"duration_s\":" << fmt(summary.duration_s)
      << ",\"scans_per_s\":" << fmt(summary.scans_per_s) << ",\"scans_per_s_by_tenth\":[";
  for (std::size_t i = 0; i < summary.scans_per_s_by_tenth.size(); ++i) {
    out << (i ? "," : "") << fmt(summary.scans_per_s_by_tenth[i]);
  }
  out << "],\"clouds\":" << summary.clouds << ",\"clouds_acked\":" << summary.clouds_acked
      << ",\"stamps_synthesized\":" << (options.format == LogFormat::dpslam ? "true" : "false");
  if (summary.consistency) {
    out << ",\"consistency\":" << fmt(*summary.consistency)
        << ",\"consistency_endpoints\":" << summary.consistency_endpoints;
  }
  out << ",\"files\":[";
  for (std::size_t i = 0; i < summary.files_written.size(); ++i) {
    out << (i ? "," : "") << json_string(summary.files_written[i]);
  }
  out << "]}";
  return out.str();
}

}  // namespace occgeo::replay
