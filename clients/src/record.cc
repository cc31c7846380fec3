#include "occgeo/client/record.h"
#include "occgeo/proto/protocol.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <map>
#include <set>
#include <stdexcept>

#include "occgeo/client/connection.h"
#include "occgeo/client/json.h"
#include "occgeo/client/option_values.h"

namespace occgeo::client {
namespace {

using Clock = std::chrono::steady_clock;

volatile std::sig_atomic_t stop_flag = 0;

void on_stop_signal(int /*signal*/) { request_record_stop(); }

std::string fmt(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.3g", v);
  return buffer;
}

std::string bytes_text(std::uint64_t bytes) {
  if (bytes >= (std::uint64_t{1} << 20)) return fmt(static_cast<double>(bytes) / (1 << 20)) + " MiB";
  if (bytes >= 1024) return fmt(static_cast<double>(bytes) / 1024) + " KiB";
  return std::to_string(bytes) + " B";
}

// The MCAP side of a recording: one protobuf schema per message type, one channel per topic.
class RecordingFile {
 public:
  RecordingFile(const std::filesystem::path& path, McapCompression compression)
      : writer_(path, compression, "occgeo record") {}

  void write(const std::string& topic, const google::protobuf::Message& message, const std::string& world,
             const std::string& robot_id) {
    const std::uint64_t now_ns = static_cast<std::uint64_t>(
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count());
    // Message indexes are kept in write order: a clock stepping back must not reorder them.
    last_ns_ = std::max(last_ns_, now_ns);
    writer_.write_message(channel(topic, *message.GetDescriptor(), world, robot_id), last_ns_, last_ns_,
                          message.SerializeAsString());
  }
  void close() { writer_.close(); }
  [[nodiscard]] std::uint64_t messages() const { return writer_.messages(); }
  [[nodiscard]] std::uint64_t bytes() const { return writer_.bytes(); }

 private:
  std::uint16_t channel(const std::string& topic, const google::protobuf::Descriptor& type, const std::string& world,
                        const std::string& robot_id) {
    if (const auto it = channels_.find(topic); it != channels_.end()) return it->second;
    const std::string name(type.full_name());
    auto schema = schemas_.find(name);
    if (schema == schemas_.end()) {
      schema = schemas_.emplace(name, writer_.add_schema(name, "protobuf", file_descriptor_set(type))).first;
    }
    std::map<std::string, std::string> metadata{{"world", world}};
    if (!robot_id.empty()) metadata["robot_id"] = robot_id;
    return channels_[topic] = writer_.add_channel(schema->second, topic, "protobuf", metadata);
  }

  McapWriter writer_;
  std::map<std::string, std::uint16_t> schemas_;
  std::map<std::string, std::uint16_t> channels_;
  std::uint64_t last_ns_ = 0;
};

// Writes one watch event under /WORLD/ROBOT/...: sensor messages after their placement (pose, changed cells).
void write_event(RecordingFile& file, const v1::WatchEvent& event) {
  const std::string prefix = "/" + event.world() + "/" + event.robot_id() + "/";
  auto put = [&](const std::string& kind, const google::protobuf::Message& message) {
    file.write(prefix + kind, message, event.world(), event.robot_id());
  };
  auto put_sensor = [&](const std::string& kind, const google::protobuf::Message& message) {
    v1::WatchEvent placement = event;
    placement.clear_data();
    placement.clear_dropped_since_last();
    put("placement", placement);
    put(kind, message);
  };
  switch (event.data_case()) {
    case v1::WatchEvent::kRobotSpec:
      put("robot_spec", event.robot_spec());
      break;
    case v1::WatchEvent::kOdometry:
      put("odometry", event.odometry());
      break;
    case v1::WatchEvent::kMotionCommand:
      put("motion_command", event.motion_command());
      break;
    case v1::WatchEvent::kLaserScan:
      put_sensor("laser_scan", event.laser_scan());
      break;
    case v1::WatchEvent::kRangeArray:
      put_sensor("range_array", event.range_array());
      break;
    case v1::WatchEvent::kServoRange:
      put_sensor("servo_range", event.servo_range());
      break;
    case v1::WatchEvent::kPointCloud:
      put_sensor("point_cloud", event.point_cloud());
      break;
    case v1::WatchEvent::DATA_NOT_SET:
      break;
  }
}

// Progress on stderr: redrawn in place at most 4 times a second on a terminal, else a line every 10 s.
class Progress {
 public:
  Progress(std::ostream& err, bool tty) : err_(err), tty_(tty) {}
  void update(const RecordingFile& file, std::uint64_t dropped, bool force = false) {
    const auto now = Clock::now();
    if (!force && now < next_) return;
    next_ = now + (tty_ ? std::chrono::milliseconds(250) : std::chrono::milliseconds(10000));
    err_ << (tty_ ? "\r" : "") << "occgeo record: " << file.messages() << " messages, " << bytes_text(file.bytes())
         << (dropped > 0 ? ", " + std::to_string(dropped) + " dropped by the server" : std::string())
         << (tty_ ? "   " : "\n") << std::flush;
    drawn_ = true;
  }
  void finish() {
    if (tty_ && drawn_) err_ << "\n";
  }

