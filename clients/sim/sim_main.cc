// occgeo-sim: a simulated robot that connects to occgeod as a driver. This file is the protocol loop only; the
// simulation itself lives in the occgeo_sim library.

#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "occgeo/client/connection.h"
#include "occgeo/proto/labels.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/sim/args.h"
#include "occgeo/sim/messages.h"
#include "occgeo/sim/report.h"
#include "occgeo/sim/run_picture.h"
#include "occgeo/sim/simulation.h"

namespace {

using occgeo::client::ClientError;
using occgeo::client::Connection;
using occgeo::sim::SimOptions;
using occgeo::sim::Simulation;
using SteadyClock = std::chrono::steady_clock;

// Exit codes: 0 after a clean run, 1 for connection, server and lockstep failures, 2 for bad arguments or inputs.
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

// Longest wall time a lockstep run waits for a batch's ScanAck and motion command.
constexpr std::chrono::seconds kLockstepAnswerTimeout{10};
// Longest single wait on the socket, so a signal is noticed promptly.
constexpr std::chrono::milliseconds kReceiveSlice{100};
// Progress lines go to stderr once per this many physics steps (10 sim seconds).
constexpr std::int64_t kProgressEverySteps = 1000;

volatile std::sig_atomic_t g_stop_requested = 0;

extern "C" void request_stop(int /*signal*/) { g_stop_requested = 1; }

// A failure that ends the run with exit code kExitFailure; the message is printed to stderr as it is.
class RunError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Where the per-scan and end-of-run files go; opened before connecting so a bad path fails early.
struct OutputFiles {
  std::optional<std::ofstream> trace;
  std::optional<std::ofstream> visible;
  // The true pose at each scan, kept for --png-out only.
  std::optional<std::vector<occgeo::geometry::Pose2>> trajectory;
};

std::ofstream open_output(const std::filesystem::path& path, const char* flag) {
  std::ofstream out(path);
  if (!out) throw occgeo::sim::ArgsError(std::string(flag) + ": cannot open '" + path.string() + "' for writing");
  return out;
}

// Sends the batch due now (pose message first) and appends the pose to the trace.
occgeo::sim::SensorBatch send_batch(Connection& connection, Simulation& simulation, OutputFiles& files) {
  occgeo::sim::SensorBatch batch = simulation.take_batch();
  for (const occgeo::v1::ClientMessage& message : batch.messages) connection.send(message);
  if (files.trace) {
    *files.trace << occgeo::sim::trace_csv_row(simulation.robot().time_s(), simulation.robot().pose()) << '\n';
  }
  if (files.trajectory) files.trajectory->push_back(simulation.robot().pose());
  return batch;
}

// Throws RunError for a server Error; returns the motion command the message carries, if any.
std::optional<occgeo::v1::MotionCommand> motion_command_in(const occgeo::v1::ServerMessage& message) {
  if (message.has_error()) {
    const occgeo::v1::Error& error = message.error();
    const std::string field = error.field().empty() ? occgeo::v1::ErrorCode_Name(error.code()) : error.field();
    throw RunError("server error: " + field + ": " + error.message());
  }
  if (message.has_motion_command()) return message.motion_command();
  return std::nullopt;
}

// Waits until the server acknowledged the batch's last sensor message and, when the batch holds the steering laser's
// scan, sent the command answering it (applied); either may come first. Older acks and commands are skipped.
void await_answer(Connection& connection, Simulation& simulation, const occgeo::sim::SensorBatch& batch) {
  bool acked = batch.last_sensor_seq == 0;
  bool answered = !batch.steering_scan_seq.has_value();
  const auto deadline = SteadyClock::now() + kLockstepAnswerTimeout;
  while (g_stop_requested == 0 && !(acked && answered)) {
    const auto now = SteadyClock::now();
    if (now >= deadline) {
      const std::string waiting_for =
          !acked ? "no ScanAck for sensor message " + std::to_string(batch.last_sensor_seq)
                 : "no motion command answered scan " + std::to_string(*batch.steering_scan_seq);
      throw RunError("occgeo-sim: lockstep: " + waiting_for + " within " +
                     std::to_string(kLockstepAnswerTimeout.count()) + " s");
    }
    const auto wait = std::min(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now), kReceiveSlice);
    const auto message = connection.receive(wait);
    if (!message) continue;
    if (message->has_scan_ack() && message->scan_ack().seq() == batch.last_sensor_seq) acked = true;
    const auto command = motion_command_in(*message);
    if (command && batch.steering_scan_seq && command->answers_scan_seq() == *batch.steering_scan_seq) {
      simulation.apply_command(*command);
      answered = true;
    }
  }
}

