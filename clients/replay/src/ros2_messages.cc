#include "occgeo/replay/ros2_messages.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

namespace occgeo::replay {

CdrReader::CdrReader(std::string_view data) : data_(data) {
  if (data.size() < 4) throw CdrError("message of " + std::to_string(data.size()) + " byte(s) has no CDR header");
  // Representation identifier: 0x0000 CDR big endian, 0x0001 CDR little endian.
  if (data[0] != 0 || (data[1] != 0 && data[1] != 1)) {
    throw CdrError("unsupported CDR representation " + std::to_string(static_cast<unsigned char>(data[0])) + "," +
                   std::to_string(static_cast<unsigned char>(data[1])) + " (plain CDR is)");
  }
  little_endian_ = data[1] == 1;
}

const char* CdrReader::take(std::size_t count, std::size_t alignment, const char* field) {
  const std::size_t body = position_ - 4;
  const std::size_t aligned = 4 + (body + alignment - 1) / alignment * alignment;
  if (aligned > data_.size() || count > data_.size() - aligned) {
    throw CdrError("message of " + std::to_string(data_.size()) + " byte(s) ends before its field '" + field +
                   "' (needs " + std::to_string(count) + " byte(s) at byte " + std::to_string(aligned) + ")");
  }
  position_ = aligned + count;
  return data_.data() + aligned;
}

namespace {
template <typename T>
T load(const char* p, bool little_endian) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, p, sizeof(T));
  if (little_endian != (std::endian::native == std::endian::little)) {
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  }
  T value;
  std::memcpy(&value, bytes, sizeof(T));
  return value;
}
}  // namespace

void CdrReader::bytes(std::size_t count, const char* field) { take(count, 1, field); }
std::uint8_t CdrReader::u8(const char* field) { return static_cast<std::uint8_t>(*take(1, 1, field)); }
std::uint32_t CdrReader::u32(const char* field) { return load<std::uint32_t>(take(4, 4, field), little_endian_); }
std::int32_t CdrReader::i32(const char* field) { return load<std::int32_t>(take(4, 4, field), little_endian_); }
float CdrReader::f32(const char* field) { return load<float>(take(4, 4, field), little_endian_); }
double CdrReader::f64(const char* field) { return load<double>(take(8, 8, field), little_endian_); }

std::string CdrReader::string(const char* field) {
  const std::uint32_t length = u32(field);  // includes the terminating NUL
  if (length == 0) return {};
  const char* bytes = take(length, 1, field);
  return std::string(bytes, length - 1);
}

std::uint32_t CdrReader::sequence_length(const char* field, std::size_t min_element_bytes) {
  const std::uint32_t count = u32(field);
  const std::size_t left = data_.size() - position_;
  if (min_element_bytes > 0 && count > left / min_element_bytes) {
    throw CdrError("sequence '" + std::string(field) + "' claims " + std::to_string(count) +
                   " element(s) but the message has " + std::to_string(left) + " byte(s) left");
  }
  return count;
}

namespace {

RosHeader read_header(CdrReader& cdr) {
  RosHeader header;
  const std::int32_t sec = cdr.i32("header.stamp.sec");
  const std::uint32_t nanosec = cdr.u32("header.stamp.nanosec");
  header.stamp_s = static_cast<double>(sec) + static_cast<double>(nanosec) * 1e-9;
  header.frame_id = cdr.string("header.frame_id");
  return header;
}

RosPose read_pose(CdrReader& cdr, const char* position_field, const char* rotation_field) {
  RosPose pose;
  pose.x = cdr.f64(position_field);
  pose.y = cdr.f64(position_field);
  pose.z = cdr.f64(position_field);
  pose.qx = cdr.f64(rotation_field);
  pose.qy = cdr.f64(rotation_field);
  pose.qz = cdr.f64(rotation_field);
  pose.qw = cdr.f64(rotation_field);
  return pose;
}

void skip_covariance(CdrReader& cdr, const char* field) {
  for (int i = 0; i < 36; ++i) cdr.f64(field);
}

std::vector<float> read_floats(CdrReader& cdr, const char* field) {
  const std::uint32_t count = cdr.sequence_length(field, 4);
  std::vector<float> values;
  values.reserve(count);
  for (std::uint32_t i = 0; i < count; ++i) values.push_back(cdr.f32(field));
  return values;
}

}  // namespace

RosLaserScan decode_laser_scan(std::string_view data) {
  CdrReader cdr(data);
  RosLaserScan scan;
  scan.header = read_header(cdr);
  scan.angle_min = cdr.f32("angle_min");
  scan.angle_max = cdr.f32("angle_max");
  scan.angle_increment = cdr.f32("angle_increment");
  scan.time_increment = cdr.f32("time_increment");
  scan.scan_time = cdr.f32("scan_time");
  scan.range_min = cdr.f32("range_min");
  scan.range_max = cdr.f32("range_max");
  scan.ranges = read_floats(cdr, "ranges");
  read_floats(cdr, "intensities");
  return scan;
}

