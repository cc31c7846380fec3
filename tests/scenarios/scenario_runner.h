#pragma once

// Runs one simulated scenario against the real server in lockstep: occgeod, occgeo-sim with a robot preset in a
// shipped world, and a controller session that takes the robot's lease and sets its behaviour before the simulator
// connects (so the run is a function of the scenario alone); then measures the run from the simulator's ground truth
// (collisions, the true trajectory) and compares its path with the shortest any-angle path on the true world.

#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace occgeo::testing {

struct Scenario {
  std::string name;
  std::string world;                       // file under clients/sim/worlds/, or an absolute path
  std::string preset;                      // occgeo-sim --robot
  std::string start;                       // occgeo-sim --start X,Y,THETA
  std::string behaviour;                   // DriveRequest.behaviour: bearcat | wander | goto | teleop
  std::optional<Eigen::Vector2d> goal;     // goto's goal (waypoints: the last one), world frame, metres
  std::vector<Eigen::Vector2d> waypoints;  // waypoints' list, world frame, metres
  bool escape = true;                      // deadlock escape on (the full stack) or off (the seed's behaviour alone)
  double teleop_linear_mps = 0.0;
  double teleop_angular_radps = 0.0;
  double duration_s = 60.0;  // sim seconds
  std::string extra_config;  // YAML appended to the server's configuration (e.g. a guard: section)
  // The octree is published after every this many sensor messages (counted, not timed, so lockstep runs repeat). Its
  // deep copy grows with the world seen: about 80 ms on the open field, so large worlds publish less often (the guard
  // checks the grid, fed by the same laser, after every message).
  int octomap_publish_every_messages = 10;
  double goal_tolerance_m = 0.3;
  // occgeo-sim --command-latency: sim seconds between the server's command and its effect on the wheels (0: none).
  double command_latency_s = 0.0;
  std::string note;           // printed with the table: what the scenario shows
  double max_wall_s = 240.0;  // the run is abandoned (did not run) after this much wall time, seconds
  // When set, the behaviour is given this many wall seconds after the simulator connected (which stands at sim time 0
  // with --hold until then), as a user typing `occgeo goto` does, instead of before it connects.
  std::optional<double> drive_after_start_s;
};

struct ScenarioResult {
  std::string name;
  bool ran = false;                 // the server, the simulator and the controller all worked
  std::string failure;              // why it did not run, when it did not
  std::optional<bool> reached;      // set when the scenario has a goal
  int collisions = -1;              // ground truth, whole run
  int collisions_moving = -1;       // of those, begun while the robot moved (it ran into something)
  int collisions_at_rest = -1;      // and while it stood (a moving obstacle ran into it)
  int collisions_hit_moving = -1;   // and while it moved, a moving obstacle coming into where it stood
  double path_m = 0.0;              // true trajectory length until the goal was reached (or the run ended)
  std::optional<double> optimal_m;  // shortest any-angle path to the goal's tolerance circle, when there is a goal
  std::optional<double> lattice_m;  // shortest 8-connected path on a 0.05 m lattice to the goal's cell (for comparison)
  double sim_s = 0.0;               // sim time from the first motion until the goal was reached (or the run ended)
  double wall_s = 0.0;              // wall time of the whole run
  std::string last_state;           // the behaviour's last state as the simulator received it
  std::string collision_events;     // the simulator's first contacts (JSON objects, one per line), for a person
  Eigen::Vector3d final_pose = Eigen::Vector3d::Zero();  // x, y, theta of the last trace row
  // The true pose at every batch the simulator sent: sim time (s), x, y (m, world frame), theta (rad). Two lockstep
  // runs of one scenario must give the same rows.
  std::vector<Eigen::Vector4d> trace;
  [[nodiscard]] std::optional<double> ratio() const {
    if (!optimal_m || *optimal_m <= 0.0 || !reached || !*reached) return std::nullopt;
    return path_m / *optimal_m;
  }
};

// A scenario's world file: under clients/sim/worlds/ unless the name is an absolute path.
std::filesystem::path world_path(const std::string& world);

// Runs the scenario; every wait is bounded. picture_dir, when set, receives NAME.png of the true trajectory.
ScenarioResult run_scenario(const Scenario& scenario, const std::optional<std::string>& picture_dir);

// The first trace row where the two runs differ (or where one ends), if any.
std::optional<std::size_t> first_trace_difference(const ScenarioResult& a, const ScenarioResult& b);

// One table of every result: scenario, reached, collisions, path, optimal, ratio, sim time, wall time, last state.
std::string results_table(const std::vector<Scenario>& scenarios, const std::vector<ScenarioResult>& results);

struct OptimalPath {
  // Theta* on a 0.05 m lattice over the true static world (moving obstacles left out), for the disc of the preset's
  // inscribed radius, from start to the goal's tolerance circle: a lower bound for the robot's own path up to the
  // lattice's numeric error. The table's reference.
  std::optional<double> any_angle_m;
  // 8-connected lattice path for the disc of half the preset's width, to the goal's cell: bent to the lattice and
  // ending at the goal itself, so not comparable with a path that stops at the tolerance circle; printed alongside.
  std::optional<double> lattice_m;
};

std::optional<OptimalPath> optimal_path_length(const std::string& world_file, const std::string& preset,
                                               const Eigen::Vector2d& start, const Eigen::Vector2d& goal,
                                               double goal_tolerance_m);

}  // namespace occgeo::testing
