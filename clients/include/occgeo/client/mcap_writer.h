#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace google::protobuf {
class Descriptor;
}

namespace occgeo::client {

enum class McapCompression { none, zstd, lz4 };

// "none" | "zstd" | "lz4"; throws std::invalid_argument naming the text otherwise.
McapCompression parse_mcap_compression(const std::string& text);

// Writes an MCAP file (https://mcap.dev/spec): magic, header, messages grouped in chunks (compressed with zstd or lz4,
// or not), each chunk followed by its message indexes; on close() a summary (schemas, channels, statistics, chunk
// indexes) with summary offsets and the footer, so readers can seek by time and channel. Schema and channel records
// go into the chunk where they are first needed, so a reader that streams the file front to back finds them before
// the messages. Throws std::runtime_error naming the file when it cannot be written.
class McapWriter {
 public:
  McapWriter(const std::filesystem::path& path, McapCompression compression, std::string library,
             std::size_t chunk_bytes = std::size_t{1} << 20);
  // Closes the file (summary and footer) if close() was not called; errors are swallowed here.
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  // Registers a schema; returns its id (1, 2, ...).
  std::uint16_t add_schema(const std::string& name, const std::string& encoding, const std::string& data);
  // Registers a channel of `schema_id` (0: no schema); returns its id (0, 1, ...).
  std::uint16_t add_channel(std::uint16_t schema_id, const std::string& topic, const std::string& message_encoding,
                            const std::map<std::string, std::string>& metadata = {});
  // One message; log_time_ns should not go backwards (message indexes are kept in write order).
  void write_message(std::uint16_t channel_id, std::uint64_t log_time_ns, std::uint64_t publish_time_ns,
                     std::string_view data);
  // Writes the last chunk, the summary and the footer. Further calls do nothing.
  void close();

  [[nodiscard]] std::uint64_t messages() const { return message_count_; }
  // Bytes in the file so far (the current chunk is counted once it is written).
  [[nodiscard]] std::uint64_t bytes() const { return offset_; }

 private:
  struct ChunkIndex {
    std::uint64_t start_time = 0, end_time = 0, offset = 0, length = 0;
    std::map<std::uint16_t, std::uint64_t> message_index_offsets;
    std::uint64_t message_index_length = 0, compressed_size = 0, uncompressed_size = 0;
  };
  void write_bytes(std::string_view bytes);
  void write_record(std::uint8_t opcode, std::string_view body);
  void flush_chunk();

  std::filesystem::path path_;
  std::ofstream out_;
  McapCompression compression_;
  std::size_t chunk_bytes_;
  std::uint64_t offset_ = 0;
  bool closed_ = false;

  std::vector<std::string> schema_records_;   // bodies, for the summary
  std::vector<std::string> channel_records_;  // bodies, for the summary
  std::map<std::uint16_t, std::uint64_t> channel_message_counts_;
  std::uint64_t message_count_ = 0;
  std::uint64_t start_time_ = 0, end_time_ = 0;

  std::string chunk_;  // uncompressed records of the open chunk
  std::uint64_t chunk_start_time_ = 0, chunk_end_time_ = 0;
  bool chunk_has_messages_ = false;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_index_;  // time, offset
  std::vector<ChunkIndex> chunk_indexes_;
};

// The FileDescriptorSet (serialised) of `descriptor`'s file and every file it imports: the schema data MCAP readers
// such as Foxglove decode protobuf channels with.
std::string file_descriptor_set(const google::protobuf::Descriptor& descriptor);

}  // namespace occgeo::client
