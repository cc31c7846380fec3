#pragma once

#include <cmath>

#include "occgeo/v1/robot.pb.h"

namespace occgeo::testing {

// Geometry of the test robot below, shared by the handler and integration tests.
struct SensorRobot {
  static constexpr double kSonarMountX_m = 0.1;  // sonar ring centre, ahead of base_link
  static constexpr double kSonarRingRadius_m = 0.25;
  static constexpr int kSonarElements = 8;  // element k faces k * 45°, counter-clockwise from ahead
  static constexpr double kSonarRangeMin_m = 0.1;
  static constexpr double kSonarRangeMax_m = 3.0;
  static constexpr double kServoRangeMax_m = 4.0;  // the servo rangefinder sits on base_link's origin
  static constexpr double kServoMin_rad = -M_PI / 2;
  static constexpr double kServoMax_rad = M_PI / 2;
  static constexpr double kDepthMountX_m = 0.2;  // depth camera, 0.3 m up, looking ahead
  static constexpr double kDepthMountZ_m = 0.3;
  static constexpr double kDepthRangeMax_m = 6.0;
  static constexpr unsigned kDepthMaxPoints = 1000;
  static constexpr double kHeight_m = 0.5;  // footprint height: the point-cloud obstacle band's top
  // The ActivityBot's encoders (seed 003): 64 ticks per revolution, 3.25 mm of travel per tick.
  static constexpr double kMetresPerTick = 0.00325;
  static constexpr double kWheelSeparation_m = 0.1058;
};

// A laser-less robot with a sonar ring ("sonar"), a servo rangefinder ("lidar_lite"), a depth
// camera ("depth") and ActivityBot wheel encoders, starting at initial_pose (0.05, 0.05, 0): the
// middle of cell (0, 0) on a 0.1 m grid.
inline v1::RobotSpec sensor_robot_spec() {
  using R = SensorRobot;
  v1::RobotSpec spec;
  spec.set_model("sensor-rover");
  auto* drive = spec.mutable_kinematics()->mutable_differential();
  drive->set_wheel_separation_m(R::kWheelSeparation_m);
  drive->set_wheel_radius_m(R::kMetresPerTick * 64 / (2 * M_PI));
  drive->set_max_wheel_speed_mps(0.2);
  auto* box = spec.mutable_footprint()->mutable_box();
  box->set_length_m(0.6);
  box->set_width_m(0.5);
  box->set_height_m(R::kHeight_m);
  spec.set_command_timeout_s(0.5);

  auto* sonar = spec.add_sensors();
  sonar->set_name("sonar");
  sonar->mutable_mount()->mutable_position()->set_x(R::kSonarMountX_m);
  sonar->mutable_mount()->mutable_position()->set_z(0.2);
  auto* ring = sonar->mutable_range_array();
  for (int k = 0; k < R::kSonarElements; ++k) {
    const double a = k * M_PI / 4;
    auto* element = ring->add_elements();
    element->set_x(R::kSonarRingRadius_m * std::cos(a));
    element->set_y(R::kSonarRingRadius_m * std::sin(a));
    element->set_theta(a);
  }
  ring->set_beam_width_rad(0.44);
  ring->set_range_min_m(R::kSonarRangeMin_m);
  ring->set_range_max_m(R::kSonarRangeMax_m);
  ring->set_period_s(0.1);

  auto* servo = spec.add_sensors();
  servo->set_name("lidar_lite");
  servo->mutable_mount()->mutable_position()->set_z(0.3);
  auto* servo_spec = servo->mutable_servo_range();
  servo_spec->set_servo_min_rad(R::kServoMin_rad);
  servo_spec->set_servo_max_rad(R::kServoMax_rad);
  servo_spec->set_servo_step_rad(M_PI / 36);
  servo_spec->set_step_period_s(0.02);
  servo_spec->set_range_min_m(0.05);
  servo_spec->set_range_max_m(R::kServoRangeMax_m);

  auto* depth = spec.add_sensors();
  depth->set_name("depth");
  depth->mutable_mount()->mutable_position()->set_x(R::kDepthMountX_m);
  depth->mutable_mount()->mutable_position()->set_z(R::kDepthMountZ_m);
  depth->mutable_point_cloud()->set_range_max_m(R::kDepthRangeMax_m);
  depth->mutable_point_cloud()->set_max_points(R::kDepthMaxPoints);

  auto* encoders = spec.mutable_encoders();
  encoders->set_ticks_per_revolution(64);
  encoders->set_wheel_radius_m(R::kMetresPerTick * 64 / (2 * M_PI));
  encoders->set_wheel_separation_m(R::kWheelSeparation_m);
  encoders->set_counter_bits(32);
  spec.mutable_initial_pose()->set_x(0.05);
  spec.mutable_initial_pose()->set_y(0.05);
  return spec;
}

}  // namespace occgeo::testing
