// The replay library's PNG encoder (checked by decoding with zlib), line reader (gzip and plain), argument parser
// and map-consistency measure.
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <stdexcept>

#include "../support/temp_dir.h"
#include "occgeo/replay/line_source.h"
#include "occgeo/replay/png.h"
#include "occgeo/replay/replay.h"

namespace occgeo::replay {
namespace {

std::uint32_t read_u32(const std::vector<std::uint8_t>& bytes, std::size_t at) {
  return (std::uint32_t{bytes.at(at)} << 24U) | (std::uint32_t{bytes.at(at + 1)} << 16U) |
         (std::uint32_t{bytes.at(at + 2)} << 8U) | std::uint32_t{bytes.at(at + 3)};
}

struct Chunk {
  std::string type;
  std::vector<std::uint8_t> data;
};

// Splits a PNG into chunks, checking the signature and every CRC.
std::vector<Chunk> chunks_of(const std::vector<std::uint8_t>& png) {
  const std::vector<std::uint8_t> signature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  EXPECT_TRUE(std::equal(signature.begin(), signature.end(), png.begin()));
  std::vector<Chunk> chunks;
  std::size_t at = signature.size();
  while (at + 12 <= png.size()) {
    const std::uint32_t length = read_u32(png, at);
    Chunk chunk;
    chunk.type.assign(png.begin() + static_cast<std::ptrdiff_t>(at + 4),
                      png.begin() + static_cast<std::ptrdiff_t>(at + 8));
    chunk.data.assign(png.begin() + static_cast<std::ptrdiff_t>(at + 8),
                      png.begin() + static_cast<std::ptrdiff_t>(at + 8 + length));
    const uLong crc = crc32(0L, png.data() + at + 4, static_cast<uInt>(4 + length));
    EXPECT_EQ(read_u32(png, at + 8 + length), static_cast<std::uint32_t>(crc)) << chunk.type;
    chunks.push_back(std::move(chunk));
    at += 12 + length;
  }
  EXPECT_EQ(at, png.size());
  return chunks;
}

TEST(Png, HeaderAndInflatedRowsMatchThePixels) {
  constexpr std::uint32_t kWidth = 37, kHeight = 5;
  std::vector<std::uint8_t> pixels(kWidth * kHeight);
  std::mt19937 rng(3);
  for (auto& p : pixels) p = static_cast<std::uint8_t>(rng() % 256);
  const auto chunks = chunks_of(encode_png_gray8(kWidth, kHeight, pixels));
  ASSERT_EQ(chunks.size(), 3U);
  ASSERT_EQ(chunks[0].type, "IHDR");
  ASSERT_EQ(chunks[0].data.size(), 13U);
  EXPECT_EQ(read_u32(chunks[0].data, 0), kWidth);
  EXPECT_EQ(read_u32(chunks[0].data, 4), kHeight);
  EXPECT_EQ(chunks[0].data[8], 8);   // bit depth
  EXPECT_EQ(chunks[0].data[9], 0);   // greyscale
  EXPECT_EQ(chunks[0].data[10], 0);  // deflate
  EXPECT_EQ(chunks[0].data[11], 0);  // adaptive filtering method
  EXPECT_EQ(chunks[0].data[12], 0);  // not interlaced
  ASSERT_EQ(chunks[1].type, "IDAT");
  EXPECT_EQ(chunks[2].type, "IEND");
  EXPECT_TRUE(chunks[2].data.empty());

  std::vector<std::uint8_t> raw((kWidth + 1) * kHeight + 16);
  uLongf raw_size = static_cast<uLongf>(raw.size());
  ASSERT_EQ(uncompress(raw.data(), &raw_size, chunks[1].data.data(), static_cast<uLong>(chunks[1].data.size())), Z_OK);
  ASSERT_EQ(raw_size, (kWidth + 1) * kHeight);
  for (std::uint32_t row = 0; row < kHeight; ++row) {
    EXPECT_EQ(raw[row * (kWidth + 1)], 0) << "row " << row << " filter";
    for (std::uint32_t col = 0; col < kWidth; ++col) {
      ASSERT_EQ(raw[row * (kWidth + 1) + 1 + col], pixels[row * kWidth + col]) << row << ", " << col;
    }
  }
}

TEST(Png, RejectsInconsistentSizes) {
  EXPECT_THROW(encode_png_gray8(3, 2, std::vector<std::uint8_t>(5)), std::invalid_argument);
  EXPECT_THROW(encode_png_gray8(0, 2, {}), std::invalid_argument);
}

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
  EXPECT_EQ(message({"f.log"}), "missing required option --format");
  EXPECT_EQ(message({"--format", "rosbag", "f.log"}), "--format must be carmen, dpslam or urg, not 'rosbag'");
  EXPECT_EQ(message({"--format", "carmen"}), "missing the log FILE");
  EXPECT_EQ(message({"--format", "carmen", "f", "--speed", "2", "--max"}), "give --speed or --max, not both");
  EXPECT_EQ(message({"--format", "carmen", "f", "--speed", "-1"}), "option --speed needs a positive number, not '-1'");
  EXPECT_EQ(message({"--format", "carmen", "f", "--bogus"}), "unknown option '--bogus'");
  EXPECT_EQ(message({"--format", "carmen", "f", "g"}), "unexpected argument 'g' (one log file only)");
  EXPECT_EQ(message({"--format", "carmen", "f", "--out"}), "option --out needs a value");
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
  summary.consistency = 0.975;
  Diagnostics diagnostics;
  diagnostics.warn("truncated_line", 3, "cut");
  const std::string json = summary_json(options, summary, diagnostics);
  EXPECT_NE(json.find("\"scans\":10"), std::string::npos) << json;
  EXPECT_NE(json.find("\"warnings\":1,\"warnings_by_kind\":{\"truncated_line\":1}"), std::string::npos) << json;
  EXPECT_NE(json.find("\"errors\":1"), std::string::npos) << json;
  EXPECT_NE(json.find("\"scans_per_s\":5"), std::string::npos) << json;
  EXPECT_NE(json.find("\"duration_s\":2"), std::string::npos) << json;
  EXPECT_NE(json.find("\"consistency\":0.975"), std::string::npos) << json;
  EXPECT_NE(json.find("\"file\":\"a\\\"b.log\""), std::string::npos) << json;
}

}  // namespace
}  // namespace occgeo::replay
