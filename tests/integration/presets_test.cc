// Every robot preset of the simulator against the real server, in lockstep on the shipped room world: each connects,
// streams its own sensors (laser, sonar ring, servo-swept single beam with encoder ticks, URG on a skid-steer base),
// and the map the server builds must mark what those sensors could see and little else.
#include <gtest/gtest.h>

#include <iostream>
#include <string>
#include <vector>

#include "../support/json_fields.h"
#include "../support/map_score.h"
#include "../support/process.h"

namespace occgeo::testing {
namespace {

struct PresetRun {
  std::string robot;     // --robot
  std::string duration;  // sim seconds
  std::string drive;     // --drive script; empty when the server steers the robot
  std::string start;     // --start pose x,y,theta
  std::string world;     // a pixel world shipped in clients/sim/worlds
  // Free cells more than one cell from any obstacle that may be marked occupied, as a fraction of all free cells.
  double max_false_rate_beyond_one_cell = 0.02;
};

void PrintTo(const PresetRun& run, std::ostream* out) { *out << run.robot; }

class PresetMapsWorld : public ::testing::TestWithParam<PresetRun> {};

TEST_P(PresetMapsWorld, MarksWhatItsSensorsSawAndLittleElse) {
  const PresetRun& run = GetParam();
  TempDir dir;
  ServerProcess server(dir.path());
  const auto world_yaml = source("clients/sim/worlds/" + run.world);
  const WorldTruth truth(mapfile::read_map_yaml(world_yaml));
  const auto visible_file = dir.path() / "visible.txt";

  std::vector<std::string> args = {binary("clients/sim/occgeo-sim").string(),
                                   "--server",
                                   server.address(),
                                   "--robot",
                                   run.robot,
                                   "--world",
                                   world_yaml.string(),
                                   "--world-name",
                                   run.robot,
                                   "--id",
                                   run.robot + "-1",
                                   "--start",
                                   run.start,
                                   "--lockstep",
                                   "--duration",
                                   run.duration,
                                   "--json",
                                   "--visible-out",
                                   visible_file.string()};
  if (!run.drive.empty()) args.insert(args.end(), {"--drive", run.drive});
  const ProcessResult sim = run_process(args, std::chrono::seconds(240));
  ASSERT_FALSE(sim.timed_out) << sim.err;
  ASSERT_EQ(sim.exit_code, 0) << sim.err << "\nserver log:\n" << server.log();
  std::cout << run.robot << ": " << sim.out;
  EXPECT_NEAR(json_number(sim.out, "sim_time_s"), std::stod(run.duration), 0.2) << sim.out;

  const auto prefix = dir.path() / "exported";
  const ProcessResult exported =
      run_process({binary("clients/occgeo").string(), "map", "export", "--server", server.address(), "--world",
                   run.robot, "--out", prefix.string(), "--json"},
                  std::chrono::seconds(60));
  ASSERT_EQ(exported.exit_code, 0) << exported.err;

  const CellSet visible = read_visible_cells(visible_file, truth);
  ASSERT_GT(visible.size(), 100U) << "the sensors should have seen many of the room's obstacle cells";
  const MapScore score = score_map(visible, mapfile::read_map_yaml(prefix.string() + ".yaml"), truth);
  std::cout << run.robot << " map: " << score.describe() << '\n';
  EXPECT_GE(score.recall(), 0.90);
  // Free cells are judged with the same one-cell tolerance as obstacles: every wall face of this room lies on a cell
  // boundary, and a robot that stands facing one (the Bearcat deadlocks here) puts about half of its noisy hits in the
  // free cell in front of it. The strict rates are printed above.
  EXPECT_LT(score.false_rate_beyond_one_cell(), run.max_false_rate_beyond_one_cell);
}

// The server steers the robots with a laser (Bearcat behaviour); the scout and the ActivityBot have none, so they
// follow looped scripts: the scout tours a 3 m x 2.4 m loop round the room's centre (HIMM needs sonar readings from
// many places), the ActivityBot stands sweeping its servo and turns a quarter between sweeps. The UGV's URG reaches
// 4 m, so it maps the open field, where the Bearcat behaviour keeps it moving; in the room it deadlocks at once.
const std::string kScoutTour =
    "0.3,0,5;0,0.5,3.1416;0.3,0,4;0,0.5,3.1416;0.3,0,10;0,0.5,3.1416;0.3,0,8;0,0.5,3.1416;0.3,0,10;0,0.5,3.1416;"
    "0.3,0,4;0,0.5,3.1416;0.3,0,5;0,0.5,6.2832";

INSTANTIATE_TEST_SUITE_P(
    EveryPreset, PresetMapsWorld,
    ::testing::Values(
        PresetRun{.robot = "bearcat", .duration = "60", .drive = "", .start = "0,0,0", .world = "room.yaml"},
        PresetRun{.robot = "ugv", .duration = "90", .drive = "", .start = "0,0,-2.4", .world = "open_field.yaml"},
        // HIMM marks an off-axis echo on the element's axis, where nothing is (seed 001 §3 saw its map "of its own
        // path"); such a mark now goes only when a later echo passes through it, since a sonar's silence (mostly a
        // specular miss) carves nothing. The price of keeping the walls: 4.3 % of free cells marked here against
        // 1.7 % when silence carved, for 100 % of the seen wall cells kept against 98.6 % on this tour (and 97 %
        // against 68 % on a wander along the walls, tests/scenarios/sonar_wander_test.cc).
        PresetRun{.robot = "scout",
                  .duration = "120",
                  .drive = kScoutTour,
                  .start = "0,0,0",
                  .world = "room.yaml",
                  .max_false_rate_beyond_one_cell = 0.05},
        PresetRun{.robot = "activitybot",
                  .duration = "40",
                  .drive = "0,0,7.2;0,0.8,2;0,0,7.2;0,0.8,2",
                  .start = "0,0,0",
                  .world = "room.yaml"}),
    [](const ::testing::TestParamInfo<PresetRun>& run_info) { return run_info.param.robot; });

}  // namespace
}  // namespace occgeo::testing
