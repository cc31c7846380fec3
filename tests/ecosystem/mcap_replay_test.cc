// `occgeo replay --format mcap` of ROS 2 bags written by the MCAP ecosystem's own libraries (make_bags.mjs:
// @mcap/core + @foxglove/rosmsg2-serialization) from the recorded datasets, against the real occgeod: the Intel bag
// maps as consistently as the CARMEN log it came from in every chunk compression, exp1 replays with its pose from TF,
// and damaged bags stop with an error naming the offset while nothing of the damaged part reaches the server.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <string>

#include "../support/json_fields.h"
#include "../support/process.h"

namespace occgeo::testing {
namespace {

constexpr auto kReplayLimit = std::chrono::seconds(240);

std::filesystem::path bags() { return OCCGEO_BAGS_DIR; }
std::filesystem::path datasets() { return source("../shared/datasets"); }

std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void write_file(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

std::uint64_t le64(const std::string& bytes, std::size_t at) {
  std::uint64_t value = 0;
  for (int i = 7; i >= 0; --i)
    value = (value << 8) | static_cast<unsigned char>(bytes[at + static_cast<std::size_t>(i)]);
  return value;
}

// File offset of the first Chunk record (opcode 0x06) of an MCAP file.
std::size_t first_chunk(const std::string& bytes) {
  std::size_t at = 8;
  while (at + 9 <= bytes.size()) {
    if (bytes[at] == 0x06) return at;
    at += 9 + static_cast<std::size_t>(le64(bytes, at + 1));
  }
  throw std::runtime_error("no chunk");
}

class McapReplay : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(bags() / "intel-none.mcap")) {
      GTEST_SKIP() << "no bags in " << bags() << " (the ecosystem_make_bags test writes them)";
    }
    server_ = std::make_unique<ServerProcess>(dir_.path());
  }

  ProcessResult replay(std::vector<std::string> args) {
    args.insert(args.begin(), {binary("clients/occgeo").string(), "replay", "--server", server_->address()});
    const ProcessResult result = run_process(args, kReplayLimit);
    EXPECT_FALSE(result.timed_out) << "replay did not finish within " << kReplayLimit.count() << " s";
    return result;
  }

  std::string replay_ok(const std::vector<std::string>& args) {
    const ProcessResult result = replay(args);
    EXPECT_EQ(result.exit_code, 0) << result.err << "\nserver log:\n" << server_->log();
    return result.out;
  }

  // `occgeo status --json` of the server.
  std::string status() {
    const ProcessResult result =
        run_process({binary("clients/occgeo").string(), "status", "--server", server_->address(), "--json"},
                    std::chrono::seconds(30));
    EXPECT_EQ(result.exit_code, 0) << result.err;
    return result.out;
  }

  TempDir dir_;
  std::unique_ptr<ServerProcess> server_;
};

TEST_F(McapReplay, IntelBagMapsAsConsistentlyAsTheCarmenLogInEveryChunkCompression) {
  const std::string carmen =
      replay_ok({"--format", "carmen", (datasets() / "carmen-intel/intel-corrected.log.gz").string(), "--max",
                 "--consistency", "--json", "--world", "carmen"});
  const double carmen_consistency = json_number(carmen, "consistency");
  std::cout << "carmen log: " << json_number(carmen, "scans_per_s") << " scans/s, consistency " << carmen_consistency
            << "\n";
  for (const char* compression : {"none", "zstd", "lz4"}) {
    SCOPED_TRACE(compression);
    const std::string world = std::string("bag-") + compression;
    // The log replay treats 30 m and beyond as no return; the bag states the sensor's 81 m, so say so explicitly.
    const ProcessResult result =
        replay({"--format", "mcap", (bags() / ("intel-" + std::string(compression) + ".mcap")).string(), "--max",
                "--max-range", "30", "--consistency", "--json", "--world", world});
    ASSERT_EQ(result.exit_code, 0) << result.err;
    EXPECT_NE(result.err.find("scans from topic /scan (sensor_msgs/msg/LaserScan)"), std::string::npos) << result.err;
    EXPECT_NE(result.err.find("odometry from topic /odom (nav_msgs/msg/Odometry)"), std::string::npos) << result.err;
    EXPECT_EQ(json_number(result.out, "scans"), 910);
    EXPECT_EQ(json_number(result.out, "scans_acked"), 910);
    EXPECT_EQ(json_number(result.out, "errors"), 0);
    EXPECT_NEAR(json_number(result.out, "consistency"), carmen_consistency, 0.005);
    std::cout << "intel-" << compression << ".mcap: " << json_number(result.out, "scans_per_s")
              << " scans/s, consistency " << json_number(result.out, "consistency") << "\n";
  }
}

