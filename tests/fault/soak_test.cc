// The 60-second form of scripts/soak.sh: 4 robots, 64 query clients and 8 watching observers (occgeo-load) against
// one occgeod; no errors and no crash. Memory is printed, not judged: in one minute the robots' maps are still
// growing (the 600 s run of the script judges it).
#include <gtest/gtest.h>

#include "process.h"

namespace occgeo::testing {
namespace {

TEST(Soak, SixtySecondsOfRobotsQueriesAndObserversWithoutErrors) {
  TempDir dir;
  const auto result =
      run_process({"/bin/bash", source("scripts/soak.sh").string(), "--build", OCCGEO_BINARY_DIR, "--duration", "60",
                   "--sample-interval", "2", "--memory-verdict", "off", "--out", dir.path().string()},
                  std::chrono::seconds(240));
  std::printf("%s", result.out.c_str());
  EXPECT_FALSE(result.timed_out);
  EXPECT_EQ(result.exit_code, 0) << result.out << result.err;
  EXPECT_NE(result.out.find("SOAK PASSED"), std::string::npos);
  EXPECT_NE(result.out.find("errors: 0"), std::string::npos);
}

}  // namespace
}  // namespace occgeo::testing
