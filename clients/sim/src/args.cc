#include "occgeo/sim/args.h"
#include "occgeo/client/cli_options.h"

#include <charconv>
#include <cmath>
#include <set>
#include <variant>

namespace occgeo::sim {

namespace {

// Longest command latency accepted, seconds: beyond this the robot would act on scans older than its own watchdog
// period many times over, which no real robot survives and is more likely a unit mistake (milliseconds for seconds).
constexpr double kMaxCommandLatency_s = 5.0;
static_assert(kPhysicsStep_s == 0.01, "--command-latency's messages name the physics step");

// Flags that take one value.
const std::set<std::string_view> kValueFlags = {
    "--world",           "--robot", "--id",   "--world-name",  "--server",    "--duration", "--start",
    "--laser-range",     "--noise", "--seed", "--visible-out", "--trace-out", "--drive",    "--png-out",
    "--command-latency", "--hold"};

// Every tool words its command-line errors alike: "option '--flag' <problem>", "unknown option '--flag'".
[[noreturn]] void fail(std::string_view flag, const std::string& problem) {
  throw ArgsError("option '" + std::string(flag) + "' " + problem);
}

double parse_number(std::string_view flag, std::string_view text, const std::string& what) {
  const std::optional<double> value = client::finite_number(text);
  if (!value) fail(flag, "needs " + what + ", got '" + std::string(text) + "'");
  return *value;
}

double parse_positive(std::string_view flag, std::string_view text, const std::string& what) {
  const double value = parse_number(flag, text, what);
  if (value <= 0.0) fail(flag, "must be greater than 0, got '" + std::string(text) + "'");
  return value;
}

std::uint64_t parse_seed(std::string_view flag, std::string_view text) {
  std::uint64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size()) {
    fail(flag, "needs a non-negative integer, got '" + std::string(text) + "'");
  }
  return value;
}

geometry::Pose2 parse_pose(std::string_view flag, std::string_view text) {
  const std::string expected = "X,Y,THETA (metres, metres, radians)";
  std::vector<double> values;
  std::size_t begin = 0;
  while (true) {
    const std::size_t comma = text.find(',', begin);
    const std::string_view part = text.substr(begin, comma == std::string_view::npos ? comma : comma - begin);
    values.push_back(parse_number(flag, part, expected + " in '" + std::string(text) + "', a number"));
    if (comma == std::string_view::npos) break;
    begin = comma + 1;
  }
  if (values.size() != 3) fail(flag, "needs " + expected + ", got '" + std::string(text) + "'");
  return {values[0], values[1], values[2]};
}

std::string parse_name(std::string_view flag, std::string_view text) {
  if (text.empty()) fail(flag, "must not be empty");
  return std::string(text);
}

void apply(SimOptions& options, std::string_view flag, std::string_view value) {
  if (flag == "--world") {
    options.world_file = parse_name(flag, value);
  } else if (flag == "--robot") {
    if (find_robot_preset(value) == nullptr) {
      fail(flag, "needs a known robot, got '" + std::string(value) + "' (known: " + robot_preset_names() + ")");
    }
    options.robot = std::string(value);
  } else if (flag == "--id") {
    options.robot_id = parse_name(flag, value);
  } else if (flag == "--world-name") {
    options.world_name = parse_name(flag, value);
  } else if (flag == "--server") {
    try {
      options.server = client::Endpoint::parse(value);
    } catch (const client::ClientError& error) {
      fail(flag, error.what());
    }
  } else if (flag == "--duration") {
    options.duration_s = parse_positive(flag, value, "a duration in seconds");
  } else if (flag == "--start") {
    options.start = parse_pose(flag, value);
  } else if (flag == "--laser-range") {
    options.laser_range_m = parse_positive(flag, value, "a range in metres");
  } else if (flag == "--noise") {
    options.noise_sigma_m = parse_number(flag, value, "a standard deviation in metres");
    if (*options.noise_sigma_m < 0.0) fail(flag, "must not be negative, got '" + std::string(value) + "'");
  } else if (flag == "--command-latency") {
    options.command_latency_s = parse_number(flag, value, "a latency in seconds");
    const double steps = options.command_latency_s / kPhysicsStep_s;
    if (options.command_latency_s < 0.0 || options.command_latency_s > kMaxCommandLatency_s) {
      fail(flag, "must be between 0 and 5 s, got '" + std::string(value) + "'");
    }
    if (std::abs(steps - std::round(steps)) > 1e-9) {
      fail(flag, "must be a whole number of 0.01 s physics steps, got '" + std::string(value) + "'");
    }
  } else if (flag == "--hold") {
    options.hold_s = parse_positive(flag, value, "a wait in seconds");
  } else if (flag == "--seed") {
    options.seed = parse_seed(flag, value);
  } else if (flag == "--visible-out") {
    options.visible_out = parse_name(flag, value);
  } else if (flag == "--trace-out") {
    options.trace_out = parse_name(flag, value);
  } else if (flag == "--png-out") {
    options.png_out = parse_name(flag, value);
  } else if (flag == "--drive") {
    options.drive = parse_drive_script(value);
  }
}

}  // namespace

