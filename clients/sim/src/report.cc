#include "occgeo/sim/report.h"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <sstream>
#include "occgeo/client/json.h"

namespace occgeo::sim {

namespace {

// The shortest decimal text that reads back as the same double; JSON has no NaN or infinity, so those become null.
std::string number_text(double value) {
  if (!std::isfinite(value)) return "null";
  std::array<char, 32> buffer{};
  const auto result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  return std::string(buffer.data(), result.ptr);
}

using client::json_string;

}  // namespace

RunSummary summarize(const Simulation& simulation, const std::string& robot_id, const std::string& world_file) {
  const SimulatedRobot& robot = simulation.robot();
  std::vector<RunSummary::Collision> collisions;
  for (std::size_t i = 0; i < robot.collision_events().size(); ++i) {
    collisions.push_back({robot.collision_events()[i],
                          i < simulation.collision_states().size() ? simulation.collision_states()[i] : ""});
  }
  return RunSummary{.robot_id = robot_id,
                    .world_file = world_file,
                    .distance_m = robot.distance_m(),
                    .collisions = robot.collisions(),
                    .collisions_moving = robot.collisions_moving(),
                    .collisions_at_rest = robot.collisions_at_rest(),
                    .collisions_hit_moving = robot.collisions_hit_moving(),
                    .sim_time_s = robot.time_s(),
                    .scans_sent = simulation.scan_count(),
                    .commands_received = simulation.command_count(),
                    .final_pose = robot.pose(),
                    .deadlock_reported = simulation.deadlock_reported(),
                    .last_state = simulation.last_state(),
                    .state_counts = simulation.state_counts(),
                    .messages_sent = simulation.message_counts(),
                    .commands_ignored = simulation.ignored_command_count(),
                    .collision_events = std::move(collisions)};
}

namespace {

// The contacts as a JSON array.
std::string collisions_json(const std::vector<RunSummary::Collision>& collisions) {
  std::string out;
  for (const RunSummary::Collision& c : collisions) {
    if (!out.empty()) out += ", ";
    out += "{\"t_s\": " + number_text(c.event.time_s) + ", \"x\": " + number_text(c.event.X_WB.x) +
           ", \"y\": " + number_text(c.event.X_WB.y) + ", \"theta\": " + number_text(c.event.X_WB.theta) +
           ", \"left_mps\": " + number_text(c.event.wheels.left_mps) +
           ", \"right_mps\": " + number_text(c.event.wheels.right_mps) +
           ", \"moving\": " + (c.event.moving ? "true" : "false") +
           ", \"ran_into_robot\": " + (c.event.ran_into_robot ? "true" : "false") +
           ", \"obstacle\": " + json_string(c.event.obstacle) +
           ", \"state\": " + json_string(c.state.empty() ? "-" : c.state) + "}";
  }
  return out;
}

// "key": count pairs for the JSON summary; an empty key is written as "-".
std::string counts_json(const std::map<std::string, std::uint64_t>& counts) {
  std::string out;
  for (const auto& [state, count] : counts) {
    if (!out.empty()) out += ", ";
    out += json_string(state.empty() ? "-" : state) + ": " + std::to_string(count);
  }
  return out;
}

}  // namespace

std::string to_json(const RunSummary& summary) {
  return "{\"robot\": " + json_string(summary.robot_id) + ", \"world\": " + json_string(summary.world_file) +
         ", \"distance_m\": " + number_text(summary.distance_m) +
         ", \"collisions\": " + std::to_string(summary.collisions) +
         ", \"collisions_moving\": " + std::to_string(summary.collisions_moving) +
         ", \"collisions_at_rest\": " + std::to_string(summary.collisions_at_rest) +
         ", \"collisions_hit_moving\": " + std::to_string(summary.collisions_hit_moving) +
         ", \"sim_time_s\": " + number_text(summary.sim_time_s) +
         ", \"scans_sent\": " + std::to_string(summary.scans_sent) +
         ", \"commands_received\": " + std::to_string(summary.commands_received) +
         ", \"final_pose\": {\"x\": " + number_text(summary.final_pose.x) +
         ", \"y\": " + number_text(summary.final_pose.y) + ", \"theta\": " + number_text(summary.final_pose.theta) +
         "}, \"deadlock_reported\": " + (summary.deadlock_reported ? "true" : "false") +
         ", \"last_state\": " + json_string(summary.last_state) + ", \"state_counts\": {" +
         counts_json(summary.state_counts) + "}, \"messages_sent\": {" + counts_json(summary.messages_sent) +
         "}, \"commands_ignored\": " + std::to_string(summary.commands_ignored) + ", \"collision_events\": [" +
         collisions_json(summary.collision_events) + "]}";
}

std::string to_text(const RunSummary& summary) {
  std::ostringstream text;
  text << std::fixed << "robot " << summary.robot_id << " in " << summary.world_file << '\n'
       << std::setprecision(2) << "  sim time    " << summary.sim_time_s << " s\n"
       << std::setprecision(3) << "  distance    " << summary.distance_m << " m\n"
       << "  collisions  " << summary.collisions << " (" << summary.collisions_moving << " moving, "
       << summary.collisions_at_rest << " hit at rest, " << summary.collisions_hit_moving << " hit while moving)\n";
  for (const RunSummary::Collision& c : summary.collision_events) {
    text << std::setprecision(2) << "    t " << c.event.time_s << " s at (" << c.event.X_WB.x << ", " << c.event.X_WB.y
         << ") wheels " << c.event.wheels.left_mps << " / " << c.event.wheels.right_mps << " m/s, "
         << (!c.event.ran_into_robot ? "ran into "
             : c.event.moving        ? "hit while moving by "
                                     : "hit at rest by ")
         << c.event.obstacle << " (state " << (c.state.empty() ? "-" : c.state) << ")\n";
  }
  text << "  scans sent  " << summary.scans_sent << " sensor messages\n"
       << "  commands    " << summary.commands_received
       << " (last state: " << (summary.last_state.empty() ? "-" : summary.last_state)
       << ", deadlock reported: " << (summary.deadlock_reported ? "yes" : "no") << ")\n"
       << "  final pose  x " << summary.final_pose.x << " m, y " << summary.final_pose.y << " m, theta "
       << std::setprecision(4) << summary.final_pose.theta << " rad\n";
  return text.str();
}

void write_visible_pixels(std::ostream& out, const std::set<Pixel>& pixels) {
  for (const Pixel& pixel : pixels) out << pixel.col << ' ' << pixel.row << '\n';
}

std::string trace_csv_row(double time_s, const geometry::Pose2& X_WB) {
  return number_text(time_s) + "," + number_text(X_WB.x) + "," + number_text(X_WB.y) + "," + number_text(X_WB.theta);
}

}  // namespace occgeo::sim