 private:
  std::ostream& err_;
  bool tty_;
  bool drawn_ = false;
  Clock::time_point next_{};
};

double positive_seconds(const std::string& option, const std::string& value) {
  const std::optional<double> number = finite_number(value);
  if (!number || *number <= 0.0) {
    throw std::invalid_argument("option '" + option + "' needs a positive number of seconds, got '" + value + "'");
  }
  return *number;
}

// Follows each recorded world's grid: the union of the cell boxes its sensor messages may have changed, fetched as a
// GridWindowRequest (the whole window first, then only the blocks changed since the version held) at most every
// period, one request in flight per world, and written as /WORLD/grid (occgeo.v1.GridWindowReply). Cells outside the
// union never changed, so the incremental answers over a growing window miss nothing. Queries run on the server's
// query pool: following the map costs ingest nothing.
class GridFollower {
 public:
  explicit GridFollower(double period_s)
      : period_(std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(period_s))) {}

  void note(const v1::WatchEvent& event) {
    if (!event.has_changed_cells() || event.cell_size_m() <= 0.0) return;
    World& world = worlds_[event.world()];
    const auto& box = event.changed_cells();
    if (!world.have_box) {
      world.min_ix = box.min().ix();
      world.min_iy = box.min().iy();
      world.max_ix = box.max().ix();
      world.max_iy = box.max().iy();
      world.have_box = true;
    }
    world.min_ix = std::min(world.min_ix, box.min().ix());
    world.min_iy = std::min(world.min_iy, box.min().iy());
    world.max_ix = std::max(world.max_ix, box.max().ix());
    world.max_iy = std::max(world.max_iy, box.max().iy());
    world.cell_size_m = event.cell_size_m();
    world.dirty = true;
  }

  // Asks for the changes of every world that has some, unless one is in flight or (unless `now`) the period has not
  // passed since the last request.
  void request(Connection& connection, bool now = false) {
    const auto at = Clock::now();
    for (auto& [name, world] : worlds_) {
      if (!world.dirty || world.pending != 0 || world.failed || (!now && at < world.last_request + period_)) continue;
      v1::ClientMessage message;
      auto& window = *message.mutable_grid_window();
      message.set_request_id(next_request_id_);
      window.set_world(name);
      // Cell centres: the window holds exactly the cells of the box.
      window.mutable_min_corner()->set_x((world.min_ix + 0.5) * world.cell_size_m);
      window.mutable_min_corner()->set_y((world.min_iy + 0.5) * world.cell_size_m);
      window.mutable_max_corner()->set_x((world.max_ix + 0.5) * world.cell_size_m);
      window.mutable_max_corner()->set_y((world.max_iy + 0.5) * world.cell_size_m);
      window.set_since_version(world.version);
      connection.send(message);
      world.pending = next_request_id_++;
      world.dirty = false;
      world.last_request = at;
    }
  }

