// occgeo: command-line client for occgeod. This file is its command line (commands, options, help); the commands
// themselves (cli_commands.h) are in cli_queries.cc, cli_maps.cc and cli_robot.cc.
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "cli_commands.h"
#include "occgeo/client/cli_options.h"
#include "occgeo/client/record.h"
#include "occgeo/replay/replay.h"

namespace {

using namespace occgeo::cli;

constexpr const char* kUsage = R"(usage: occgeo [--server HOST:PORT] [--json] COMMAND [options]
commands:
  status [--detailed]                        robots, worlds and clients of the server (--detailed: also
                                             each robot's planned path and latest laser returns)
  query collision --robot ID --x X --y Y [--theta T] [--models grid,octomap,ptem] [--footprint SHAPE]
                                             is the robot's footprint at this pose in collision?
  query clearance --robot ID --x X --y Y [--theta T] [--max-distance D] [--models grid,octomap,ptem]
                                             distance from the footprint to the nearest obstacle
                                             (--models: which of the world's models; default all three;
                                             --footprint: use this footprint instead of the robot's, in
                                             base_link, metres: box:LENGTH,WIDTH,HEIGHT[,CENTER_X],
                                             cylinder:RADIUS,HEIGHT or polygon:HEIGHT:X1,Y1:X2,Y2:X3,Y3...
                                             (a convex outline, either winding); also for clearance, swept)
  query ptem --world W --x X --y Y           the PTEM's threat, gradient and restricted flag at a point
  query raycast --x X --y Y --theta T --max-range R [--world W] [--models ...]
                                             range along a ray and what it hit, per model
  query occupancy --x X --y Y [--z Z] [--world W] [--models ...]
                                             grid certainty, octree probability and PTEM threat at a point
  query swept --robot ID --x X --y Y [--theta T] --v V --w W --duration S [--models ...]
                                             does the footprint moving at (v, w) for S seconds touch
                                             anything, and when first?
  query window --min-x X0 --min-y Y0 --max-x X1 --max-y Y1 [--world W] [--since VERSION]
                                             a grid window as certainty values (or its changes since a version)
  map export [--format pgm|png|bt] --world W --out PREFIX [--ptem] [--trajectory FILE.csv] [--scale N]
                                             pgm (default): the world's grid as PREFIX.pgm + PREFIX.yaml
                                             (ROS map_server format); bt: its OctoMap as PREFIX.bt;
                                             png: a picture of the grid as PREFIX.png only (white free,
                                             black occupied, mid-grey unknown; less certain cells greyer), each
                                             cell N x N pixels (--scale, default 1, at most 16), with
                                             the world's PTEM clusters (--ptem: magenta circles, orange
                                             restricted discs) and a trajectory (--trajectory: red line
                                             and blue final pose; occgeo-sim --trace-out's CSV) drawn on it
  cloud insert FILE.pcd --pose x,y,z,roll,pitch,yaw --world W [--robot ID]
                                             send a .pcd point cloud taken by a sensor at that pose
                                             (world frame) into the world's maps, as driver robot ID
                                             (default occgeo-cli-cloud, left registered and offline)
  lease acquire|retain|return|take --robot ID [--timeout S] [--token T]
                                             one lease request as a controller (take needs the operator token)
  drive --robot ID bearcat|bearcat_seed|wander|stop|teleop [--v V --w W] [--hold S] [--timeout S] [--token T]
                                             acquire the robot's lease, set its behaviour (teleop: V m/s,
                                             W rad/s), keep the lease S seconds (default 0) with retains, return it
  goto --robot ID X Y [--no-escape] [--limit S] [--timeout S] [--token T]
                                             drive the robot to (X, Y) with PointBug, holding the lease
                                             until it reports reached or no_path (or --limit S wall
                                             seconds, default 600, or Ctrl-C), printing progress;
                                             a stall or loop follows a global path over the map
                                             unless --no-escape
  waypoints --robot ID X1,Y1 X2,Y2 ... [--no-escape] [--limit S] [--timeout S] [--token T]
                                             the same along waypoints with PTEM guidance
  estop --robot ID [--release] [--token T]   engage the robot's e-stop (as an observer); --release frees it
                                             (as a controller: acquires the lease, releases, returns it)
  replay --format carmen|dpslam|urg|mcap FILE [--max | --speed X] [--consistency] [--out PREFIX] [--json] ...
                                             stream a recorded laser log or ROS 2 bag as a driver
                                             (occgeo replay --help)
  record --out FILE.mcap [--robot ID] [--world W] [--duration S] [--compression zstd|lz4|none]
                                             record what the server accepts as MCAP until Ctrl-C
                                             (occgeo record --help)
common options (before or after the command):
  --server HOST:PORT   server address (default 127.0.0.1:7700)
  --token T            the operator token (lease, drive, goto, waypoints, estop)
  --json               print the reply as one JSON object
  --name=VALUE works as well as --name VALUE.
Units: metres and radians; poses are base_link in the world frame.
)";

