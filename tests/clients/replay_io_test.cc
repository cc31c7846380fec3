// The replay library's line reader (gzip and plain), argument parser, map-consistency measure and summary. (Its PNG
// encoder is occgeo_mapfile's, tested in tests/mapping/png_test.cc.)
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <stdexcept>

#include "../support/temp_dir.h"
#include "occgeo/replay/line_source.h"
#include "occgeo/replay/replay.h"

namespace occgeo::replay {
namespace {

// A directory under the system temp dir, removed afterwards.
TEST(LineSource, ReadsGzipDetectedByMagicBytesAndPlainTextAlike) {
  occgeo::testing::TempDir dir;
  const std::string text = "first line\r\nsecond\n\n" + std::string(20000, 'x') + "\nlast without newline";
  const auto gz_path = dir.path() / "log.txt";  // no .gz suffix: detection is by content
  {
    gzFile out = gzopen(gz_path.c_str(), "wb");
    ASSERT_NE(out, nullptr);
    ASSERT_EQ(gzwrite(out, text.data(), static_cast<unsigned>(text.size())), static_cast<int>(text.size()));
    gzclose(out);
  }
  const auto plain_path = dir.path() / "log.gz";  // and a misleading suffix on plain text
  std::ofstream(plain_path, std::ios::binary) << text;

  for (const auto& [path, gzip] : {std::pair{gz_path, true}, std::pair{plain_path, false}}) {
    EXPECT_EQ(is_gzip_file(path), gzip);
    LineSource source(path);
    EXPECT_EQ(source.is_gzip(), gzip);
    std::vector<std::string> lines;
    while (auto line = source.next()) lines.push_back(*line);
    ASSERT_EQ(lines.size(), 5U) << path;
    EXPECT_EQ(lines[0], "first line");
    EXPECT_EQ(lines[1], "second");
    EXPECT_EQ(lines[2], "");
    EXPECT_EQ(lines[3].size(), 20000U);
    EXPECT_EQ(lines[4], "last without newline");
    EXPECT_EQ(source.line_number(), 5U);
    EXPECT_DOUBLE_EQ(source.progress(), 1.0);
  }
  EXPECT_THROW(LineSource(dir.path() / "missing.log"), std::runtime_error);
}

TEST(ReplayArgs, ParsesOptionsAndNamesMistakes) {
  const auto options = parse_replay_args({"--format", "urg", "exp1.dat", "--max", "--json", "--consistency", "--out",
                                          "/tmp/x", "--max-range", "4.5", "--world", "w", "--id", "r"});
  EXPECT_EQ(options.format, LogFormat::urg);
  EXPECT_EQ(options.file, "exp1.dat");
  EXPECT_TRUE(options.as_fast_as_possible);
  EXPECT_TRUE(options.json);
  EXPECT_TRUE(options.consistency);
  EXPECT_EQ(options.out_prefix, "/tmp/x");
  EXPECT_DOUBLE_EQ(*options.max_range_m, 4.5);
  EXPECT_EQ(options.world, "w");
  EXPECT_EQ(options.robot_id, "r");

  const auto message = [](const std::vector<std::string>& args) {
    try {
      parse_replay_args(args);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message({"f.log"}), "option '--format' is required");
  EXPECT_EQ(message({"--format", "rosbag", "f.log"}),
            "option '--format' needs carmen, dpslam, urg or mcap, got 'rosbag'");
  EXPECT_EQ(message({"--format", "carmen"}), "missing the log FILE");
  EXPECT_EQ(message({"--format", "carmen", "f", "--speed", "2", "--max"}),
            "options '--speed' and '--max' exclude each other");
  EXPECT_EQ(message({"--format", "carmen", "f", "--speed", "-1"}),
            "option '--speed' needs a positive number, got '-1'");
  EXPECT_EQ(message({"--format", "carmen", "f", "--bogus"}), "unknown option '--bogus'");
  EXPECT_EQ(message({"--format", "carmen", "f", "g"}), "unexpected argument 'g' (one log file only)");
  EXPECT_EQ(message({"--format", "carmen", "f", "--out"}), "option '--out' needs a value");
  EXPECT_EQ(message({"--format", "mcap", "f", "--laser-pose", "1,2,3"}),
            "option '--laser-pose' needs x,y,z,roll,pitch,yaw, got '1,2,3'");
  EXPECT_EQ(message({"--format", "mcap", "f", "--laser-pose", "1,2,3,4,5,x"}),
            "option '--laser-pose' needs six numbers x,y,z,roll,pitch,yaw, got '1,2,3,4,5,x'");
  const ReplayOptions mcap = parse_replay_args({"--format", "mcap", "bag.mcap", "--topic-scan", "/front/scan",
                                                "--topic-odom", "/wheel/odom", "--laser-pose", "0.1,0,0.2,0,0,1.5"});
  EXPECT_EQ(mcap.format, LogFormat::mcap);
  EXPECT_EQ(mcap.mcap.topic_scan, "/front/scan");
  EXPECT_EQ(mcap.mcap.topic_odom, "/wheel/odom");
  ASSERT_TRUE(mcap.mcap.laser_pose);
  EXPECT_DOUBLE_EQ((*mcap.mcap.laser_pose)[5], 1.5);
}

TEST(Consistency, CountsEndpointsWithinOneCellOfAnOccupiedCell) {
  // 5 x 5 cells of 0.1 m from (0, 0); cell (3, 2) is occupied, (1, 4) only at certainty 2 (below threshold 3), the
  // rest free; (4, 4) never observed.
  mapfile::CertaintyWindow grid;
  grid.cell_size_m = 0.1;
  grid.width = 5;
  grid.height = 5;
  grid.occupied_threshold = 3;
  grid.cells.assign(25, 0);
  grid.cells[2 * 5 + 3] = 7;
  grid.cells[4 * 5 + 1] = 2;
  grid.cells[4 * 5 + 4] = 255;
  EXPECT_TRUE(occupied_near(grid, 0.35, 0.25));
  EXPECT_TRUE(occupied_near(grid, 0.21, 0.11));   // diagonal neighbour cell (2, 1)
  EXPECT_FALSE(occupied_near(grid, 0.15, 0.25));  // two cells away
  EXPECT_FALSE(occupied_near(grid, 0.15, 0.45));  // next to a cell below the threshold only
  EXPECT_FALSE(occupied_near(grid, -5.0, 9.0));   // outside the window

  // A sensor at (0.05, 0.25) looking along +x, mounted 0.05 m ahead of base_link: beams straight ahead (0.3 m, hit),
  // at +90 deg (0.2 m, to (0.05, 0.45): miss); the no-return and too-short beams do not count.
  ScanRecord scan;
  scan.X_WB = LogPose{0.0, 0.25, 0.0};
  scan.X_BS = LogPose{0.05, 0.0, 0.0};
  scan.angle_min_rad = 0.0;
  scan.angle_increment_rad = std::numbers::pi / 2.0;
  scan.ranges_m = {0.3F, 0.2F, std::numeric_limits<float>::infinity(), 0.01F};
  ConsistencyCounter counter;
  counter.add_scan(grid, scan, 0.05, 5.0);
  EXPECT_EQ(counter.endpoints(), 2U);
  EXPECT_EQ(counter.hits(), 1U);
  EXPECT_DOUBLE_EQ(counter.fraction(), 0.5);
}

TEST(SummaryJson, HasTheDocumentedFields) {
  ReplayOptions options;
  options.file = "a\"b.log";
  ReplaySummary summary;
  summary.scans = 10;
  summary.errors = 1;
  summary.duration_s = 2.0;
  summary.scans_per_s = 5.0;
  summary.scans_per_s_by_tenth = {4.0, 6.5};
  summary.consistency = 0.975;
  Diagnostics diagnostics;
  diagnostics.warn("truncated_line", 3, "cut");
  const std::string json = summary_json(options, summary, diagnostics);
  EXPECT_NE(json.find("\"scans\":10"), std::string::npos) << json;
  EXPECT_NE(json.find("\"warnings\":1,\"warnings_by_kind\":{\"truncated_line\":1}"), std::string::npos) << json;
  EXPECT_NE(json.find("\"errors\":1"), std::string::npos) << json;
  EXPECT_NE(json.find("\"scans_per_s\":5,\"scans_per_s_by_tenth\":[4,6.5]"), std::string::npos) << json;
  EXPECT_NE(json.find("\"duration_s\":2"), std::string::npos) << json;
  EXPECT_NE(json.find("\"consistency\":0.975"), std::string::npos) << json;
  EXPECT_NE(json.find("\"file\":\"a\\\"b.log\""), std::string::npos) << json;
}

}  // namespace
}  // namespace occgeo::replay
