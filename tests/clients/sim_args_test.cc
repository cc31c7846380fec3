#include <gtest/gtest.h>

#include "occgeo/sim/args.h"

namespace occgeo::sim {
namespace {

// The message of the ArgsError that parsing args raises, or "" when it parses.
std::string error_of(const std::vector<std::string_view>& args) {
  try {
    parse_args(args);
  } catch (const ArgsError& error) {
    return error.what();
  }
  return "";
}

TEST(ParseArgs, TakesEveryFlagInBothForms) {
  const SimOptions options = parse_args({"--world",
                                         "w.yaml",
                                         "--robot=bearcat",
                                         "--id",
                                         "bc-7",
                                         "--world-name",
                                         "lab",
                                         "--server",
                                         "example.org:7701",
                                         "--lockstep",
                                         "--duration=12.5",
                                         "--start",
                                         "-1.5,2,0.25",
                                         "--laser-range",
                                         "6",
                                         "--noise",
                                         "0",
                                         "--seed",
                                         "99",
                                         "--json",
                                         "--visible-out",
                                         "v.txt",
                                         "--trace-out=t.csv",
                                         "--command-latency",
                                         "0.3"});
  EXPECT_EQ(options.world_file, "w.yaml");
  EXPECT_EQ(options.robot, "bearcat");
  EXPECT_EQ(options.robot_id, "bc-7");
  EXPECT_EQ(options.world_name, "lab");
  EXPECT_EQ(options.server.host, "example.org");
  EXPECT_EQ(options.server.port, 7701);
  EXPECT_TRUE(options.lockstep);
  EXPECT_EQ(options.duration_s, 12.5);
  EXPECT_EQ(options.start.x, -1.5);
  EXPECT_EQ(options.start.y, 2.0);
  EXPECT_EQ(options.start.theta, 0.25);
  EXPECT_EQ(options.laser_range_m, 6.0);
  EXPECT_EQ(options.noise_sigma_m, 0.0);
  EXPECT_EQ(options.seed, 99U);
  EXPECT_TRUE(options.json);
  EXPECT_EQ(options.visible_out, "v.txt");
  EXPECT_EQ(options.trace_out, "t.csv");
  EXPECT_EQ(options.command_latency_s, 0.3);
}

TEST(ParseArgs, HasTheDocumentedDefaults) {
  const SimOptions options = parse_args({"--world", "w.yaml"});
  EXPECT_EQ(options.robot, "bearcat");
  EXPECT_EQ(options.robot_id, "bearcat-1");
  EXPECT_EQ(options.world_name, "default");
  EXPECT_EQ(options.server.to_string(), "127.0.0.1:7700");
  EXPECT_FALSE(options.lockstep);
  EXPECT_FALSE(options.duration_s);
  EXPECT_EQ(options.start.x, 0.0);
  EXPECT_EQ(options.seed, 1U);
  EXPECT_FALSE(options.json);
  EXPECT_FALSE(options.visible_out);
  EXPECT_EQ(options.command_latency_s, 0.0) << "lockstep without latency unless asked";
  EXPECT_TRUE(parse_args({"--help"}).help) << "--help needs no --world";
}

TEST(ParseArgs, ErrorsNameTheFlag) {
  const std::vector<std::pair<std::vector<std::string_view>, std::string>> cases = {
      {{}, "option '--world' is required"},
      {{"--world"}, "option '--world' needs a value"},
      {{"--world", "--json"}, "option '--world' needs a value"},
      {{"--world", ""}, "option '--world' must not be empty"},
      {{"--world", "w.yaml", "--duration", "soon"}, "option '--duration' needs a duration in seconds, got 'soon'"},
      {{"--world", "w.yaml", "--duration", "0"}, "option '--duration' must be greater than 0"},
      {{"--world", "w.yaml", "--duration=-3"}, "option '--duration' must be greater than 0"},
      {{"--world", "w.yaml", "--duration", "inf"}, "option '--duration' needs a duration in seconds"},
      {{"--world", "w.yaml", "--start", "1,2"}, "option '--start' needs X,Y,THETA"},
      {{"--world", "w.yaml", "--start", "1,2,x"}, "option '--start' needs X,Y,THETA"},
      {{"--world", "w.yaml", "--start", "1,2,3,4"}, "option '--start' needs X,Y,THETA"},
      {{"--world", "w.yaml", "--robot", "r2d2"},
       "option '--robot' needs a known robot, got 'r2d2' (known: bearcat, scout, activitybot, ugv, bearcat_3d)"},
      {{"--world", "w.yaml", "--server", "localhost"}, "option '--server' "},
      {{"--world", "w.yaml", "--server", "localhost:99999"}, "option '--server' "},
      {{"--world", "w.yaml", "--seed", "-3"}, "option '--seed' needs a non-negative integer"},
      {{"--world", "w.yaml", "--noise", "-0.1"}, "option '--noise' must not be negative"},
      {{"--world", "w.yaml", "--laser-range", "0"}, "option '--laser-range' must be greater than 0"},
      {{"--world", "w.yaml", "--id", ""}, "option '--id' must not be empty"},
      {{"--world", "w.yaml", "--command-latency", "-0.1"}, "option '--command-latency' must be between 0 and 5 s"},
      {{"--world", "w.yaml", "--command-latency", "300"}, "option '--command-latency' must be between 0 and 5 s"},
      {{"--world", "w.yaml", "--command-latency", "0.305"},
       "option '--command-latency' must be a whole number of 0.01 s physics steps, got '0.305'"},
      {{"--world", "w.yaml", "--command-latency", "nan"}, "option '--command-latency' needs a latency in seconds"},
      {{"--world", "w.yaml", "--json=yes"}, "option '--json' takes no value"},
      {{"--world", "w.yaml", "--seed", "1", "--seed", "2"}, "option '--seed' given more than once"},
      {{"--world", "w.yaml", "--speed", "2"}, "unknown option '--speed'"},
      {{"--world", "w.yaml", "extra"}, "unexpected argument 'extra'"},
  };
  for (const auto& [args, expected] : cases) {
    const std::string message = error_of(args);
    EXPECT_EQ(message.rfind(expected, 0), 0U)
        << "got \"" << message << "\", expected it to start with \"" << expected << "\"";
  }
}

TEST(ConfiguredPreset, AppliesTheLaserOverrides) {
  const RobotPreset preset = configured_preset(parse_args({"--world", "w.yaml", "--laser-range", "5", "--noise", "0"}));
  EXPECT_EQ(preset.laser()->range_max_m, 5.0);
  EXPECT_EQ(preset.laser()->range_noise_sigma_m, 0.0);
  const RobotPreset defaults = configured_preset(parse_args({"--world", "w.yaml"}));
  EXPECT_EQ(defaults.laser()->range_max_m, 8.0);
  EXPECT_EQ(defaults.laser()->range_noise_sigma_m, 0.01);
}

TEST(Usage, ListsEveryFlag) {
  for (const char* flag :
       {"--world", "--robot", "--id", "--world-name", "--server", "--start", "--duration", "--lockstep",
        "--laser-range", "--noise", "--seed", "--json", "--visible-out", "--trace-out", "--command-latency"}) {
    EXPECT_NE(usage().find(flag), std::string::npos) << flag;
  }
}

}  // namespace
}  // namespace occgeo::sim
