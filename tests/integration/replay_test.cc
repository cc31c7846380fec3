// `occgeo replay` against the real occgeod: the three recorded datasets replay to the end without a server error,
// the SLAM-corrected Intel log maps consistently, and a log full of quirks is replayed with its quirks counted.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "../clients/replay_excerpts.h"
#include "../support/json_fields.h"
#include "../support/process.h"

namespace occgeo::testing {
namespace {

constexpr auto kReplayLimit = std::chrono::seconds(180);

std::filesystem::path datasets() { return source("../shared/datasets"); }

class Replay : public ::testing::Test {
 protected:
  void SetUp() override { server_ = std::make_unique<ServerProcess>(dir_.path()); }

  // Runs `occgeo replay` with `args` against the server, bounded by kReplayLimit; returns its stdout.
  std::string replay(std::vector<std::string> args) {
    args.insert(args.begin(), {binary("clients/occgeo").string(), "replay", "--server", server_->address()});
    const ProcessResult result = run_process(args, kReplayLimit);
    EXPECT_FALSE(result.timed_out) << "replay did not finish within " << kReplayLimit.count() << " s";
    EXPECT_EQ(result.exit_code, 0) << result.err << "\nserver log:\n" << server_->log();
    return result.out;
  }

  void require_datasets() {
    if (!std::filesystem::is_directory(datasets())) {
      GTEST_SKIP() << "datasets not found at " << datasets() << " (CI keeps ../shared beside the repository)";
    }
  }

