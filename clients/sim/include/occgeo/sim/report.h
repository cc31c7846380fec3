#pragma once

#include <cstdint>
#include <map>
#include <ostream>
#include <set>
#include <string>
#include <vector>

#include "occgeo/geometry/pose.h"
#include "occgeo/sim/simulation.h"
#include "occgeo/sim/world.h"

namespace occgeo::sim {

// What a run did, printed on exit.
struct RunSummary {
  std::string robot_id;
  std::string world_file;
  double distance_m = 0.0;                             // path length driven, metres
  std::uint64_t collisions = 0;                        // contacts with obstacles, both kinds below
  std::uint64_t collisions_moving = 0;                 // the robot, moving, ran into an obstacle
  std::uint64_t collisions_at_rest = 0;                // a moving obstacle ran into the robot standing still
  std::uint64_t collisions_hit_moving = 0;             // a moving obstacle ran into the robot while its wheels turned
  double sim_time_s = 0.0;                             // sim time simulated, seconds
  std::uint64_t scans_sent = 0;                        // sensor messages of every kind
  std::uint64_t commands_received = 0;                 // motion commands applied
  geometry::Pose2 final_pose;                          // true base_link pose at the end
  bool deadlock_reported = false;                      // any command's behaviour state was "deadlock"
  std::string last_state;                              // behaviour state of the last command
  std::map<std::string, std::uint64_t> state_counts;   // applied commands per behaviour state
  std::map<std::string, std::uint64_t> messages_sent;  // messages per kind (odometry, laser_scan, range_array, ...)
  std::uint64_t commands_ignored = 0;                  // motion commands not applied because --drive steered
  // The first contacts, in order (SimulatedRobot::collision_events), each with the behaviour state then in effect.
  struct Collision {
    SimulatedRobot::CollisionEvent event;
    std::string state;
  };
  std::vector<Collision> collision_events;
};

// The summary of a simulation run for the robot and world file given.
RunSummary summarize(const Simulation& simulation, const std::string& robot_id, const std::string& world_file);

// One JSON object on one line: robot, world, distance_m, collisions, sim_time_s, scans_sent, commands_received,
// final_pose {x, y, theta}, deadlock_reported, last_state, state_counts {state: commands}, messages_sent {kind: count},
// commands_ignored, collisions_hit_moving, collision_events [{t_s, x, y, theta, left_mps, right_mps, moving,
// ran_into_robot, obstacle, state}].
std::string to_json(const RunSummary& summary);

// A few lines for people.
std::string to_text(const RunSummary& summary);

// Writes one "col row" line per pixel, in order.
void write_visible_pixels(std::ostream& out, const std::set<Pixel>& pixels);

// The first line of the trace CSV.
inline constexpr const char* kTraceCsvHeader = "t,x,y,theta";

// One trace CSV line: sim time in seconds and the base_link pose (metres, radians).
std::string trace_csv_row(double time_s, const geometry::Pose2& X_WB);

}  // namespace occgeo::sim