DriveScript parse_drive_script(std::string_view text) {
  constexpr std::string_view kFlag = "--drive";
  const std::string expected = "V,W,T (m/s, rad/s, s)";
  if (text.empty()) fail(kFlag, "needs segments " + expected + " separated by ';', got nothing");
  DriveScript script;
  std::size_t begin = 0;
  while (begin <= text.size()) {
    const std::size_t semicolon = text.find(';', begin);
    const std::string_view part =
        text.substr(begin, semicolon == std::string_view::npos ? semicolon : semicolon - begin);
    const std::string where = "segment " + std::to_string(script.size() + 1) + " '" + std::string(part) + "'";
    std::vector<double> values;
    std::size_t field_begin = 0;
    while (field_begin <= part.size()) {
      const std::size_t comma = part.find(',', field_begin);
      const std::string_view field =
          part.substr(field_begin, comma == std::string_view::npos ? comma : comma - field_begin);
      values.push_back(parse_number(kFlag, field, expected + " in " + where + ", a number"));
      if (comma == std::string_view::npos) break;
      field_begin = comma + 1;
    }
    if (values.size() != 3) fail(kFlag, where + ": expected " + expected);
    if (values[2] <= 0.0) fail(kFlag, where + ": the duration must be greater than 0 s");
    script.push_back({values[0], values[1], values[2]});
    if (semicolon == std::string_view::npos) break;
    begin = semicolon + 1;
  }
  return script;
}

namespace {

// occgeo-sim's options as one CLI11 app: every value goes through apply(), which words its mistakes; each option may
// be given once.
struct SimCommandLine {
  CLI::App app{"occgeo-sim", "occgeo-sim"};
  std::set<std::string> seen;

  explicit SimCommandLine(SimOptions& options) {
    client::configure_cli(app, options.help);
    for (const std::string_view flag : kValueFlags) {
      const std::string name(flag);
      app.add_option_function<std::string>(name, [this, &options, name](const std::string& value) {
        once(name);
        apply(options, name, value);
      });
    }
    app.add_flag_function("--lockstep", [this, &options](std::int64_t) { once("--lockstep"), options.lockstep = true; })
        ->disable_flag_override();
    app.add_flag_function("--json", [this, &options](std::int64_t) { once("--json"), options.json = true; })
        ->disable_flag_override();
  }

  void once(const std::string& flag) {
    if (!seen.insert(flag).second) fail(flag, "given more than once");
  }
};

}  // namespace

SimOptions parse_args(const std::vector<std::string_view>& args) {
  SimOptions options;
  SimCommandLine line(options);
  // A repeated option is refused rather than the last one winning: two --seed values are a script's mistake.
  line.app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  try {
    client::parse_command_line(line.app, std::vector<std::string>(args.begin(), args.end()));
  } catch (const client::UsageError& error) {
    throw ArgsError(error.what());
  }
  for (const CLI::Option* option : line.app.get_options()) {
    if (option->count() > 1) fail(option->get_name(), "given more than once");
  }
  if (!options.help && options.world_file.empty())
    fail("--world", "is required: a ROS map_server or shape world YAML file");
  return options;
}