// The command line as CLI11 declares it: the common options (--server, --token, --json) on the tool, before or after
// the command words (each command falls through to them); each command's own options and bare words on it.
struct CommandLine {
  CLI::App app{"occgeo: command-line client for occgeod", "occgeo"};
  Options options;
  std::vector<std::string> words;  // the chosen command's bare words (drive's behaviour, goto's goal, a .pcd file)
  bool help = false;

  CommandLine() {
    occgeo::client::configure_cli(app, help);
    value(app, "server");
    value(app, "token");
    app.add_flag_callback("--json", [this] { options.json = true; });
  }

  // An option taking a value; the numeric ones are checked as they are read, before anything is sent.
  void value(CLI::App& command, const std::string& name) {
    static const std::set<std::string> numbers = {"x",     "y",    "z",        "theta", "max-distance", "max-range",
                                                  "v",     "w",    "duration", "min-x", "min-y",        "max-x",
                                                  "max-y", "hold", "timeout",  "limit"};
    command.add_option_function<std::string>("--" + name, [this, name](const std::string& text) {
      if (numbers.contains(name) && !finite_number(text)) {
        throw UsageError("option '--" + name + "' needs a number, got '" + text + "'");
      }
      options.values[name] = text;
    });
  }

  CLI::App* command(CLI::App& parent, const std::string& name, const std::vector<std::string>& values = {},
                    const std::vector<std::string>& switches = {}, bool takes_words = false) {
    CLI::App* sub = parent.add_subcommand(name);
    sub->fallthrough();
    sub->allow_extras();
    for (const std::string& option : values) value(*sub, option);
    for (const std::string& flag : switches) {
      sub->add_flag_callback("--" + flag, [this, flag] { options.switches.insert(flag); });
    }
    if (takes_words) sub->add_option("WORDS", words);
    return sub;
  }
};

// The command's name as typed, e.g. "query collision", from the chain of parsed subcommands.
std::string command_path(const CLI::App& app) {
  std::string path;
  for (const CLI::App* at = &app; !at->get_subcommands().empty();) {
    at = at->get_subcommands().front();
    path += (path.empty() ? "" : " ") + at->get_name();
  }
  return path;
}