  // Takes a reply or error of one of its requests (true), writing the reply; false for anything else.
  bool take(const v1::ServerMessage& message, RecordingFile& file, std::ostream& err) {
    const std::uint64_t id = reply_request_id(message);
    if (id == 0) return false;
    for (auto& [name, world] : worlds_) {
      if (world.pending != id) continue;
      world.pending = 0;
      if (message.has_grid_window()) {
        world.version = message.grid_window().version();
        file.write("/" + name + "/grid", message.grid_window(), name, "");
      } else if (message.has_error()) {
        world.failed = true;  // e.g. over limits.max_grid_reply_cells: the rest of the recording is still written
        err << "\noccgeo record: the grid of world " << name << " is no longer followed: " << describe(message.error())
            << "\n";
      }
      return true;
    }
    return false;
  }

  [[nodiscard]] bool in_flight() const {
    return std::ranges::any_of(worlds_, [](const auto& entry) { return entry.second.pending != 0; });
  }

 private:
  struct World {
    bool have_box = false;
    std::int32_t min_ix = 0, min_iy = 0, max_ix = 0, max_iy = 0;
    double cell_size_m = 0.0;
    std::uint64_t version = 0;  // of the last answer: the next since_version
    std::uint64_t pending = 0;  // request id in flight, 0: none
    bool dirty = false;
    bool failed = false;
    Clock::time_point last_request{};
  };
  Clock::duration period_;
  std::map<std::string, World> worlds_;
  std::uint64_t next_request_id_ = 2;  // 1 is the WatchRequest
};

}  // namespace

const char* const kRecordUsage = R"(usage: occgeo record --out FILE.mcap [options]
Attaches to occgeod as an observer and records what the server accepts, as MCAP with protobuf schemas (Foxglove
and the MCAP libraries decode them): per robot /WORLD/ROBOT/robot_spec, odometry, laser_scan, range_array,
servo_range, point_cloud (each after a /WORLD/ROBOT/placement: the pose it was placed at and the grid cells it may
have changed) and motion_command, and per world /WORLD/grid: the grid's changes. Stops on Ctrl-C or SIGTERM, or after --duration, and closes the file cleanly.
`occgeo replay --format mcap FILE.mcap` streams a recording back into a server.
  --out FILE.mcap      the file to write (replaced if it exists)
  --robot ID           record only this robot (default: every robot)
  --world W            record only this world (default: every world)
  --duration S         stop after S seconds
  --compression C      chunk compression: zstd (default), lz4 or none
  --grid-period S      how often the grid's changes are fetched and written as /WORLD/grid (occgeo.v1.GridWindowReply:
                       the whole window of changed cells first, then the blocks changed since), default 1; the last
                       are fetched when recording stops
  --token T            the observer token (needed beyond loopback when the server sets one)
  --server HOST:PORT   server address (default 127.0.0.1:7700)
  --json               print a summary (file, messages, bytes, dropped, duration_s) as JSON on stdout
Progress (messages written, bytes) goes to stderr.
)";

void request_record_stop() { stop_flag = 1; }

RecordOptions parse_record_args(const std::vector<std::string>& args) {
  RecordOptions options;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& option = args[i];
    if (option == "--json") {
      options.json = true;
      continue;
    }
    if (i + 1 >= args.size()) throw std::invalid_argument("option '" + option + "' needs a value");
    const std::string& value = args[++i];
    if (option == "--out") {
      options.out = value;
    } else if (option == "--robot") {
      options.robot_id = value;
    } else if (option == "--world") {
      options.world = value;
    } else if (option == "--duration") {
      options.duration_s = positive_seconds(option, value);
    } else if (option == "--compression") {
      options.compression = parse_mcap_compression(value);
    } else if (option == "--grid-period") {
      options.grid_period_s = positive_seconds(option, value);
    } else if (option == "--token") {
      options.token = value;
    } else if (option == "--server") {
      options.server = value;
    } else {
      throw std::invalid_argument("unknown option '" + option + "'");
    }
  }
  if (options.out.empty()) throw std::invalid_argument("--out FILE.mcap is required");
  return options;
}

