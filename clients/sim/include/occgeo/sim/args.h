#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "occgeo/client/connection.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/simulation.h"

namespace occgeo::sim {

// Everything occgeo-sim is told on its command line.
struct SimOptions {
  std::filesystem::path world_file;     // --world FILE.yaml: the ROS map_server world (required)
  std::string robot = "bearcat";        // --robot NAME: a robot preset
  std::string robot_id = "bearcat-1";   // --id ID: the robot id sent in the hello
  std::string world_name = "default";   // --world-name NAME: the server world the robot maps into
  client::Endpoint server;              // --server HOST:PORT
  bool lockstep = false;                // --lockstep: wait for each scan's command, run as fast as possible
  std::optional<double> duration_s;     // --duration S: sim seconds to run; unset runs until a signal
  geometry::Pose2 start;                // --start X,Y,THETA: base_link start pose, metres and radians
  std::optional<double> laser_range_m;  // --laser-range M: overrides the preset laser's range_max, metres
  std::optional<double> noise_sigma_m;  // --noise SIGMA: overrides the preset's range noise, metres (see usage())
  std::optional<DriveScript> drive;     // --drive V,W,T;...: a looped body-velocity script the robot follows itself
  std::uint64_t seed = 1;               // --seed N: seeds the range noise
  double command_latency_s = 0.0;       // --command-latency S: sim seconds from a command's receipt to its effect
  std::optional<double> hold_s;         // --hold S: wait up to S wall seconds at sim time 0 for a behaviour
  bool json = false;                    // --json: print the summary as one JSON object
  std::optional<std::filesystem::path> visible_out;  // --visible-out FILE: obstacle pixels the beams hit
  std::optional<std::filesystem::path> trace_out;    // --trace-out FILE: CSV of t,x,y,theta at each scan
  std::optional<std::filesystem::path> png_out;      // --png-out FILE: picture of the world and the true trajectory
  bool help = false;                                 // --help, -h: print usage and exit
};

// A command-line mistake; the message starts with the flag at fault, e.g. "--duration: ...".
class ArgsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Parses the arguments after the program name ("--flag value" or "--flag=value"); throws ArgsError.
SimOptions parse_args(const std::vector<std::string_view>& args);

// The text --help prints.
std::string usage();

// Parses a --drive script "V,W,T;V,W,T;...": forward speed m/s, yaw rate rad/s, duration s per segment. Throws
// ArgsError starting "--drive: " and naming the segment at fault.
DriveScript parse_drive_script(std::string_view text);

// The preset the options name, with --laser-range (the first laser's range) and --noise (every sensor's noise: σ of
// lasers and servo beams, σ at 1 m of range arrays, whose noise grows with range) applied. Throws ArgsError naming
// --laser-range when the preset has no laser.
RobotPreset configured_preset(const SimOptions& options);

}  // namespace occgeo::sim
