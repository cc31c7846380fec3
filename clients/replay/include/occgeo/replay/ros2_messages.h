#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace occgeo::replay {

// A CDR message that does not hold its type: too short, a bad encapsulation header, or a length past its end.
class CdrError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Reads ROS 2 CDR (XCDR1, little or big endian as its 4-byte encapsulation header says). Alignment counts from
// after the header, as rmw does.
class CdrReader {
 public:
  explicit CdrReader(std::string_view data);
  std::uint8_t u8(const char* field);
  std::uint32_t u32(const char* field);
  std::int32_t i32(const char* field);
  float f32(const char* field);
  double f64(const char* field);
  std::string string(const char* field);
  void bytes(std::size_t count, const char* field);  // skips `count` bytes
  // A sequence's element count, checked against the bytes left (each element at least `min_element_bytes`).
  std::uint32_t sequence_length(const char* field, std::size_t min_element_bytes);
  [[nodiscard]] std::size_t position() const { return position_; }

 private:
  const char* take(std::size_t count, std::size_t alignment, const char* field);
  std::string_view data_;
  std::size_t position_ = 4;
  bool little_endian_ = true;
};

struct RosHeader {
  double stamp_s = 0.0;
  std::string frame_id;
};

// geometry_msgs Pose / Transform: translation in metres, rotation as a unit quaternion.
struct RosPose {
  double x = 0, y = 0, z = 0;
  double qx = 0, qy = 0, qz = 0, qw = 1;
};

struct RosLaserScan {  // sensor_msgs/msg/LaserScan
  RosHeader header;
  float angle_min = 0, angle_max = 0, angle_increment = 0, time_increment = 0, scan_time = 0;
  float range_min = 0, range_max = 0;
  std::vector<float> ranges;
};

struct RosOdometry {  // nav_msgs/msg/Odometry
  RosHeader header;
  std::string child_frame_id;
  RosPose pose;
  double linear_x = 0, angular_z = 0;
};

struct RosTransform {  // geometry_msgs/msg/TransformStamped
  RosHeader header;
  std::string child_frame_id;
  RosPose transform;
};

struct RosPointCloud {  // sensor_msgs/msg/PointCloud2 reduced to its x, y, z float32 fields
  RosHeader header;
  std::vector<float> xyz;  // x, y, z triples; points with a non-finite coordinate are dropped
};

inline constexpr std::string_view kLaserScanType = "sensor_msgs/msg/LaserScan";
inline constexpr std::string_view kOdometryType = "nav_msgs/msg/Odometry";
inline constexpr std::string_view kPointCloud2Type = "sensor_msgs/msg/PointCloud2";
inline constexpr std::string_view kTfMessageType = "tf2_msgs/msg/TFMessage";

// Each throws CdrError naming the field that did not fit.
RosLaserScan decode_laser_scan(std::string_view cdr);
RosOdometry decode_odometry(std::string_view cdr);
std::vector<RosTransform> decode_tf_message(std::string_view cdr);
RosPointCloud decode_point_cloud2(std::string_view cdr);

// Yaw, pitch and roll (Z-Y-X) of a quaternion, radians.
struct RollPitchYaw {
  double roll = 0, pitch = 0, yaw = 0;
};
RollPitchYaw to_roll_pitch_yaw(const RosPose& pose);

}  // namespace occgeo::replay