RecordSummary run_record(const RecordOptions& options, std::ostream& err) {
  auto connection = Connection::open(Endpoint::parse(options.server));
  v1::Hello hello;
  hello.set_protocol_version(occgeo::proto::kProtocolVersion);
  hello.set_role(v1::ROLE_OBSERVER);
  hello.set_client_name("occgeo-record");
  hello.set_auth_token(options.token);
  connection.hello(hello);
  v1::ClientMessage watch;
  watch.mutable_watch();
  watch.set_request_id(1);
  watch.mutable_watch()->set_world(options.world);
  watch.mutable_watch()->set_robot_id(options.robot_id);
  watch.mutable_watch()->set_with_data(true);
  // Opened only once the server agreed, so a refusal leaves no empty file behind.
  connection.call(watch, 1);
  RecordingFile file(options.out, options.compression);
  err << "occgeo record: recording " << (options.robot_id.empty() ? "every robot" : "robot " + options.robot_id)
      << (options.world.empty() ? "" : " of world " + options.world) << " to " << options.out.string()
      << " (Ctrl-C stops)\n";

  RecordSummary summary;
  Progress progress(err, ::isatty(STDERR_FILENO) == 1 && &err == &std::cerr);
  const auto start = Clock::now();
  const auto end =
      options.duration_s
          ? start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(*options.duration_s))
          : Clock::time_point::max();
  GridFollower grid(options.grid_period_s);
  auto handle = [&](const v1::ServerMessage& message) {
    if (message.has_watch_event()) {
      const v1::WatchEvent& event = message.watch_event();
      if (event.dropped_since_last() > 0) {
        if (summary.dropped == 0) {
          err << "\noccgeo record: the server is dropping events because this recorder reads too slowly; the "
                 "recording has gaps\n";
        }
        summary.dropped += event.dropped_since_last();
      }
      write_event(file, event);
      grid.note(event);
    } else if (!grid.take(message, file, err) && message.has_error()) {
      err << "occgeo record: server error: " << describe(message.error()) << "\n";
    }
  };
  try {
    while (stop_flag == 0 && Clock::now() < end) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - Clock::now());
      const auto message =
          connection.receive(std::clamp(left, std::chrono::milliseconds(1), std::chrono::milliseconds(200)));
      if (message) handle(*message);
      grid.request(connection);
      progress.update(file, summary.dropped);
    }
    // The grid as it stands when recording stops: the last changes, bounded in time.
    const auto last = Clock::now() + std::chrono::seconds(10);
    grid.request(connection, true);
    while (grid.in_flight() && Clock::now() < last) {
      if (const auto message = connection.receive(std::chrono::milliseconds(200))) handle(*message);
    }
  } catch (const ClientError&) {
    file.close();
    progress.finish();
    throw;
  }
  file.close();
  progress.update(file, summary.dropped, true);
  progress.finish();
  summary.messages = file.messages();
  summary.bytes = file.bytes();
  summary.duration_s = std::chrono::duration<double>(Clock::now() - start).count();
  return summary;
}

int run_record_cli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  RecordOptions options;
  try {
    options = parse_record_args(args);
  } catch (const std::invalid_argument& e) {
    err << "occgeo record: " << e.what() << "\nrun 'occgeo record --help' for usage\n";
    return 2;
  }
  stop_flag = 0;
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
  try {
    const RecordSummary summary = run_record(options, err);
    err << "occgeo record: wrote " << summary.messages << " messages (" << bytes_text(summary.bytes) << ") to "
        << options.out.string() << " in " << fmt(summary.duration_s) << " s";
    if (summary.dropped > 0) {
      err << "; the server dropped " << summary.dropped
          << " events because the recorder read too slowly (the recording has gaps)";
    }
    err << "\n";
    if (options.json) {
      out << "{\"file\":" << json_string(options.out.string()) << ",\"messages\":" << summary.messages
          << ",\"bytes\":" << summary.bytes << ",\"dropped\":" << summary.dropped
          << ",\"duration_s\":" << fmt(summary.duration_s) << "}\n";
    }
    return 0;
  } catch (const std::exception& e) {
    err << "occgeo record: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace occgeo::client
