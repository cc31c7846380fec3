// occgeod's Foxglove endpoint driven by @foxglove/ws-protocol's FoxgloveClient (foxglove_check.mjs): /map and /scans
// are advertised, subscribing delivers decodable messages whose grid matches `occgeo map export`, unsubscribing stops
// them.
#include <gtest/gtest.h>

#include <filesystem>
#include <iostream>

#include "../support/http_get.h"
#include "../support/json_fields.h"
#include "../support/process.h"

namespace occgeo::testing {
namespace {

TEST(FoxgloveClient, SubscribesToMapAndScansThatMatchTheExportAndUnsubscribes) {
  const std::filesystem::path bag = std::filesystem::path(OCCGEO_BAGS_DIR) / "bunny-lz4.mcap";
  if (!std::filesystem::exists(bag)) GTEST_SKIP() << "no " << bag << " (the ecosystem_make_bags test writes it)";
  TempDir dir;
  ServerProcess server(dir.path(), {"--http", "127.0.0.1:0"});
  const std::uint16_t port = http_port(server);
  const ProcessResult result = run_process(
      {OCCGEO_NODE, source("tests/ecosystem/foxglove_check.mjs").string(), binary("clients/occgeo").string(),
       server.address(), std::to_string(port), bag.string(), dir.path().string()},
      std::chrono::seconds(150));
  ASSERT_EQ(result.exit_code, 0) << result.out << result.err << "\nserver log:\n" << server.log();
  std::cout << "foxglove: " << result.out;
  EXPECT_GE(json_number(result.out, "map_messages"), 1);
  EXPECT_GE(json_number(result.out, "scan_messages"), 1);
  EXPECT_EQ(json_number(result.out, "messages_after_unsubscribe"), 0);
}

}  // namespace
}  // namespace occgeo::testing