RosOdometry decode_odometry(std::string_view data) {
  CdrReader cdr(data);
  RosOdometry odometry;
  odometry.header = read_header(cdr);
  odometry.child_frame_id = cdr.string("child_frame_id");
  odometry.pose = read_pose(cdr, "pose.pose.position", "pose.pose.orientation");
  skip_covariance(cdr, "pose.covariance");
  odometry.linear_x = cdr.f64("twist.twist.linear");
  cdr.f64("twist.twist.linear");
  cdr.f64("twist.twist.linear");
  cdr.f64("twist.twist.angular");
  cdr.f64("twist.twist.angular");
  odometry.angular_z = cdr.f64("twist.twist.angular");
  skip_covariance(cdr, "twist.covariance");
  return odometry;
}

std::vector<RosTransform> decode_tf_message(std::string_view data) {
  CdrReader cdr(data);
  // Smallest TransformStamped: stamp 8 + two empty strings 8 + 7 doubles 56.
  const std::uint32_t count = cdr.sequence_length("transforms", 72);
  std::vector<RosTransform> transforms;
  transforms.reserve(count);
  for (std::uint32_t i = 0; i < count; ++i) {
    RosTransform transform;
    transform.header = read_header(cdr);
    transform.child_frame_id = cdr.string("transforms.child_frame_id");
    transform.transform = read_pose(cdr, "transforms.transform.translation", "transforms.transform.rotation");
    transforms.push_back(std::move(transform));
  }
  return transforms;
}

RosPointCloud decode_point_cloud2(std::string_view data) {
  CdrReader cdr(data);
  RosPointCloud cloud;
  cloud.header = read_header(cdr);
  const std::uint32_t height = cdr.u32("height");
  const std::uint32_t width = cdr.u32("width");
  constexpr std::uint8_t kFloat32 = 7;  // sensor_msgs/PointField FLOAT32
  std::int64_t offsets[3] = {-1, -1, -1};
  const std::uint32_t field_count = cdr.sequence_length("fields", 13);
  for (std::uint32_t i = 0; i < field_count; ++i) {
    const std::string name = cdr.string("fields.name");
    const std::uint32_t offset = cdr.u32("fields.offset");
    const std::uint8_t datatype = cdr.u8("fields.datatype");
    cdr.u32("fields.count");
    const int axis = name == "x" ? 0 : name == "y" ? 1 : name == "z" ? 2 : -1;
    if (axis < 0) continue;
    if (datatype != kFloat32) throw CdrError("point field '" + name + "' is not FLOAT32");
    offsets[axis] = offset;
  }
  for (const std::int64_t offset : offsets) {
    if (offset < 0) throw CdrError("point cloud lacks one of the fields x, y, z");
  }
  const bool big_endian = cdr.u8("is_bigendian") != 0;
  const std::uint32_t point_step = cdr.u32("point_step");
  cdr.u32("row_step");
  const std::uint32_t data_size = cdr.sequence_length("data", 1);
  const std::size_t data_start = cdr.position();
  cdr.bytes(data_size, "data");
  cdr.u8("is_dense");
  const std::string_view bytes = data.substr(data_start, data_size);
  const std::uint64_t points = static_cast<std::uint64_t>(height) * width;
  for (const std::int64_t offset : offsets) {
    if (point_step < 4 || static_cast<std::uint64_t>(offset) > point_step - 4) {
      throw CdrError("point field offset " + std::to_string(offset) + " does not fit point_step " +
                     std::to_string(point_step));
    }
  }
  if (points * point_step > bytes.size()) {
    throw CdrError("point cloud of " + std::to_string(points) + " points of " + std::to_string(point_step) +
                   " bytes needs more than its " + std::to_string(bytes.size()) + " data byte(s)");
  }
  cloud.xyz.reserve(static_cast<std::size_t>(points) * 3);
  for (std::uint64_t p = 0; p < points; ++p) {
    float xyz[3];
    for (int axis = 0; axis < 3; ++axis) {
      xyz[axis] = load<float>(bytes.data() + p * point_step + static_cast<std::uint64_t>(offsets[axis]), !big_endian);
    }
    if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) continue;
    cloud.xyz.insert(cloud.xyz.end(), xyz, xyz + 3);
  }
  return cloud;
}

RollPitchYaw to_roll_pitch_yaw(const RosPose& q) {
  RollPitchYaw out;
  out.roll = std::atan2(2.0 * (q.qw * q.qx + q.qy * q.qz), 1.0 - 2.0 * (q.qx * q.qx + q.qy * q.qy));
  out.pitch = std::asin(std::clamp(2.0 * (q.qw * q.qy - q.qz * q.qx), -1.0, 1.0));
  out.yaw = std::atan2(2.0 * (q.qw * q.qz + q.qx * q.qy), 1.0 - 2.0 * (q.qy * q.qy + q.qz * q.qz));
  return out;
}

}  // namespace occgeo::replay
