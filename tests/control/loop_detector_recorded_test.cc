// The loop detector on true trajectories recorded from lockstep runs of the scenario catalogue (t, x, y, theta of
// base_link in the world frame every 0.1 s, from occgeo-sim --trace-out), with the parameters the deadlock escape
// uses: the seed behaviours' endless loops are caught (PointBug in front of the cup of seed 003 Fig 2.10; cumulative
// PTEM guidance circling the obstacle of seed 004 §6.3.2), the full stack's way round the cup and in is not a loop.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "occgeo/service/control/loop_detector.h"

namespace occgeo::service::control {
namespace {

struct TracePose {
  double t_s = 0.0;
  Pose2 pose;
};

std::vector<TracePose> read_trace(const std::string& name) {
  std::ifstream in(std::string(OCCGEO_CONTROL_TEST_DATA) + "/" + name);
  std::vector<TracePose> rows;
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream fields(line);
    TracePose row;
    if (fields >> row.t_s >> row.pose.x >> row.pose.y >> row.pose.theta) rows.push_back(row);
  }
  return rows;
}

// As the escape configures it (behaviour.cc): the defaults with an 8 s stall.
LoopDetectorParams escape_params() {
  LoopDetectorParams params;
  params.stall_time_s = 8.0;
  return params;
}

struct Verdicts {
  std::optional<double> loop_s;   // first time a loop was reported
  std::optional<double> stall_s;  // first time a stall was reported
  std::optional<double> reached_s;
  double driven_m = 0.0;  // until the end, or the goal's tolerance circle
};

// Feeds the trace until it ends or enters the goal's 0.3 m tolerance circle (the catalogue's).
Verdicts replay(const std::vector<TracePose>& trace, const Eigen::Vector2d& goal_W) {
  LoopDetector detector(escape_params());
  Verdicts verdicts;
  for (std::size_t i = 0; i < trace.size(); ++i) {
    const Pose2& pose = trace[i].pose;
    if (i > 0) verdicts.driven_m += std::hypot(pose.x - trace[i - 1].pose.x, pose.y - trace[i - 1].pose.y);
    if ((Eigen::Vector2d(pose.x, pose.y) - goal_W).norm() <= 0.3) {
      verdicts.reached_s = trace[i].t_s;
      break;
    }
    const LoopStatus status = detector.update({pose, trace[i].t_s, goal_W, BehaviourState::kNone});
    if (status.loop && !verdicts.loop_s) verdicts.loop_s = trace[i].t_s;
    if (status.stalled && !verdicts.stall_s) verdicts.stall_s = trace[i].t_s;
  }
  return verdicts;
}

TEST(LoopDetectorOnRecordedRuns, CatchesPointBugsEndlessLoopInFrontOfTheCup) {
  const std::vector<TracePose> trace = read_trace("pointbug_cup_ugv_alone.csv");
  ASSERT_GT(trace.size(), 500U);
  const Verdicts verdicts = replay(trace, {4.4, 0.0});
  EXPECT_FALSE(verdicts.reached_s);
  // The zigzag repeats only roughly (each sudden point lies a little elsewhere), so the third pass within 0.3 m comes
  // late or not at all in 60 s; the stall verdict catches it first: no closer to the goal since about 20 s.
  ASSERT_TRUE(verdicts.stall_s) << "driven " << verdicts.driven_m << " m without a verdict";
  EXPECT_LT(*verdicts.stall_s, 35.0);
}

TEST(LoopDetectorOnRecordedRuns, CatchesCumulativePtemCirclingTheObstacle) {
  const std::vector<TracePose> trace = read_trace("ptem_loop_cumulative_alone.csv");
  ASSERT_GT(trace.size(), 500U);
  const Verdicts verdicts = replay(trace, {4.5, 0.0});
  EXPECT_FALSE(verdicts.reached_s);
  // The circle repeats: the third pass through the same place, heading the same way, is a loop (near the end of the
  // 60 s run); the stall verdict, which the escape acts on as well, comes long before.
  ASSERT_TRUE(verdicts.loop_s) << "driven " << verdicts.driven_m << " m without a loop verdict";
  ASSERT_TRUE(verdicts.stall_s);
  EXPECT_LT(*verdicts.stall_s, 35.0);
  EXPECT_LT(*verdicts.stall_s, *verdicts.loop_s) << "no progress shows before the circle closes twice";
}

TEST(LoopDetectorOnRecordedRuns, TheFullStacksWayRoundTheCupIsNoLoop) {
  const std::vector<TracePose> trace = read_trace("pointbug_cup_ugv_escape.csv");
  ASSERT_GT(trace.size(), 200U);
  const Verdicts verdicts = replay(trace, {4.4, 0.0});
  EXPECT_TRUE(verdicts.reached_s);
  EXPECT_FALSE(verdicts.loop_s) << "at " << verdicts.loop_s.value_or(0.0) << " s";
}

}  // namespace
}  // namespace occgeo::service::control
