// Server + simulated Bearcat in lockstep on the open-field world: the robot must drive without
// touching anything, and the map the server builds must match what its laser could see.
#include <gtest/gtest.h>

#include "../support/json_fields.h"
#include "../support/map_score.h"
#include "../support/process.h"

namespace occgeo::testing {
namespace {

// Avoidance states of the Bearcat behaviour: any of them means the robot steered around something.
const std::vector<std::string> kAvoidanceStates = {"avoid_right_obstacle", "avoid_left_obstacle", "steer_gap",
                                                   "pass_between", "no_gap"};

TEST(DriveOpenField, BearcatWandersTwoMinutesWithoutCollisionAndMapsWhatItSaw) {
  TempDir dir;
  ServerProcess server(dir.path());
  const auto world_yaml = source("clients/sim/worlds/open_field.yaml");
  const WorldTruth truth(mapfile::read_map_yaml(world_yaml));
  CellSet visible;

  // Four headings from the origin whose straight lines run into obstacles; each robot maps into
  // the same world, one after the other.
  const std::vector<std::string> headings = {"2.8", "0.5", "-0.8", "-2.4"};
  for (std::size_t i = 0; i < headings.size(); ++i) {
    const std::string id = "bearcat-" + std::to_string(i + 1);
    const auto visible_file = dir.path() / ("visible-" + id + ".txt");
    const ProcessResult sim =
        run_process({binary("clients/sim/occgeo-sim").string(), "--server", server.address(), "--robot", "bearcat",
                     "--world", world_yaml.string(), "--start", "0,0," + headings[i], "--id", id, "--lockstep",
                     "--duration", "120", "--json", "--visible-out", visible_file.string()},
                    std::chrono::seconds(240));
    ASSERT_FALSE(sim.timed_out) << sim.err;
    ASSERT_EQ(sim.exit_code, 0) << sim.err << "\nserver log:\n" << server.log();
    std::cout << id << ": " << sim.out;

    EXPECT_EQ(json_number(sim.out, "collisions"), 0) << sim.out;
    EXPECT_GE(json_number(sim.out, "distance_m"), 20.0) << sim.out;
    EXPECT_NEAR(json_number(sim.out, "sim_time_s"), 120.0, 0.2) << sim.out;
    double avoiding = 0;
    for (const auto& state : kAvoidanceStates) {
      if (sim.out.find("\"" + state + "\"") != std::string::npos) avoiding += json_number(sim.out, state);
    }
    EXPECT_GT(avoiding, 0) << "the robot should have had to steer around something: " << sim.out;
    const auto seen = read_visible_cells(visible_file, truth);
    visible.insert(seen.begin(), seen.end());
  }

  // Export the server's grid with the CLI, as a user would.
  const auto prefix = dir.path() / "exported";
  const ProcessResult exported =
      run_process({binary("clients/occgeo").string(), "map", "export", "--server", server.address(), "--world",
                   "default", "--out", prefix.string(), "--json"},
                  std::chrono::seconds(60));
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  const auto map = mapfile::read_map_yaml(prefix.string() + ".yaml");
  const auto marked = occupied_cells(map);
  ASSERT_GT(visible.size(), 100U) << "the laser should have seen many obstacle cells";
  const MapScore score = score_map(visible, map, truth);
  std::cout << "map: " << score.describe() << '\n';
  EXPECT_GE(score.recall(), 0.90);
  EXPECT_LT(score.false_rate(), 0.02);
  EXPECT_LT(score.observed_false_rate(), 0.02);

  // The CLI's collision query: inside an obstacle the robot mapped says hit, its start pose is free.
  std::optional<std::pair<int, int>> mapped_obstacle;
  for (const auto& cell : visible) {
    if (marked.contains(cell)) {
      mapped_obstacle = cell;
      break;
    }
  }
  ASSERT_TRUE(mapped_obstacle);
  const double cell = truth.cell_size();
  const auto query = [&](double x, double y) {
    return run_process(
        {binary("clients/occgeo").string(), "query", "collision", "--server", server.address(), "--robot", "bearcat-1",
         "--x", std::to_string(x), "--y", std::to_string(y), "--theta", "0.3", "--json"},
        std::chrono::seconds(30));
  };
  const ProcessResult inside = query((mapped_obstacle->first + 0.5) * cell, (mapped_obstacle->second + 0.5) * cell);
  ASSERT_EQ(inside.exit_code, 0) << inside.err;
  EXPECT_TRUE(json_bool(inside.out, "hit")) << inside.out;
  const ProcessResult start = query(0.0, 0.0);
  ASSERT_EQ(start.exit_code, 0) << start.err;
  EXPECT_FALSE(json_bool(start.out, "hit")) << start.out;

  EXPECT_EQ(server.stop(), 0);
  EXPECT_TRUE(std::filesystem::exists(dir.path() / "worlds" / "default" / "grid.pgm"))
      << "a clean shutdown saves each world to the data directory";
}

}  // namespace
}  // namespace occgeo::testing
