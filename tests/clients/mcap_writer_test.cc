// occgeo record's MCAP writer, read back by occgeo's own MCAP reader (the one `occgeo replay` uses) in every chunk
// compression, and its summary checked where readers that seek rely on it: the footer, the summary CRC, the
// statistics and the chunk indexes. (tests/ecosystem reads recordings with @mcap/core.)
#include <gtest/gtest.h>
#include <zlib.h>

#include <google/protobuf/descriptor.pb.h>
#include <unistd.h>

#include <fstream>
#include <iterator>
#include <map>
#include <string>

#include "occgeo/client/mcap_writer.h"
#include "occgeo/replay/mcap.h"
#include "occgeo/v1/sensors.pb.h"

namespace occgeo::client {
namespace {

struct TempFile {
  std::filesystem::path path;
  explicit TempFile(const std::string& name)
      : path(std::filesystem::temp_directory_path() / (name + "-" + std::to_string(::getpid()) + ".mcap")) {}
  ~TempFile() { std::filesystem::remove(path); }
};

std::string read_all(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

std::uint64_t le(const std::string& bytes, std::size_t at, int size) {
  std::uint64_t value = 0;
  for (int i = size - 1; i >= 0; --i)
    value = (value << 8) | static_cast<unsigned char>(bytes[at + static_cast<std::size_t>(i)]);
  return value;
}

// Writes 300 scans on one channel and 300 odometry messages on another with small chunks (several of them).
void write_session(const std::filesystem::path& path, McapCompression compression) {
  McapWriter writer(path, compression, "test", 4096);
  const auto scans = writer.add_channel(
      writer.add_schema("occgeo.v1.LaserScan", "protobuf", file_descriptor_set(*v1::LaserScan::descriptor())),
      "/default/bot/laser_scan", "protobuf", {{"robot_id", "bot"}});
  const auto odometry = writer.add_channel(
      writer.add_schema("occgeo.v1.Odometry", "protobuf", file_descriptor_set(*v1::Odometry::descriptor())),
      "/default/bot/odometry", "protobuf");
  for (std::uint64_t seq = 1; seq <= 300; ++seq) {
    v1::Odometry odom;
    odom.set_seq(seq);
    odom.mutable_pose()->set_x(0.01 * static_cast<double>(seq));
    writer.write_message(odometry, seq * 1000, seq * 1000, odom.SerializeAsString());
    v1::LaserScan scan;
    scan.set_seq(seq);
    scan.set_sensor("front_laser");
    for (int i = 0; i < 50; ++i) scan.add_ranges(static_cast<float>(seq) + static_cast<float>(i));
    writer.write_message(scans, seq * 1000 + 1, seq * 1000 + 1, scan.SerializeAsString());
  }
  writer.close();
}

class McapWriterCompressions : public ::testing::TestWithParam<McapCompression> {};

TEST_P(McapWriterCompressions, OurReaderGetsEveryMessageBackInOrderWithItsSchemaAndTopic) {
  TempFile file("mcap-writer");
  write_session(file.path, GetParam());
  replay::McapReader reader(file.path);
  std::uint64_t scans = 0, odometry = 0;
  std::uint64_t last_time = 0;
  while (const auto message = reader.next()) {
    ASSERT_NE(message->schema, nullptr);
    EXPECT_EQ(message->schema->encoding, "protobuf");
    EXPECT_EQ(message->channel->message_encoding, "protobuf");
    EXPECT_GE(message->log_time_ns, last_time);
    last_time = message->log_time_ns;
    if (message->channel->topic == "/default/bot/laser_scan") {
      EXPECT_EQ(message->schema->name, "occgeo.v1.LaserScan");
      v1::LaserScan scan;
      ASSERT_TRUE(scan.ParseFromArray(message->data.data(), static_cast<int>(message->data.size())));
      EXPECT_EQ(scan.seq(), ++scans);
      ASSERT_EQ(scan.ranges_size(), 50);
      EXPECT_EQ(scan.ranges(49), static_cast<float>(scans) + 49.0F);
    } else {
      EXPECT_EQ(message->channel->topic, "/default/bot/odometry");
      v1::Odometry odom;
      ASSERT_TRUE(odom.ParseFromArray(message->data.data(), static_cast<int>(message->data.size())));
      EXPECT_EQ(odom.seq(), ++odometry);
    }
  }
  EXPECT_EQ(scans, 300U);
  EXPECT_EQ(odometry, 300U);
}

TEST_P(McapWriterCompressions, TheSummaryLocatesItsGroupsAndCountsWhatWasWritten) {
  TempFile file("mcap-summary");
  write_session(file.path, GetParam());
  const std::string bytes = read_all(file.path);
  ASSERT_GT(bytes.size(), 8U + 28U + 8U);
  ASSERT_EQ(bytes.substr(bytes.size() - 8), std::string("\x89MCAP0\r\n", 8));
  const std::size_t footer = bytes.size() - 8 - 29;
  ASSERT_EQ(bytes[footer], 0x02);
  const std::uint64_t summary_start = le(bytes, footer + 9, 8);
  const std::uint64_t summary_offset_start = le(bytes, footer + 17, 8);
  const auto crc = static_cast<std::uint32_t>(le(bytes, footer + 25, 4));
  const uLong expected = ::crc32(0L, reinterpret_cast<const Bytef*>(bytes.data() + summary_start),
                                 static_cast<uInt>(footer + 25 - summary_start));
  EXPECT_EQ(crc, static_cast<std::uint32_t>(expected));
  // Walk the summary: 2 schemas, 2 channels, statistics, one chunk index per chunk (each pointing at a Chunk record).
  std::map<int, int> records;
  std::uint64_t statistics_messages = 0;
  std::uint32_t statistics_chunks = 0;
  for (std::size_t at = summary_start; at < summary_offset_start;) {
    const int opcode = static_cast<unsigned char>(bytes[at]);
    const std::uint64_t length = le(bytes, at + 1, 8);
    ++records[opcode];
    if (opcode == 0x0B) {
      statistics_messages = le(bytes, at + 9, 8);
      statistics_chunks = static_cast<std::uint32_t>(le(bytes, at + 9 + 8 + 2 + 4 + 4 + 4, 4));
    }
    if (opcode == 0x08) {
      const std::uint64_t chunk_offset = le(bytes, at + 9 + 16, 8);
      EXPECT_EQ(bytes[chunk_offset], 0x06) << "a chunk index points at no chunk";
    }
    at += 9 + length;
  }
  EXPECT_EQ(records[0x03], 2);
  EXPECT_EQ(records[0x04], 2);
  EXPECT_EQ(records[0x0B], 1);
  EXPECT_EQ(statistics_messages, 600U);
  EXPECT_GT(statistics_chunks, 1U);
  EXPECT_EQ(records[0x08], static_cast<int>(statistics_chunks));
}

INSTANTIATE_TEST_SUITE_P(Compressions, McapWriterCompressions,
                         ::testing::Values(McapCompression::none, McapCompression::zstd, McapCompression::lz4),
                         [](const ::testing::TestParamInfo<McapCompression>& param_info) {
                           switch (param_info.param) {
                             case McapCompression::zstd:
                               return std::string("zstd");
                             case McapCompression::lz4:
                               return std::string("lz4");
                             case McapCompression::none:
                               break;
                           }
                           return std::string("none");
                         });

TEST(McapWriter, FileDescriptorSetCarriesTheTypeAndItsImports) {
  google::protobuf::FileDescriptorSet set;
  ASSERT_TRUE(set.ParseFromString(file_descriptor_set(*v1::Odometry::descriptor())));
  ASSERT_EQ(set.file_size(), 2);
  EXPECT_EQ(set.file(0).name(), "occgeo/v1/common.proto");  // imported first
  EXPECT_EQ(set.file(1).name(), "occgeo/v1/sensors.proto");
}

TEST(McapWriter, UnknownCompressionIsRefusedByName) {
  EXPECT_THROW(parse_mcap_compression("gzip"), std::invalid_argument);
  EXPECT_EQ(parse_mcap_compression("lz4"), McapCompression::lz4);
}

}  // namespace
}  // namespace occgeo::client
