#pragma once

#include <cstdint>
#include <numbers>
#include <optional>
#include <random>
#include <span>
#include <string_view>
#include <vector>

#include "occgeo/service/control/bearcat.h"
#include "occgeo/service/control/behaviour_state.h"

// The wander and avoid behaviours of seed 001 (§2.1–2.2, Figures 1–2): random straight runs of random length, then
// with probability 0.5 a small turn (turn_little) in a random direction; an obstacle seen by the front sensors
// inside a threshold subsumes wander with a turn in place, in one randomly chosen direction, until the front is
// clear. The seed's robot is a Nomad Super Scout II with a ring of 16 sonars.
namespace occgeo::service::control {

// The bearing step of the Scout's 16-sonar ring, radians; sonar 0 looks straight ahead and the numbering runs
// counter-clockwise (the Nomad convention; the seed does not say, so this is an assumption).
inline constexpr double kScoutSonarSpacing_rad = 2.0 * std::numbers::pi / 16.0;

// One set of range readings in the robot frame (x forward, y left), the common input of a range-array ring and a
// laser scan; beams need not be ordered or evenly spaced.
struct RangeSet {
  std::vector<BeamReading> beams;  // bearing (radians, CCW from x) and range (metres, +inf means no return)
  double range_max_m = 0.0;        // readings at or beyond this mean no return, metres
};

// A laser scan as a RangeSet; every beam is kept.
RangeSet range_set_from_scan(const ScanView& scan);

// A ring of range-array elements as a RangeSet: element i looks along bearings_rad[i] and read ranges_m[i]; throws
// std::invalid_argument naming the argument when the two sizes differ.
RangeSet range_set_from_ring(std::span<const double> bearings_rad, std::span<const double> ranges_m,
                             double range_max_m);

// The bearings of the Scout's 16-sonar ring, sonar i at i * 22.5 degrees wrapped into (-pi, pi].
std::vector<double> scout_sonar_bearings_rad();

// Tuning of wander and avoid. The seed gives the structure and the 0.5 turn probability only; every distance,
// angle and speed below is an assumption, chosen for a Scout-sized (0.41 m diameter) robot.
struct WanderParams {
  // The frontal sector that avoid watches: the seed's sonars 13–15 (right, -22.5..-67.5 degrees) and 0–2 (ahead
  // and left, 0..45 degrees); beams with -right <= bearing <= left count. The seed's choice is asymmetric.
  double front_sector_right_rad = 3.0 * kScoutSonarSpacing_rad;  // radians clockwise from ahead, in [0, pi]
  double front_sector_left_rad = 2.0 * kScoutSonarSpacing_rad;   // radians counter-clockwise from ahead, in [0, pi]
  // A front beam shorter than this is an obstacle (seed: "a certain threshold"; assumption: ~1.5 robot diameters).
  double obstacle_threshold_m = 0.6;  // metres
  // Straight runs are uniform in [min, max] (seed: "random(distance)"; assumption).
  double run_length_min_m = 0.5;  // metres
  double run_length_max_m = 2.0;  // metres
  // Probability that a run ends with turn_little (seed §2.1: 0.5).
  double turn_probability = 0.5;
  // turn_little turns by a uniform angle in [min, max] (seed: "turn_little"; assumption: 10..45 degrees).
  double turn_little_min_rad = 10.0 * std::numbers::pi / 180.0;  // radians
  double turn_little_max_rad = 45.0 * std::numbers::pi / 180.0;  // radians
  double linear_speed_mps = 0.3;     // forward speed of a straight run, m/s (assumption; the Scout does ~1 m/s)
  double turn_speed_radps = 0.5;     // yaw rate of turn_little and of avoid's turn, rad/s (assumption)
  std::uint64_t seed = 0x5eed0001U;  // seeds the behaviour's std::mt19937_64 so runs are reproducible

  // Throws std::invalid_argument naming the first field that is not finite or out of range.
  void validate() const;
};

// What the robot did since the last decision. Odometry is preferred; a missing value is estimated from the last
// command times elapsed_s, so a server without odometry still gets runs measured in metres.
struct WanderProgress {
  double elapsed_s = 0.0;             // time since the last decision, seconds, non-negative
  std::optional<double> travelled_m;  // distance driven since the last decision, metres (sign ignored)
  std::optional<double> turned_rad;   // yaw turned since the last decision, radians (sign ignored)
};

// One wander decision: a body velocity and the state that produced it.
struct WanderDecision {
  double linear_mps = 0.0;     // forward speed, m/s
  double angular_radps = 0.0;  // counter-clockwise yaw rate, rad/s
  bool stop = false;           // never set: the seed's robot wanders forever; here for uniformity with bearcat
  BehaviourState state = BehaviourState::kWanderStraight;  // kWanderStraight, kWanderTurn or kAvoidTurn
  bool front_blocked = false;                              // some frontal beam is closer than obstacle_threshold_m
  double remaining_m = 0.0;    // what is left of the current straight run, metres (0 unless wander_straight)
  double remaining_rad = 0.0;  // what is left of turn_little, radians (0 unless wander_turn)
};

// The wander/avoid state machine. Deterministic: its only random source is the std::mt19937_64 seeded from
// params.seed, and uniform draws are made from the generator's raw bits (not std::uniform_real_distribution,
// whose algorithm differs between standard libraries), so the same params and inputs give the same decisions.
class WanderBehaviour {
 public:
  enum class State { kWanderStraight, kWanderTurn, kAvoidTurn };

  // Throws std::invalid_argument naming the bad field of params. Draws the first run's length.
  explicit WanderBehaviour(const WanderParams& params);

  // Advances by the progress since the last decision, then decides on the readings; throws std::invalid_argument
  // naming the field when the readings are malformed or none lies in the frontal sector, or progress is invalid.
  WanderDecision decide(const RangeSet& readings, const WanderProgress& progress);

  // Whether some beam in the frontal sector is closer than the threshold; validates readings like decide.
  bool front_blocked(const RangeSet& readings) const;

  State state() const { return state_; }
  const WanderParams& params() const { return params_; }

 private:
  double uniform(double low, double high);  // uniform in [low, high)
  bool coin(double probability);            // true with the given probability
  void start_run();
  WanderDecision command() const;

  WanderParams params_;
  std::mt19937_64 generator_;
  State state_ = State::kWanderStraight;
  double remaining_m_ = 0.0;      // rest of the straight run, metres
  double remaining_rad_ = 0.0;    // rest of turn_little, radians
  double turn_direction_ = 1.0;   // +1 counter-clockwise, -1 clockwise, for wander_turn and avoid_turn
  double last_linear_mps_ = 0.0;  // the last command, to estimate progress without odometry
  double last_angular_radps_ = 0.0;
};

}  // namespace occgeo::service::control
