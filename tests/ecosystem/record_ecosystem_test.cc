// `occgeo record`'s files read by the MCAP ecosystem's own libraries (read_recording.mjs): @mcap/core's indexed reader
// through the summary and indexes, its stream reader with every CRC checked, and protobufjs decoding each message with
// the FileDescriptorSet embedded as its schema, in every chunk compression.
#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <iostream>
#include <thread>

#include "../support/json_fields.h"
#include "../support/process.h"

namespace occgeo::testing {
namespace {

using namespace std::chrono_literals;

class RecordingReadByTheEcosystem : public ::testing::TestWithParam<std::string> {};

TEST_P(RecordingReadByTheEcosystem, McapCoreFindsEveryMessageAndProtobufjsDecodesThemWithTheEmbeddedSchemas) {
  TempDir dir;
  ServerProcess server(dir.path());
  const auto file = dir.path() / ("session-" + GetParam() + ".mcap");
  BackgroundProcess record({binary("clients/occgeo").string(), "record", "--out", file.string(), "--compression",
                            GetParam(), "--server", server.address()},
                           dir.path() / "record.out", dir.path() / "record.err");
  for (int i = 0; i < 100 && server.log().find("session_watch") == std::string::npos; ++i) {
    std::this_thread::sleep_for(50ms);
  }
  ASSERT_NE(server.log().find("session_watch"), std::string::npos) << "the recorder did not attach";
  const auto sim = run_process(
      {binary("clients/sim/occgeo-sim").string(), "--world", source("clients/sim/worlds/corridor.yaml").string(),
       "--server", server.address(), "--lockstep", "--duration", "10", "--json"},
      120s);
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  const double scans_sent = json_number(sim.out, "scans_sent");
  ASSERT_GT(scans_sent, 50);
  std::this_thread::sleep_for(500ms);
  ASSERT_EQ(record.stop(SIGTERM, 20s), 0) << "SIGTERM must close the recording cleanly";

  const ProcessResult read =
      run_process({OCCGEO_NODE, source("tests/ecosystem/read_recording.mjs").string(), file.string()}, 120s);
  ASSERT_EQ(read.exit_code, 0) << read.out << read.err;
  std::cout << "read_recording (" << GetParam() << "): " << read.out;
  // Indexed (summary, chunk and message indexes), streamed (CRCs) and the statistics agree.
  const double messages = json_number(read.out, "indexed_messages");
  EXPECT_EQ(json_number(read.out, "streamed_messages"), messages);
  EXPECT_EQ(json_number(read.out, "statistics_messages"), messages);
  EXPECT_GE(json_number(read.out, "chunk_indexes"), 1);
  // Every scan the simulator sent was accepted and recorded, each with its placement and the cells it changed.
  EXPECT_EQ(json_number(read.out, "laser_scans"), scans_sent);
  EXPECT_EQ(json_number(read.out, "laser_beams_min"), 181);
  EXPECT_EQ(json_number(read.out, "placements_with_pose"), scans_sent);
  EXPECT_EQ(json_number(read.out, "placements_with_changed_cells"), scans_sent);
  EXPECT_EQ(json_number(read.out, "odometry"), scans_sent);
  EXPECT_GE(json_number(read.out, "motion_commands"), json_number(sim.out, "commands_received"));
  EXPECT_NE(read.out.find("\"robot_models\":[\"bearcat\"]"), std::string::npos);
  EXPECT_NE(read.out.find("\"/default/bearcat-1/laser_scan\":{\"schema\":\"occgeo.v1.LaserScan\","
                          "\"schema_encoding\":\"protobuf\",\"message_encoding\":\"protobuf\""),
            std::string::npos);
}

INSTANTIATE_TEST_SUITE_P(Compressions, RecordingReadByTheEcosystem, ::testing::Values("zstd", "lz4", "none"),
                         [](const ::testing::TestParamInfo<std::string>& param_info) { return param_info.param; });

}  // namespace
}  // namespace occgeo::testing
