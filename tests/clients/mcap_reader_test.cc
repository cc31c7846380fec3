// The MCAP reader and CDR decoders on hand-built files: every record kind the replay needs, chunks with and without a
// CRC, and each kind of damage stopping with an error that names the offset (and the topic, for a bad message).
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "occgeo/client/mcap_format.h"
#include "occgeo/replay/mcap.h"
#include "occgeo/replay/ros2_messages.h"
#include "occgeo/replay/scan_source.h"

namespace occgeo::replay {
namespace {

// Little-endian byte building for MCAP records and CDR messages.
struct Bytes {
  std::string data;
  Bytes& u8(std::uint8_t v) { return raw(&v, 1); }
  Bytes& u16(std::uint16_t v) { return raw(&v, 2); }
  Bytes& u32(std::uint32_t v) { return raw(&v, 4); }
  Bytes& u64(std::uint64_t v) { return raw(&v, 8); }
  Bytes& i32(std::int32_t v) { return raw(&v, 4); }
  Bytes& f32(float v) { return raw(&v, 4); }
  Bytes& f64(double v) { return raw(&v, 8); }
  Bytes& str(const std::string& s) { return u32(static_cast<std::uint32_t>(s.size())).add(s); }
  Bytes& add(const std::string& s) {
    data += s;
    return *this;
  }
  Bytes& raw(const void* p, std::size_t n) {
    data.append(static_cast<const char*>(p), n);
    return *this;
  }
};

// CDR (little endian) alignment counts from after the 4-byte encapsulation header.
struct Cdr {
  Bytes b;
  Cdr() { b.add(std::string("\0\1\0\0", 4)); }
  void align(std::size_t n) {
    while ((b.data.size() - 4) % n != 0) b.u8(0);
  }
  Cdr& u32(std::uint32_t v) { return align(4), b.u32(v), *this; }
  Cdr& i32(std::int32_t v) { return align(4), b.i32(v), *this; }
  Cdr& f32(float v) { return align(4), b.f32(v), *this; }
  Cdr& f64(double v) { return align(8), b.f64(v), *this; }
  Cdr& str(const std::string& s) {
    u32(static_cast<std::uint32_t>(s.size() + 1));
    b.add(s).u8(0);
    return *this;
  }
  Cdr& header(double stamp, const std::string& frame) {
    return i32(static_cast<std::int32_t>(stamp))
        .u32(static_cast<std::uint32_t>((stamp - std::floor(stamp)) * 1e9))
        .str(frame);
  }
};

std::string laser_scan(double stamp, const std::vector<float>& ranges) {
  Cdr c;
  c.header(stamp, "base_link").f32(-1.0F).f32(1.0F).f32(2.0F / static_cast<float>(ranges.size() - 1)).f32(0).f32(0.1F);
  c.f32(0.05F).f32(10.0F).u32(static_cast<std::uint32_t>(ranges.size()));
  for (const float r : ranges) c.f32(r);
  c.u32(0);
  return c.b.data;
}

std::string odometry(double stamp, double x, double y, double yaw) {
  Cdr c;
  c.header(stamp, "odom")
      .str("base_link")
      .f64(x)
      .f64(y)
      .f64(0)
      .f64(0)
      .f64(0)
      .f64(std::sin(yaw / 2))
      .f64(std::cos(yaw / 2));
  for (int i = 0; i < 36 + 6 + 36; ++i) c.f64(0);
  return c.b.data;
}

std::string record(std::uint8_t opcode, const std::string& body) {
  return Bytes().u8(opcode).u64(body.size()).add(body).data;
}
std::string schema(std::uint16_t id, const std::string& name) {
  return record(0x03, Bytes().u16(id).str(name).str("ros2msg").str("").data);
}
std::string channel(std::uint16_t id, std::uint16_t schema_id, const std::string& topic) {
  return record(0x04, Bytes().u16(id).u16(schema_id).str(topic).str("cdr").u32(0).data);
}
std::string message(std::uint16_t channel_id, double stamp, const std::string& data) {
  const auto ns = static_cast<std::uint64_t>(stamp * 1e9);
  return record(0x05, Bytes().u16(channel_id).u32(0).u64(ns).u64(ns).add(data).data);
}
std::string chunk(const std::string& records, bool with_crc) {
  const auto crc = with_crc ? static_cast<std::uint32_t>(crc32(0, reinterpret_cast<const Bytef*>(records.data()),
                                                               static_cast<uInt>(records.size())))
                            : 0U;
  return record(0x06, Bytes().u64(0).u64(0).u64(records.size()).u32(crc).str("").u64(records.size()).add(records).data);
}
std::string file(const std::string& records) {
  const std::string magic(mcap::kMagic);
  return magic + record(0x01, Bytes().str("ros2").str("test").data) + records +
         record(0x02, Bytes().u64(0).u64(0).u32(0).data) + magic;
}

// Two scans on /scan with odometry on /odom, the second pair inside a chunk.
std::string good_bag() {
  const std::string plain = schema(1, "sensor_msgs/msg/LaserScan") + schema(2, "nav_msgs/msg/Odometry") +
                            channel(1, 1, "/scan") + channel(2, 2, "/odom") +
                            message(2, 1.0, odometry(1.0, 1, 2, 0.5)) + message(1, 1.0, laser_scan(1.0, {1, 2, 3}));
  return file(plain +
              chunk(message(2, 1.5, odometry(1.5, 3, 4, 0)) + message(1, 1.5, laser_scan(1.5, {4, 20, 6})), true));
}

std::unique_ptr<ScanSource> source_of(const std::string& bytes, Diagnostics& diagnostics, McapOptions options = {}) {
  auto reader = std::make_unique<McapReader>(std::make_unique<std::istringstream>(bytes), "bag.mcap", bytes.size());
  return open_mcap_source(std::move(reader), options, diagnostics, nullptr);
}

std::vector<ScanRecord> all_scans(const std::string& bytes, McapOptions options = {}) {
  Diagnostics diagnostics;
  auto source = source_of(bytes, diagnostics, std::move(options));
  std::vector<ScanRecord> scans;
  while (auto scan = source->next()) scans.push_back(std::move(*scan));
  return scans;
}

std::string error_of(const std::string& bytes, McapOptions options = {}) {
  try {
    all_scans(bytes, std::move(options));
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "no error";
}

TEST(McapReader, ReadsScansWithTheirOdometryPosesFromPlainRecordsAndChunks) {
  const auto scans = all_scans(good_bag());
  ASSERT_EQ(scans.size(), 2U);
  EXPECT_DOUBLE_EQ(scans[0].X_WB.x, 1.0);
  EXPECT_DOUBLE_EQ(scans[0].X_WB.y, 2.0);
  EXPECT_NEAR(scans[0].X_WB.theta, 0.5, 1e-12);
  EXPECT_NEAR(*scans[0].stamp_s, 1.0, 1e-9);
  EXPECT_FLOAT_EQ(scans[0].ranges_m[2], 3.0F);
  EXPECT_DOUBLE_EQ(scans[1].X_WB.x, 3.0);
  EXPECT_TRUE(std::isinf(scans[1].ranges_m[1])) << "20 m is past range_max 10: no return";
  EXPECT_NEAR(scans[1].angle_min_rad, -1.0, 1e-6);
  EXPECT_NEAR(*scans[1].sensor_range_max_m, 10.0, 1e-6);
}

TEST(McapReader, LaserPoseOptionPlacesTheLaserAndAnUpsideDownMountMirrorsTheScan) {
  McapOptions options;
  options.laser_pose = std::array<double, 6>{0.2, 0.1, 0.3, M_PI, 0.0, 0.0};
  const auto scans = all_scans(good_bag(), options);
  ASSERT_EQ(scans.size(), 2U);
  EXPECT_DOUBLE_EQ(scans[0].X_BS.x, 0.2);
  EXPECT_DOUBLE_EQ(scans[0].X_BS.y, 0.1);
  EXPECT_FLOAT_EQ(scans[0].ranges_m[0], 3.0F) << "upside down, the last beam comes first";
  EXPECT_NEAR(scans[0].angle_min_rad, -1.0, 1e-6);
}

TEST(McapReader, BadMagicIsRefusedAtOffsetZero) {
  std::string bytes = good_bag();
  bytes[1] = 'N';
  EXPECT_EQ(error_of(bytes), "bag.mcap: offset 0: not an MCAP file (bad magic)");
}

TEST(McapReader, ChunkWithAWrongCrcIsRefusedBeforeAnyOfItsMessages) {
  std::string bytes = good_bag();
  bytes[bytes.size() - 40] = static_cast<char>(bytes[bytes.size() - 40] ^ 1);  // inside the last scan's ranges
  Diagnostics diagnostics;
  auto source = source_of(bytes, diagnostics);
  ASSERT_TRUE(source->next()) << "the first scan is outside the chunk";
  try {
    source->next();
    FAIL() << "the corrupt chunk was read";
  } catch (const McapError& e) {
    EXPECT_NE(std::string(e.what()).find("chunk CRC mismatch"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("offset " + std::to_string(e.offset())), std::string::npos);
    EXPECT_EQ(bytes[e.offset()], '\x06') << "the offset is the Chunk record's";
  }
}

TEST(McapReader, RecordCutShortAndMissingFooterAreErrors) {
  const std::string bytes = good_bag();
  EXPECT_NE(error_of(bytes.substr(0, bytes.size() - 100)).find("Chunk record cut short"), std::string::npos);
  EXPECT_NE(error_of(bytes.substr(0, bytes.size() - 8)).find("file cut short: the closing magic"), std::string::npos);
  const std::size_t footer = bytes.size() - 8 - 29;
  EXPECT_NE(error_of(bytes.substr(0, footer)).find("file ends without a Footer record"), std::string::npos);
}

TEST(McapReader, ShortCdrMessageNamesItsTopicOffsetAndField) {
  const std::string scan = laser_scan(1.0, {1, 2, 3});
  const std::string records = schema(1, "sensor_msgs/msg/LaserScan") + channel(1, 1, "/scan");
  const std::string bytes = file(records + message(1, 1.0, scan.substr(0, scan.size() - 10)));
  const std::string error = error_of(bytes);
  const std::size_t offset = 8 + record(0x01, Bytes().str("ros2").str("test").data).size() + records.size();
  EXPECT_NE(error.find("offset " + std::to_string(offset) + ": topic '/scan' (sensor_msgs/msg/LaserScan)"),
            std::string::npos)
      << error;
  EXPECT_NE(error.find("ranges"), std::string::npos) << error;
}

TEST(McapReader, ATopicOfAnotherTypeIsRefusedByNameAndWithoutScansTheUnsupportedTopicsAreListed) {
  McapOptions options;
  options.topic_scan = "/odom";
  const std::string wrong = error_of(good_bag(), options);
  EXPECT_NE(wrong.find("topic '/odom' is of type 'nav_msgs/msg/Odometry'"), std::string::npos) << wrong;
  EXPECT_NE(wrong.find("offset "), std::string::npos) << wrong;
  const std::string only_images =
      file(schema(1, "sensor_msgs/msg/Image") + channel(1, 1, "/camera") + message(1, 1.0, std::string(8, '\0')));
  const std::string none = error_of(only_images);
  EXPECT_NE(none.find("no sensor_msgs/msg/LaserScan topic"), std::string::npos) << none;
  EXPECT_NE(none.find("/camera (sensor_msgs/msg/Image)"), std::string::npos) << none;
}

TEST(CdrDecoders, PointCloud2KeepsXyzFloatFieldsAndSkipsOthers) {
  Cdr c;
  c.header(2.0, "lidar").u32(1).u32(2).u32(4);
  const char* names[] = {"x", "y", "z", "intensity"};
  for (std::uint32_t k = 0; k < 4; ++k) {
    c.str(names[k]).u32(4 * k);
    c.b.u8(7);
    c.u32(1);
  }
  c.b.u8(0);
  c.u32(16).u32(32).u32(32);
  for (const float v : {1.F, 2.F, 3.F, 9.F, 4.F, NAN, 6.F, 9.F}) c.b.f32(v);
  c.b.u8(1);
  const RosPointCloud cloud = decode_point_cloud2(c.b.data);
  EXPECT_EQ(cloud.xyz, (std::vector<float>{1, 2, 3})) << "the point with a NaN is dropped";
  EXPECT_THROW(decode_point_cloud2(c.b.data.substr(0, c.b.data.size() - 20)), CdrError);
}

TEST(CdrDecoders, TfMessageGivesEachTransform) {
  Cdr c;
  c.u32(1).header(3.0, "odom").str("base_link").f64(1).f64(2).f64(0).f64(0).f64(0).f64(0).f64(1);
  const auto transforms = decode_tf_message(c.b.data);
  ASSERT_EQ(transforms.size(), 1U);
  EXPECT_EQ(transforms[0].header.frame_id, "odom");
  EXPECT_EQ(transforms[0].child_frame_id, "base_link");
  EXPECT_DOUBLE_EQ(transforms[0].transform.y, 2.0);
  EXPECT_THROW(decode_tf_message(std::string("\0\1\0\0\xff\xff\xff\x0f", 8)), CdrError) << "count past the end";
}

}  // namespace
}  // namespace occgeo::replay
