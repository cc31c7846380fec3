// Server + simulated Bearcat in lockstep on the open-field world: the robot must drive without
// touching anything, and the map the server builds must match what its laser could see.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>

#include "../support/process.h"
#include "../support/world_truth.h"

namespace occgeo::testing {
namespace {

// Pulls a number out of a flat JSON object by key (the sim's and CLI's summaries are flat
// except for final_pose, whose keys do not clash with the top-level ones asked for here).
double json_number(const std::string& json, const std::string& key) {
  const std::regex pattern("\"" + key + "\"\\s*:\\s*(-?[0-9.eE+-]+)");
  std::smatch match;
  if (!std::regex_search(json, match, pattern)) throw std::runtime_error("no '" + key + "' in " + json);
  return std::stod(match[1]);
}

bool json_bool(const std::string& json, const std::string& key) {
  const std::regex pattern("\"" + key + "\"\\s*:\\s*(true|false)");
  std::smatch match;
  if (!std::regex_search(json, match, pattern)) throw std::runtime_error("no '" + key + "' in " + json);
  return match[1] == "true";
}

std::set<std::pair<int, int>> read_visible_cells(const std::filesystem::path& file, const WorldTruth& truth) {
  std::set<std::pair<int, int>> cells;
  std::ifstream in(file);
  std::uint32_t col = 0, row = 0;
  while (in >> col >> row) cells.insert(truth.cell_of_pixel(col, row));
  return cells;
}

bool marked_within_one_cell(const std::set<std::pair<int, int>>& marked, const std::pair<int, int>& cell) {
  for (int dx = -1; dx <= 1; ++dx) {
    for (int dy = -1; dy <= 1; ++dy) {
      if (marked.contains({cell.first + dx, cell.second + dy})) return true;
    }
  }
  return false;
}

// Avoidance states of the Bearcat behaviour: any of them means the robot steered around something.
const std::vector<std::string> kAvoidanceStates = {"avoid_right_obstacle", "avoid_left_obstacle", "steer_gap",
                                                   "pass_between", "no_gap"};

TEST(DriveOpenField, BearcatWandersTwoMinutesWithoutCollisionAndMapsWhatItSaw) {
  TempDir dir;
  ServerProcess server(dir.path());
  const auto world_yaml = source("clients/sim/worlds/open_field.yaml");
  const WorldTruth truth(mapfile::read_map_yaml(world_yaml));
  std::set<std::pair<int, int>> visible;

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

  std::size_t found = 0;
  for (const auto& cell : visible) found += marked_within_one_cell(marked, cell) ? 1 : 0;
  const double recall = static_cast<double>(found) / static_cast<double>(visible.size());

  std::size_t false_marks = 0;
  for (const auto& cell : marked) false_marks += truth.free_cells().contains(cell) ? 1 : 0;
  const double false_rate = static_cast<double>(false_marks) / static_cast<double>(truth.free_cells().size());
  // A stricter view of the same errors: relative to the free cells the map actually observed.
  const auto observed = observed_cells(map);
  std::size_t observed_free = 0;
  for (const auto& cell : observed) observed_free += truth.free_cells().contains(cell) ? 1 : 0;
  const double observed_false_rate = static_cast<double>(false_marks) / static_cast<double>(observed_free);
  std::cout << "map: " << visible.size() << " obstacle cells seen, " << found << " marked within one cell ("
            << 100.0 * recall << "%); " << false_marks << " of " << truth.free_cells().size()
            << " free cells marked occupied (" << 100.0 * false_rate << "%; " << 100.0 * observed_false_rate
            << "% of the " << observed_free << " free cells observed)\n";
  EXPECT_GE(recall, 0.90);
  EXPECT_LT(false_rate, 0.02);
  EXPECT_LT(observed_false_rate, 0.02);

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