TEST_F(McapReplay, Exp1BagTakesItsPoseAndLaserMountFromTf) {
  const std::string urg = replay_ok({"--format", "urg", (datasets() / "urg04lx-mines/exp1.dat").string(), "--max",
                                     "--consistency", "--json", "--world", "urg"});
  const ProcessResult result = replay({"--format", "mcap", (bags() / "exp1-zstd.mcap").string(), "--max",
                                       "--consistency", "--json", "--world", "exp1"});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_EQ(result.err.find("laser_pose_unknown"), std::string::npos) << result.err;
  EXPECT_EQ(json_number(result.out, "scans"), 756);
  EXPECT_EQ(json_number(result.out, "errors"), 0);
  // Same scans, same dead-reckoned poses (computed in the bag writer from the same ticks), same mount.
  EXPECT_NEAR(json_number(result.out, "consistency"), json_number(urg, "consistency"), 0.005);
  std::cout << "exp1 bag consistency " << json_number(result.out, "consistency") << ", urg log "
            << json_number(urg, "consistency") << "\n";
}

TEST_F(McapReplay, NamedTopicsAreUsedAndATopicOfAnotherTypeIsRefused) {
  const ProcessResult named = replay({"--format", "mcap", (bags() / "bunny-lz4.mcap").string(), "--max", "--json",
                                      "--topic-scan", "/scan", "--topic-odom", "/odom", "--topic-cloud", "/points"});
  ASSERT_EQ(named.exit_code, 0) << named.err;
  EXPECT_EQ(json_number(named.out, "scans"), 20);
  EXPECT_EQ(json_number(named.out, "clouds"), 1);
  EXPECT_EQ(json_number(named.out, "clouds_acked"), 1) << "the bunny's 397 points were accepted";
  EXPECT_EQ(json_number(named.out, "errors"), 0);
  EXPECT_NE(named.err.find("point clouds from topic /points (sensor_msgs/msg/PointCloud2)"), std::string::npos)
      << named.err;

  const ProcessResult wrong = replay({"--format", "mcap", (bags() / "intel-zstd.mcap").string(), "--max",
                                      "--topic-scan", "/odom", "--world", "wrong"});
  EXPECT_EQ(wrong.exit_code, 1);
  EXPECT_NE(wrong.err.find("topic '/odom' is of type 'nav_msgs/msg/Odometry', not the sensor_msgs/msg/LaserScan"),
            std::string::npos)
      << wrong.err;
  EXPECT_NE(wrong.err.find("offset "), std::string::npos) << wrong.err;
  EXPECT_EQ(status().find("\"world\":\"wrong\""), std::string::npos) << "nothing was sent";
}

TEST_F(McapReplay, DamagedBagsStopWithTheOffsetAndSendNothingOfTheDamagedPart) {
  const std::string good = read_file(bags() / "intel-none.mcap");
  const std::size_t chunk = first_chunk(good);

  std::string bad_magic = good;
  bad_magic[1] = 'X';
  write_file(dir_.path() / "bad_magic.mcap", bad_magic);
  const ProcessResult magic = replay({"--format", "mcap", (dir_.path() / "bad_magic.mcap").string(), "--max"});
  EXPECT_EQ(magic.exit_code, 1);
  EXPECT_NE(magic.err.find("offset 0: not an MCAP file (bad magic)"), std::string::npos) << magic.err;

  // A flipped byte inside the first chunk's records (uncompressed: 9-byte record prefix + 40 bytes of chunk fields).
  std::string corrupt = good;
  corrupt[chunk + 9 + 40 + 500] = static_cast<char>(corrupt[chunk + 9 + 40 + 500] ^ 0x20);
  write_file(dir_.path() / "crc.mcap", corrupt);
  const ProcessResult crc =
      replay({"--format", "mcap", (dir_.path() / "crc.mcap").string(), "--max", "--world", "crc"});
  EXPECT_EQ(crc.exit_code, 1);
  EXPECT_NE(crc.err.find("offset " + std::to_string(chunk) + ": chunk CRC mismatch"), std::string::npos) << crc.err;
  EXPECT_EQ(status().find("\"world\":\"crc\""), std::string::npos) << "no scan of the corrupt chunk reached the server";

  // Cut in the middle of the file: the complete chunks before the cut are replayed, then the error.
  write_file(dir_.path() / "cut.mcap", good.substr(0, good.size() / 2));
  const ProcessResult cut =
      replay({"--format", "mcap", (dir_.path() / "cut.mcap").string(), "--max", "--world", "cut"});
  EXPECT_EQ(cut.exit_code, 1);
  EXPECT_NE(cut.err.find("Chunk record cut short"), std::string::npos) << cut.err;
  EXPECT_NE(cut.err.find("left in the file"), std::string::npos) << cut.err;
}

}  // namespace
}  // namespace occgeo::testing
