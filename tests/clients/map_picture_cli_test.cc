// Map pictures end to end, against the real server: occgeo-sim --lockstep for 20 s on the open field with --trace-out
// and --png-out, then `occgeo map export --format png --ptem --trajectory`; and `occgeo replay --out` of a synthetic
// CARMEN log. The PNGs are decoded: their size follows the world image (sim) and the server's grid times --scale
// (export, replay), obstacles are black and the trajectory is drawn.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "../mapping/png_reader.h"
#include "../support/json_fields.h"
#include "../support/process.h"
#include "occgeo/mapfile/map_file.h"
#include "occgeo/mapfile/map_picture.h"

namespace occgeo::testing {
namespace {

// How many RGB pixels of the image have the colour.
std::size_t count_colour(const PngImage& image, mapfile::Rgb colour) {
  std::size_t count = 0;
  for (std::size_t i = 0; i + 2 < image.samples.size(); i += 3) {
    if (image.samples[i] == colour.r && image.samples[i + 1] == colour.g && image.samples[i + 2] == colour.b) ++count;
  }
  return count;
}

TEST(MapPictureCli, SimulatorAndExportPicturesShowObstaclesAndTheTrajectory) {
  TempDir dir;
  ServerProcess server(dir.path());
  const auto world_yaml = source("clients/sim/worlds/open_field.yaml");
  const auto trace = dir.path() / "trace.csv";
  const auto sim_png = dir.path() / "sim.png";
  const ProcessResult sim = run_process(
      {binary("clients/sim/occgeo-sim").string(), "--server", server.address(), "--world", world_yaml.string(),
       "--lockstep", "--duration", "20", "--json", "--trace-out", trace.string(), "--png-out", sim_png.string()},
      std::chrono::seconds(120));
  ASSERT_FALSE(sim.timed_out) << sim.err;
  ASSERT_EQ(sim.exit_code, 0) << sim.err << "\nserver log:\n" << server.log();
  EXPECT_GE(json_number(sim.out, "distance_m"), 2.0) << sim.out;

  // The simulator's picture: one pixel per world pixel, the fence and obstacles black, the drive red, the end blue.
  const mapfile::OccupancyImage world = mapfile::read_map_yaml(world_yaml);
  ASSERT_TRUE(std::filesystem::exists(sim_png));
  const PngImage sim_picture = decode_png(read_file_bytes(sim_png));
  EXPECT_EQ(sim_picture.width, world.width);
  EXPECT_EQ(sim_picture.height, world.height);
  EXPECT_EQ(sim_picture.channels, 3U);
  EXPECT_GT(count_colour(sim_picture, {0, 0, 0}), 1000U);  // the 0.3 m fence alone is 4 x 3 x 600 pixels
  EXPECT_GT(count_colour(sim_picture, mapfile::kTrajectoryColour), 10U);
  EXPECT_GT(count_colour(sim_picture, mapfile::kMarkerColour), 5U);

  // The server's map as pgm (for its size) and as a png at scale 2 with the PTEM clusters and the trace.
  const auto pgm_prefix = dir.path() / "grid";
  const ProcessResult pgm = run_process({binary("clients/occgeo").string(), "map", "export", "--server",
                                         server.address(), "--world", "default", "--out", pgm_prefix.string()},
                                        std::chrono::seconds(60));
  ASSERT_EQ(pgm.exit_code, 0) << pgm.err;
  const mapfile::OccupancyImage grid = mapfile::read_map_yaml(pgm_prefix.string() + ".yaml");

  const auto png_prefix = dir.path() / "picture";
  const ProcessResult exported =
      run_process({binary("clients/occgeo").string(), "map", "export", "--server", server.address(), "--world",
                   "default", "--format", "png", "--ptem", "--trajectory", trace.string(), "--scale", "2", "--out",
                   png_prefix.string(), "--json"},
                  std::chrono::seconds(60));
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  std::cout << exported.out;
  EXPECT_FALSE(std::filesystem::exists(png_prefix.string() + ".pgm")) << "png writes the picture only";
  const auto png_path = png_prefix.string() + ".png";
  ASSERT_TRUE(std::filesystem::exists(png_path));
  const PngImage picture = decode_png(read_file_bytes(png_path));
  EXPECT_EQ(picture.width, 2 * grid.width);
  EXPECT_EQ(picture.height, 2 * grid.height);
  EXPECT_EQ(json_number(exported.out, "width"), picture.width);
  EXPECT_GE(json_number(exported.out, "clusters"), 0.0);
  EXPECT_GT(json_number(exported.out, "trajectory_points"), 10.0);
  EXPECT_GT(count_colour(picture, {0, 0, 0}), 0U) << "no fully certain occupied cell";
  EXPECT_GT(count_colour(picture, {255, 255, 255}), 0U) << "no fully certain free cell";
  EXPECT_GT(count_colour(picture, mapfile::kTrajectoryColour), 10U);
}

// A CARMEN log of a robot driving 4 m along +x down a corridor whose walls are at y = +-1.5 m (181 beams, 1 deg apart
// from -90 deg, as FLASER has them).
std::string corridor_log() {
  std::ostringstream log;
  constexpr int kScans = 41;
  for (int k = 0; k < kScans; ++k) {
    const double x = 0.1 * k;
    log << "FLASER 181";
    for (int i = 0; i < 181; ++i) {
      const double angle = (-90.0 + i) * M_PI / 180.0;
      const double s = std::sin(angle);
      const double range = std::abs(s) < 1e-9 ? 50.0 : std::min(50.0, 1.5 / std::abs(s));
      log << ' ' << range;
    }
    log << ' ' << x << " 0 0 " << x << " 0 0 " << 1.0 + 0.1 * k << " host " << 1.0 + 0.1 * k << "\n";
  }
  return log.str();
}

TEST(MapPictureCli, ReplayPictureShowsTheMapAndTheReplayedTrajectory) {
  TempDir dir;
  ServerProcess server(dir.path());
  const auto log_file = dir.path() / "corridor.log";
  std::ofstream(log_file) << corridor_log();
  const auto prefix = dir.path() / "corridor";
  const ProcessResult replay =
      run_process({binary("clients/occgeo").string(), "replay", "--format", "carmen", log_file.string(), "--max",
                   "--server", server.address(), "--world", "corridor", "--out", prefix.string(), "--json"},
                  std::chrono::seconds(60));
  ASSERT_EQ(replay.exit_code, 0) << replay.err;
  EXPECT_EQ(json_number(replay.out, "scans"), 41);
  // The PNG pictures the map written beside it: one pixel per cell, as `map export --format png` draws it.
  const mapfile::OccupancyImage grid = mapfile::read_map_yaml(prefix.string() + ".yaml");
  const PngImage picture = decode_png(read_file_bytes(prefix.string() + ".png"));
  EXPECT_EQ(picture.width, grid.width);
  EXPECT_EQ(picture.height, grid.height);
  EXPECT_EQ(picture.channels, 3U);
  // The walls (two rows of cells at least 4 m long) are black, the 4 m drive a red line ending in a blue marker.
  EXPECT_GT(count_colour(picture, {0, 0, 0}), 60U);
  const std::size_t red = count_colour(picture, mapfile::kTrajectoryColour);
  std::cout << "replay picture " << picture.width << " x " << picture.height << ": " << red << " trajectory pixels\n";
  EXPECT_GE(red, 30U);
  EXPECT_GT(count_colour(picture, mapfile::kMarkerColour), 0U);
}

TEST(MapPictureCli, PictureOptionsNameTheFlagAtFault) {
  TempDir dir;
  const auto occgeo = binary("clients/occgeo").string();
  // Usage errors come before any connection, so no server is needed.
  const ProcessResult ptem_on_pgm =
      run_process({occgeo, "map", "export", "--world", "w", "--out", "x", "--ptem"}, std::chrono::seconds(30));
  EXPECT_EQ(ptem_on_pgm.exit_code, 2);
  EXPECT_NE(ptem_on_pgm.err.find("option '--ptem' needs --format png"), std::string::npos) << ptem_on_pgm.err;
  const ProcessResult bad_scale =
      run_process({occgeo, "map", "export", "--format", "png", "--world", "w", "--out", "x", "--scale", "0"},
                  std::chrono::seconds(30));
  EXPECT_EQ(bad_scale.exit_code, 2);
  EXPECT_NE(bad_scale.err.find("option '--scale' needs a whole number from 1 to 16, got '0'"), std::string::npos)
      << bad_scale.err;
  const auto missing = dir.path() / "missing.csv";
  const ProcessResult no_trace = run_process(
      {occgeo, "map", "export", "--format", "png", "--world", "w", "--out", "x", "--trajectory", missing.string()},
      std::chrono::seconds(30));
  EXPECT_EQ(no_trace.exit_code, 1);
  EXPECT_NE(no_trace.err.find("option '--trajectory': cannot read"), std::string::npos) << no_trace.err;
  const auto bad_csv = dir.path() / "bad.csv";
  std::ofstream(bad_csv) << "t,x,y,theta\n0,1,2,0\n0.1,1,oops,0\n";
  const ProcessResult bad_trace = run_process(
      {occgeo, "map", "export", "--format", "png", "--world", "w", "--out", "x", "--trajectory", bad_csv.string()},
      std::chrono::seconds(30));
  EXPECT_EQ(bad_trace.exit_code, 1);
  EXPECT_NE(bad_trace.err.find("option '--trajectory': " + bad_csv.string() + " line 3: expected 4 numbers"),
            std::string::npos)
      << bad_trace.err;
}

}  // namespace
}  // namespace occgeo::testing