// Applies every command that arrives until the wall-clock deadline of the current physics step.
void receive_until(Connection& connection, Simulation& simulation, SteadyClock::time_point deadline) {
  do {
    const auto wait = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - SteadyClock::now());
    const auto message = connection.receive(std::max(wait, std::chrono::milliseconds(0)));
    if (!message) break;
    if (const auto command = motion_command_in(*message)) simulation.apply_command(*command);
  } while (SteadyClock::now() < deadline);
  std::this_thread::sleep_until(deadline);
}

void log_progress(const Simulation& simulation) {
  const occgeo::sim::SimulatedRobot& robot = simulation.robot();
  std::fprintf(stderr,
               "occgeo-sim: t=%.0f s pose=(%.2f, %.2f, %.3f) distance=%.1f m collisions=%llu sensor messages=%llu "
               "commands=%llu state=%s\n",
               robot.time_s(), robot.pose().x, robot.pose().y, robot.pose().theta, robot.distance_m(),
               static_cast<unsigned long long>(robot.collisions()),
               static_cast<unsigned long long>(simulation.scan_count()),
               static_cast<unsigned long long>(simulation.command_count()),
               simulation.last_state().empty() ? "-" : simulation.last_state().c_str());
}

// --hold: the robot stands at sim time 0 until a client gives it a behaviour other than "stop", so that a lockstep
// run is the same whether its goal came before the simulator started or a while after. Polls the robot's status on a
// query session of its own; throws RunError when nothing was set within `hold_s` wall seconds.
void hold_until_driven(const SimOptions& options, double hold_s) {
  Connection query = Connection::open(options.server);
  occgeo::v1::Hello hello;
  hello.set_protocol_version(occgeo::proto::kProtocolVersion);
  hello.set_role(occgeo::v1::ROLE_QUERY);
  hello.set_client_name("occgeo-sim --hold");
  query.hello(hello);
  const auto deadline =
      SteadyClock::now() + std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(hold_s));
  for (std::uint64_t id = 1; g_stop_requested == 0; ++id) {
    occgeo::v1::ClientMessage request;
    request.mutable_status();
    request.set_request_id(id);
    const occgeo::v1::ServerMessage reply = query.call(request, id);
    for (const occgeo::v1::RobotStatus& robot : reply.status().robots()) {
      if (robot.id() == options.robot_id && robot.behaviour() != occgeo::v1::BEHAVIOUR_UNSPECIFIED &&
          robot.behaviour() != occgeo::v1::BEHAVIOUR_STOP) {
        std::fprintf(stderr, "occgeo-sim: --hold: behaviour %s set, starting\n",
                     occgeo::proto::behaviour_label(robot.behaviour()).c_str());
        return;
      }
    }
    if (SteadyClock::now() >= deadline) {
      throw RunError("occgeo-sim: --hold: no behaviour other than stop was set for robot '" + options.robot_id +
                     "' within " + std::to_string(hold_s) + " s");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

// Connects, introduces the robot, then scans, listens and steps until the duration is reached or a signal arrives.
void run(const SimOptions& options, const occgeo::sim::RobotPreset& preset, Simulation& simulation,
         OutputFiles& files) {
  Connection connection = Connection::open(options.server);
  connection.hello(occgeo::sim::make_driver_hello(options.robot_id, options.world_name));
  occgeo::v1::ClientMessage spec;
  *spec.mutable_robot_spec() = occgeo::sim::make_robot_spec(preset, options.start);
  connection.send(spec);
  if (options.hold_s) hold_until_driven(options, *options.hold_s);

  const std::optional<std::int64_t> last_step =
      options.duration_s ? std::optional(std::llround(*options.duration_s / occgeo::sim::kPhysicsStep_s))
                         : std::nullopt;
  const auto wall_start = SteadyClock::now();
  const auto step_wall = std::chrono::duration<double>(occgeo::sim::kPhysicsStep_s);
  while (g_stop_requested == 0 && (!last_step || simulation.robot().step_count() < *last_step)) {
    if (simulation.batch_due()) {
      const occgeo::sim::SensorBatch batch = send_batch(connection, simulation, files);
      if (options.lockstep) await_answer(connection, simulation, batch);
    }
    if (g_stop_requested != 0) break;
    if (!options.lockstep) {
      const auto step_end = static_cast<double>(simulation.robot().step_count() + 1) * step_wall;
      receive_until(connection, simulation, wall_start + std::chrono::duration_cast<SteadyClock::duration>(step_end));
    }
    simulation.step();
    if (simulation.robot().step_count() % kProgressEverySteps == 0) log_progress(simulation);
  }
  connection.close();
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string_view> args(argv + 1, argv + argc);
  SimOptions options;
  OutputFiles files;
  std::optional<Simulation> simulation;
  occgeo::sim::RobotPreset preset;
  try {
    options = occgeo::sim::parse_args(args);
    if (options.help) {
      std::cout << occgeo::sim::usage();
      return 0;
    }
    preset = occgeo::sim::configured_preset(options);
    std::unique_ptr<occgeo::sim::SimWorld> world = [&] {
      try {
        return occgeo::sim::load_sim_world(options.world_file);
      } catch (const occgeo::sim::WorldError& error) {
        throw occgeo::sim::ArgsError(std::string("--world: ") + error.what());
      }
    }();
    try {
      simulation.emplace(std::move(world), preset, options.start, options.seed);
    } catch (const std::invalid_argument& error) {
      throw occgeo::sim::ArgsError(std::string("--start: ") + error.what());
    }
    simulation->set_command_latency(options.command_latency_s);
    try {
      if (options.drive) simulation->set_drive_script(*options.drive);
    } catch (const std::invalid_argument& error) {
      throw occgeo::sim::ArgsError(std::string("--drive: ") + error.what());
    }
    if (options.trace_out) {
      files.trace = open_output(*options.trace_out, "--trace-out");
      *files.trace << occgeo::sim::kTraceCsvHeader << '\n';
    }
    if (options.visible_out) files.visible = open_output(*options.visible_out, "--visible-out");
    // Opened (and left empty) now so a bad path fails before the run, like the other outputs.
    if (options.png_out) {
      open_output(*options.png_out, "--png-out");
      files.trajectory.emplace();
    }
  } catch (const occgeo::sim::ArgsError& error) {
    std::cerr << "occgeo-sim: " << error.what() << "\nrun 'occgeo-sim --help' for usage\n";
    return kExitUsage;
  }

  std::signal(SIGINT, request_stop);
  std::signal(SIGTERM, request_stop);
  try {
    run(options, preset, *simulation, files);
  } catch (const RunError& error) {
    std::cerr << error.what() << '\n';
    return kExitFailure;
  } catch (const ClientError& error) {
    std::cerr << "occgeo-sim: " << error.what() << '\n';
    return kExitFailure;
  }

  if (files.visible) occgeo::sim::write_visible_pixels(*files.visible, simulation->visible_pixels());
  if (options.png_out) {
    // The pose after the last step too, so the marker shows where the robot stopped.
    files.trajectory->push_back(simulation->robot().pose());
    try {
      occgeo::sim::run_picture(simulation->world(), *files.trajectory, simulation->robot().time_s())
          .write_png(*options.png_out);
    } catch (const std::exception& error) {
      std::cerr << "occgeo-sim: --png-out: " << error.what() << '\n';
      return kExitFailure;
    }
  }
  const auto summary = occgeo::sim::summarize(*simulation, options.robot_id, options.world_file.string());
  std::cout << (options.json ? occgeo::sim::to_json(summary) + "\n" : occgeo::sim::to_text(summary));
  return 0;
}
