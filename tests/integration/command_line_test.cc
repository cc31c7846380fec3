// The four command-line tools (occgeo, occgeo replay, occgeo-sim, occgeo-load) word a bad option alike: the tool's
// name, the option named in quotes, one line pointing at --help, and exit code 2, with nothing started.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "../support/process.h"

namespace occgeo::testing {
namespace {

struct Tool {
  std::string name;                  // as the error names it
  std::vector<std::string> command;  // the program and any command words
};

std::vector<Tool> tools() {
  const std::string occgeo = binary("clients/occgeo").string();
  return {{"occgeo", {occgeo, "status"}},
          {"occgeo replay", {occgeo, "replay", "--format", "carmen", "log.txt"}},
          {"occgeo-sim", {binary("clients/sim/occgeo-sim").string(), "--world", "w.yaml"}},
          {"occgeo-load", {binary("clients/load/occgeo-load").string()}}};
}

ProcessResult run_with(const Tool& tool, const std::vector<std::string>& extra) {
  std::vector<std::string> argv = tool.command;
  argv.insert(argv.end(), extra.begin(), extra.end());
  return run_process(argv, std::chrono::seconds(30));
}

TEST(CommandLine, EveryToolNamesAnUnknownOptionTheSameWay) {
  for (const Tool& tool : tools()) {
    const ProcessResult result = run_with(tool, {"--bogus", "1"});
    EXPECT_EQ(result.exit_code, 2) << tool.name;
    EXPECT_EQ(result.err, tool.name + ": unknown option '--bogus'\nrun '" + tool.name + " --help' for usage\n")
        << tool.name;
  }
}

TEST(CommandLine, EveryToolNamesAMissingValueTheSameWay) {
  for (const Tool& tool : tools()) {
    const ProcessResult result = run_with(tool, {"--server"});
    EXPECT_EQ(result.exit_code, 2) << tool.name;
    EXPECT_EQ(result.err, tool.name + ": option '--server' needs a value\nrun '" + tool.name + " --help' for usage\n")
        << tool.name;
  }
}

// Each tool's numeric option given a word: the error names that option and the text it got, in one style.
TEST(CommandLine, EveryToolNamesABadNumberTheSameWay) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"occgeo", "option '--x' needs a number, got 'abc'"},
      {"occgeo replay", "option '--speed' needs a positive number, got 'abc'"},
      {"occgeo-sim", "option '--duration' needs a duration in seconds, got 'abc'"},
      {"occgeo-load", "option '--duration' needs a finite number, got 'abc'"}};
  for (Tool tool : tools()) {
    const auto expected = std::find_if(cases.begin(), cases.end(), [&](const auto& c) { return c.first == tool.name; });
    ASSERT_NE(expected, cases.end()) << tool.name;
    // occgeo's status has no number: a point query has.
    if (tool.name == "occgeo") tool.command = {tool.command[0], "query", "ptem", "--world", "w", "--y", "0"};
    const std::string flag = tool.name == "occgeo" ? "--x" : tool.name == "occgeo replay" ? "--speed" : "--duration";
    const ProcessResult result = run_with(tool, {flag, "abc"});
    EXPECT_EQ(result.exit_code, 2) << tool.name;
    EXPECT_EQ(result.err, tool.name + ": " + expected->second + "\nrun '" + tool.name + " --help' for usage\n")
        << tool.name;
  }
}

}  // namespace
}  // namespace occgeo::testing