// `occgeo replay|record ...` hands its words to that tool's own parser, with the common options given before it.
std::vector<std::string> passed_on(const CLI::App& app, const CLI::App& command, const Options& options) {
  std::vector<std::string> args = command.remaining();
  if (app.count("--server") > 0) args.insert(args.end(), {"--server", options.text("server")});
  if (app.count("--json") > 0) args.emplace_back("--json");
  return args;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::vector<std::string> args(argv + 1, argv + argc);
    if (args.empty()) {
      std::fputs(kUsage, stderr);
      return 2;
    }
    CommandLine line;
    CLI::App& app = line.app;
    const auto query = [&](const std::string& name, const std::vector<std::string>& values) {
      return line.command(*app.get_subcommand("query"), name, values);
    };
    line.command(app, "help");
    line.command(app, "status", {}, {"detailed"});
    line.command(app, "query");
    query("collision", {"robot", "x", "y", "theta", "models", "footprint"});
    query("clearance", {"robot", "x", "y", "theta", "max-distance", "models", "footprint"});
    query("raycast", {"world", "x", "y", "theta", "max-range", "models"});
    query("occupancy", {"world", "x", "y", "z", "models"});
    query("swept", {"robot", "x", "y", "theta", "v", "w", "duration", "models", "footprint"});
    query("window", {"world", "min-x", "min-y", "max-x", "max-y", "since"});
    query("ptem", {"world", "x", "y"});
    line.command(*line.command(app, "map"), "export", {"world", "out", "format", "trajectory", "scale"}, {"ptem"});
    line.command(*line.command(app, "cloud"), "insert", {"pose", "world", "robot"}, {}, true);
    line.command(app, "lease", {"robot", "timeout"}, {}, true);
    line.command(app, "drive", {"robot", "v", "w", "hold", "timeout"}, {}, true);
    line.command(app, "goto", {"robot", "limit", "timeout"}, {"no-escape"}, true);
    line.command(app, "waypoints", {"robot", "limit", "timeout"}, {"no-escape"}, true);
    line.command(app, "estop", {"robot"}, {"release"});
    // replay and record parse their own options (shared with their library entry points).
    app.add_subcommand("replay")->prefix_command();
    app.add_subcommand("record")->prefix_command();

    occgeo::client::parse_cli_args(app, args);
    const std::string command = command_path(app);
    if (command == "replay" || command == "record") {
      const CLI::App& tool = *app.get_subcommand(command);
      const std::vector<std::string> rest = passed_on(app, tool, line.options);
      if (!rest.empty() && (rest[0] == "--help" || rest[0] == "-h")) {
        std::fputs(command == "replay" ? occgeo::replay::kReplayUsage : occgeo::client::kRecordUsage, stdout);
        return 0;
      }
      return command == "replay" ? occgeo::replay::run_cli(rest, std::cout, std::cerr)
                                 : occgeo::client::run_record_cli(rest, std::cout, std::cerr);
    }
    if (line.help || command == "help") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    const std::vector<std::string> extras = app.remaining(true);
    if ((command.empty() || command == "query" || command == "map" || command == "cloud") && !extras.empty() &&
        extras[0].rfind("-", 0) != 0) {
      throw UsageError("unknown command '" + (command.empty() ? "" : command + " ") + extras[0] + "'");
    }
    occgeo::client::refuse_extras(app);
    const Options& options = line.options;
    const std::vector<std::string>& words = line.words;
    if (command.empty()) throw UsageError("no command after the common options");
    if (command == "status") return run_status(options);
    if (command == "lease") {
      if (words.empty()) throw UsageError("lease needs acquire, retain, return or take");
      if (words.size() > 1) throw UsageError("unexpected argument '" + words[1] + "'");
      return run_lease(words[0], options);
    }
    if (command == "drive") return run_drive(words, options);
    if (command == "goto" || command == "waypoints") return run_goto(command == "waypoints", words, options);
    if (command == "estop") return run_estop(options);
    if (command == "query collision") return run_query_collision(options);
    if (command == "query clearance") return run_query_clearance(options);
    if (command == "query raycast") return run_query_raycast(options);
    if (command == "query occupancy") return run_query_occupancy(options);
    if (command == "query swept") return run_query_swept(options);
    if (command == "query window") return run_query_window(options);
    if (command == "query ptem") return run_query_ptem(options);
    if (command == "map export") return run_map_export(options);
    if (command == "cloud insert") {
      if (words.empty()) throw UsageError("cloud insert needs a FILE.pcd");
      if (words.size() > 1) throw UsageError("unexpected argument '" + words[1] + "'");
      return run_cloud_insert(words[0], options);
    }
    throw UsageError("unknown command '" + command + "'");
  } catch (const UsageError& e) {
    std::cerr << "occgeo: " << e.what() << "\nrun 'occgeo --help' for usage\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "occgeo: " << e.what() << "\n";
    return 1;
  }
}