std::string usage() {
  return "usage: occgeo-sim --world FILE.yaml [options]\n"
         "\n"
         "A simulated robot that connects to occgeod as a driver: it streams odometry (or wheel encoder ticks)\n"
         "and its sensors' readings and drives by the motion commands it receives (or by --drive).\n"
         "\n"
         "  --world FILE.yaml     ROS map_server world (occupied pixels are obstacles) or shape world (required)\n"
         "  --robot NAME          robot preset: " +
         robot_preset_names() +
         " (default bearcat)\n"
         "  --id ID               robot id (default bearcat-1)\n"
         "  --world-name NAME     server world to map into (default \"default\")\n"
         "  --server HOST:PORT    server address (default 127.0.0.1:7700)\n"
         "  --start X,Y,THETA     start pose in metres and radians (default 0,0,0)\n"
         "  --duration S          sim seconds to run (default: until SIGINT or SIGTERM)\n"
         "  --lockstep            after each batch wait for the ScanAck of its last sensor message (and the command\n"
         "                        answering the steering sensor: first laser, else first range array); run as fast\n"
         "                        as possible\n"
         "  --laser-range M       the first laser's maximum range in metres (default: the preset's, 8 for bearcat)\n"
         "  --noise SIGMA         range noise standard deviation in metres of lasers and servo beams, and of range\n"
         "                        arrays at 1 m (their noise grows with range) (default: each preset's)\n"
         "  --drive V,W,T;...     follow this looped script of body velocities (m/s, rad/s, seconds each) and ignore\n"
         "                        the server's motion commands (how robots the server does not steer move)\n"
         "  --command-latency S   a received motion command takes effect S sim seconds later (a whole number of\n"
         "                        0.01 s physics steps, at most 5): the loop latency of a real robot, which lockstep\n"
         "                        otherwise leaves at zero; the wheels' watchdog counts from when it takes effect\n"
         "                        (default 0)\n"
         "  --hold S              stand at sim time 0, sending nothing after the RobotSpec, until a client sets\n"
         "                        the robot a behaviour other than stop (polled on a query session), at most S wall\n"
         "                        seconds: a lockstep run then starts with its behaviour, whenever that was set\n"
         "  --seed N              noise seed (default 1)\n"
         "  --json                print the summary as one JSON object on stdout\n"
         "  --visible-out FILE    write the obstacle pixels the sensors hit, one \"col row\" line each\n"
         "                        (pixel worlds only; empty for shape worlds)\n"
         "  --trace-out FILE      write the pose at each scan as CSV t,x,y,theta\n"
         "  --png-out FILE        at the end of a clean run, write a PNG of the world (pixel worlds: one picture\n"
         "                        pixel per world pixel; shape worlds: rasterised at 0.05 m) with obstacles black,\n"
         "                        the true trajectory (pose at each scan) red and the final pose a blue triangle\n"
         "  --help                print this help\n";
}

RobotPreset configured_preset(const SimOptions& options) {
  const RobotPreset* named = find_robot_preset(options.robot);
  if (named == nullptr) throw ArgsError("option '--robot' names no known robot: '" + options.robot + "'");
  RobotPreset preset = *named;
  if (options.laser_range_m) {
    LaserPreset* laser = preset.laser();
    if (laser == nullptr)
      throw ArgsError("option '--laser-range' needs a robot with a laser; '" + preset.name + "' has none");
    laser->range_max_m = *options.laser_range_m;
  }
  if (options.noise_sigma_m) {
    const double sigma_m = *options.noise_sigma_m;
    for (SensorPreset& sensor : preset.sensors) {
      if (auto* laser = std::get_if<LaserPreset>(&sensor)) laser->range_noise_sigma_m = sigma_m;
      if (auto* servo = std::get_if<ServoRangePreset>(&sensor)) {
        servo->noise_sigma_near_m = sigma_m;
        servo->noise_sigma_far_m = sigma_m;
      }
      // A range array's noise grows with range: SIGMA is its σ at 1 m.
      if (auto* array = std::get_if<RangeArrayPreset>(&sensor)) array->range_noise_fraction = sigma_m / 1.0;
    }
  }
  return preset;
}

}  // namespace occgeo::sim
