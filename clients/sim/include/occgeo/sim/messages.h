#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "occgeo/geometry/kinematics.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/robot.h"
#include "occgeo/v1/session.pb.h"

namespace occgeo::sim {

// The hello that opens a driver session for robot_id in the world called world_name.
v1::Hello make_driver_hello(const std::string& robot_id, const std::string& world_name);

// The RobotSpec describing the preset: kinematics, footprint, every sensor (mounts as Pose3D at the sensor's height)
// and the watchdog period; for a robot with wheel encoders also the encoders and initial_pose = X_WB_start, the pose
// the server dead-reckons from.
v1::RobotSpec make_robot_spec(const RobotPreset& preset, const geometry::Pose2& X_WB_start = {});

// An Odometry message: base_link pose X_WB in the world and body velocity at sim time stamp_s.
v1::ClientMessage make_odometry_message(std::uint64_t seq, double stamp_s, const geometry::Pose2& X_WB,
                                        const geometry::BodyVelocity& velocity);

// A LaserScan message from the named sensor with ranges in metres at sim time stamp_s.
v1::ClientMessage make_laser_scan_message(const std::string& sensor, std::uint64_t seq, double stamp_s,
                                          const std::vector<float>& ranges_m);

// A RangeArray message from the named sensor: one range per element, metres, at sim time stamp_s.
v1::ClientMessage make_range_array_message(const std::string& sensor, std::uint64_t seq, double stamp_s,
                                           const std::vector<float>& ranges_m);

// A ServoRange message from the named sensor: one range in metres taken at servo_angle_rad, at sim time stamp_s.
v1::ClientMessage make_servo_range_message(const std::string& sensor, std::uint64_t seq, double stamp_s,
                                           double servo_angle_rad, float range_m);

// A PointCloud message from the named sensor: x, y, z triples in the sensor frame, metres, at sim time stamp_s.
v1::ClientMessage make_point_cloud_message(const std::string& sensor, std::uint64_t seq, double stamp_s,
                                           const std::vector<float>& xyz_S);

// A WheelEncoders message: cumulative tick counts at sim time stamp_s.
v1::ClientMessage make_wheel_encoders_message(std::uint64_t seq, double stamp_s, const EncoderTicks& ticks);

// The wheel command a MotionCommand asks for.
WheelCommand to_wheel_command(const v1::MotionCommand& command);

}  // namespace occgeo::sim
