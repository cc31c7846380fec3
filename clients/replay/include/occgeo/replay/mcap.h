#pragma once

#include <cstdint>
#include <filesystem>
#include <istream>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace occgeo::replay {

// A damaged or unsupported MCAP file: the message names the file and the byte offset of the record at fault.
class McapError : public std::runtime_error {
 public:
  McapError(const std::string& message, std::uint64_t offset) : std::runtime_error(message), offset_(offset) {}
  [[nodiscard]] std::uint64_t offset() const { return offset_; }

 private:
  std::uint64_t offset_;
};

struct McapSchema {
  std::uint16_t id = 0;
  std::string name;      // e.g. "sensor_msgs/msg/LaserScan"
  std::string encoding;  // e.g. "ros2msg", "protobuf"
  std::string data;
};

struct McapChannel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;  // e.g. "cdr", "protobuf"
};

// One message; `data` stays valid until the next call to McapReader::next().
struct McapMessage {
  const McapChannel* channel = nullptr;
  const McapSchema* schema = nullptr;  // nullptr for a schemaless channel
  std::uint64_t log_time_ns = 0;
  std::uint64_t publish_time_ns = 0;
  // File offset of the Message record, or of its Chunk record when the message is inside a chunk.
  std::uint64_t offset = 0;
  std::string_view data;
};

// Reads an MCAP file front to back (the data section; the summary is not needed for that): magic, records, chunks
// compressed with zstd or lz4 or not at all, each chunk's CRC checked before any of its messages is returned.
// Anything damaged throws McapError naming the file and offset.
class McapReader {
 public:
  explicit McapReader(const std::filesystem::path& path);
  // Reads from `input` of `size` bytes; `name` is used in error messages.
  McapReader(std::unique_ptr<std::istream> input, std::string name, std::uint64_t size);
  ~McapReader();
  McapReader(const McapReader&) = delete;
  McapReader& operator=(const McapReader&) = delete;

  // The next message in file order, or nullopt after the footer and closing magic.
  std::optional<McapMessage> next();

  [[nodiscard]] const std::string& profile() const { return profile_; }
  [[nodiscard]] const std::string& name() const { return name_; }
  // Fraction of the file consumed, 0..1.
  [[nodiscard]] double progress() const;

 private:
  [[noreturn]] void fail(const std::string& what, std::uint64_t offset) const;
  void read_exact(char* out, std::uint64_t count, std::uint64_t record_offset, const char* what);
  // Handles one record of the data section or of a chunk; returns true when it was a message now in `message_`.
  bool take_record(std::uint8_t opcode, std::string_view body, std::uint64_t record_offset);
  void load_chunk(std::string_view body, std::uint64_t record_offset);

  std::unique_ptr<std::istream> input_;
  std::string name_;
  std::uint64_t size_ = 0;
  std::uint64_t position_ = 0;
  bool done_ = false;
  std::string profile_;
  std::map<std::uint16_t, McapSchema> schemas_;
  std::map<std::uint16_t, McapChannel> channels_;
  std::string record_;  // body of the record last read from the file
  std::string chunk_;   // records of the chunk being read, decompressed
  std::size_t chunk_position_ = 0;
  std::uint64_t chunk_offset_ = 0;
  bool in_chunk_ = false;
  McapMessage message_;
};

// Bounds-checked little-endian reads over a record body; throws McapError naming `what` when it runs out.
class McapFields {
 public:
  McapFields(std::string_view body, std::string file, std::uint64_t offset, std::string record)
      : body_(body), file_(std::move(file)), offset_(offset), record_(std::move(record)) {}
  std::uint8_t u8(const char* what);
  std::uint16_t u16(const char* what);
  std::uint32_t u32(const char* what);
  std::uint64_t u64(const char* what);
  std::string_view string(const char* what);   // uint32 length + bytes
  std::string_view bytes32(const char* what);  // uint32 length + bytes
  std::string_view bytes64(const char* what);  // uint64 length + bytes
  std::string_view rest() { return body_.substr(position_); }

 private:
  std::string_view take(std::uint64_t count, const char* what);
  std::string_view body_;
  std::string file_;
  std::uint64_t offset_;
  std::string record_;
  std::size_t position_ = 0;
};

// True when `path` starts with the MCAP magic.
bool is_mcap_file(const std::filesystem::path& path);

}  // namespace occgeo::replay