  TempDir dir_;
  std::unique_ptr<ServerProcess> server_;
};

TEST_F(Replay, IntelCorrectedLogMapsConsistentlyAndWritesPgmYamlPng) {
  require_datasets();
  if (IsSkipped()) return;
  const auto prefix = dir_.path() / "intel";
  const std::string json = replay({"--format", "carmen", (datasets() / "carmen-intel/intel-corrected.log.gz").string(),
                                   "--max", "--consistency", "--json", "--out", prefix.string(), "--world", "intel"});
  std::cout << "intel: " << json;
  EXPECT_EQ(json_number(json, "scans"), 910);  // SOURCE.txt: 910 FLASER
  EXPECT_EQ(json_number(json, "errors"), 0);
  // The poses are gmapping's corrected ones: an odd scan's hits should fall on walls the even scans mapped.
  EXPECT_GE(json_number(json, "consistency"), 0.95);
  std::cout << "intel scans_per_s " << json_number(json, "scans_per_s") << ", consistency "
            << json_number(json, "consistency") << "\n";
  // The rate within each tenth of the log shows whether ingest slows as the map grows.
  const std::vector<double> tenths = json_number_array(json, "scans_per_s_by_tenth");
  ASSERT_EQ(tenths.size(), 10U) << json;
  for (const double rate : tenths) EXPECT_GT(rate, 0.0) << json;
  for (const char* suffix : {".pgm", ".yaml", ".png"}) {
    const auto path = prefix.string() + suffix;
    ASSERT_TRUE(std::filesystem::exists(path)) << path;
    EXPECT_GT(std::filesystem::file_size(path), 16U) << path;
  }
  std::ifstream png(prefix.string() + ".png", std::ios::binary);
  std::string signature(8, '\0');
  png.read(signature.data(), 8);
  EXPECT_EQ(signature, "\x89PNG\r\n\x1a\n");
  std::ifstream pgm(prefix.string() + ".pgm", std::ios::binary);
  std::string magic(2, '\0');
  pgm.read(magic.data(), 2);
  EXPECT_EQ(magic, "P5");
}

TEST_F(Replay, UrgExp1ReplaysToTheEnd) {
  require_datasets();
  if (IsSkipped()) return;
  const std::string json = replay({"--format", "urg", (datasets() / "urg04lx-mines/exp1.dat").string(), "--max",
                                   "--json", "--world", "mines", "--consistency"});
  std::cout << "urg: " << json;
  EXPECT_EQ(json_number(json, "scans"), 756);  // SOURCE.txt
  EXPECT_EQ(json_number(json, "scans_acked"), 756);
  EXPECT_EQ(json_number(json, "errors"), 0);
  // About half the beams are the URG's error codes; clearing along them (reading them as "no return") erased the
  // walls and scored about 0.2. Skipped, the raw encoder odometry's map scores about 0.9.
  EXPECT_GT(json_number(json, "invalid_beams"), 200000);
  EXPECT_GE(json_number(json, "consistency"), 0.85);
  std::cout << "urg scans_per_s " << json_number(json, "scans_per_s") << ", consistency "
            << json_number(json, "consistency") << "\n";
}

TEST_F(Replay, DpslamLoop5ReplaysToTheEnd) {
  require_datasets();
  if (IsSkipped()) return;
  const std::string json =
      replay({"--format", "dpslam", (datasets() / "dpslam-loop5/loop5.log").string(), "--max", "--json"});
  std::cout << "dpslam: " << json;
  EXPECT_EQ(json_number(json, "scans"), 551);  // SOURCE.txt
  EXPECT_EQ(json_number(json, "scans_acked"), 551);
  EXPECT_EQ(json_number(json, "errors"), 0);
  std::cout << "dpslam scans_per_s " << json_number(json, "scans_per_s") << "\n";
}

// A replay keeps several scans ahead of their answers (--in-flight, default 8); the server holds it back through TCP
// and drops nothing, so every scan is answered and the map is the one a lockstep replay of the same log builds.
TEST_F(Replay, ScansAheadOfTheirAnswersBuildTheSameMapAsLockstep) {
  require_datasets();
  if (IsSkipped()) return;
  const auto log = (datasets() / "dpslam-loop5/loop5.log").string();
  const auto lockstep = dir_.path() / "lockstep";
  const auto ahead = dir_.path() / "ahead";
  const std::string lockstep_json = replay({"--format", "dpslam", log, "--max", "--json", "--in-flight", "1", "--world",
                                            "lockstep", "--id", "lockstep", "--out", lockstep.string()});
  const std::string ahead_json = replay({"--format", "dpslam", log, "--max", "--json", "--in-flight", "32", "--world",
                                         "ahead", "--id", "ahead", "--out", ahead.string()});
  for (const std::string& json : {lockstep_json, ahead_json}) {
    EXPECT_EQ(json_number(json, "scans"), 551) << json;
    EXPECT_EQ(json_number(json, "scans_acked"), 551) << json;
    EXPECT_EQ(json_number(json, "errors"), 0) << json;
  }
  std::cout << "lockstep scans_per_s " << json_number(lockstep_json, "scans_per_s") << ", 32 in flight "
            << json_number(ahead_json, "scans_per_s") << "\n";
  const auto bytes = [](const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string lockstep_map = bytes(lockstep.string() + ".pgm");
  ASSERT_GT(lockstep_map.size(), 1000U);
  EXPECT_TRUE(lockstep_map == bytes(ahead.string() + ".pgm")) << "the two replays built different maps";
}

TEST_F(Replay, RefusesAnInFlightCountThatIsNotAWholePositiveNumber) {
  for (const char* count : {"0", "2.5", "-1", "5000"}) {
    const ProcessResult result = run_process(
        {binary("clients/occgeo").string(), "replay", "--format", "carmen", "any.log", "--in-flight", count},
        std::chrono::seconds(10));
    EXPECT_EQ(result.exit_code, 2) << count;
    EXPECT_NE(result.err.find("--in-flight"), std::string::npos) << count << ": " << result.err;
  }
}

TEST_F(Replay, QuirkyLogIsPacedAndItsQuirksCountedWithoutServerErrors) {
  // Real Intel lines plus a truncated FLASER, a non-numeric one, an unknown line type and a scan whose timestamp
  // goes backwards, paced at 20x the log's speed (the two real scans are 2.2 s apart).
  std::string text = replay::testing::kCarmenIntelExcerpt;
  text += "FLASER 180 1.0 2.0 3.0\n";
  text += "FLASER 3 1.0 abc 3.0 0 0 0 0 0 0 40.0 host 40.0\n";
  text += "WHATEVER 1 2 3\n";
  std::string backwards = text.substr(text.find("FLASER 180 1.72"));
  backwards = backwards.substr(0, backwards.find('\n'));
  backwards.replace(backwards.rfind("35.1051 pippo"), 7, "30.0000");
  text += backwards + "\n";
  const auto log = dir_.path() / "quirky.log";
  std::ofstream(log) << text;
  const std::string json = replay({"--format", "carmen", log.string(), "--speed", "20", "--json"});
  std::cout << "quirky: " << json;
  EXPECT_EQ(json_number(json, "scans"), 3);
  EXPECT_EQ(json_number(json, "errors"), 0);
  EXPECT_EQ(json_number(json, "truncated_line"), 1);
  EXPECT_EQ(json_number(json, "unknown_line_type"), 1);
  EXPECT_EQ(json_number(json, "timestamp_not_increasing"), 1);
  // Pacing: 2.2 s of log at 20x takes at least 0.11 s.
  EXPECT_GE(json_number(json, "duration_s"), 0.1);
}

}  // namespace
}  // namespace occgeo::testing
