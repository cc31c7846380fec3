#include "occgeo/client/mcap_writer.h"

#include "occgeo/client/mcap_format.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>
#include <lz4frame.h>
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <set>
#include <stdexcept>

namespace occgeo::client {
namespace {

using namespace mcap;  // opcodes and magic

// Little-endian field encoders.
void put_u8(std::string& out, std::uint8_t v) { out.push_back(static_cast<char>(v)); }
void put_u16(std::string& out, std::uint16_t v) {
  for (int i = 0; i < 2; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
void put_u32(std::string& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
void put_u64(std::string& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
void put_string(std::string& out, std::string_view s) {
  put_u32(out, static_cast<std::uint32_t>(s.size()));
  out.append(s);
}
std::string record(std::uint8_t opcode, std::string_view body) {
  std::string out;
  out.reserve(9 + body.size());
  put_u8(out, opcode);
  put_u64(out, body.size());
  out.append(body);
  return out;
}

std::uint32_t crc32_of(std::string_view bytes, std::uint32_t crc = 0) {
  uLong value = crc;
  std::size_t done = 0;
  while (done < bytes.size()) {
    const auto piece = static_cast<uInt>(std::min<std::size_t>(bytes.size() - done, 1U << 30));
    value = ::crc32(value, reinterpret_cast<const Bytef*>(bytes.data() + done), piece);
    done += piece;
  }
  return static_cast<std::uint32_t>(value);
}

std::string compress(McapCompression compression, const std::string& records) {
  if (compression == McapCompression::zstd) {
    std::string out(ZSTD_compressBound(records.size()), '\0');
    const std::size_t size = ZSTD_compress(out.data(), out.size(), records.data(), records.size(), 3);
    if (ZSTD_isError(size) != 0U) throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(size));
    out.resize(size);
    return out;
  }
  if (compression == McapCompression::lz4) {
    std::string out(LZ4F_compressFrameBound(records.size(), nullptr), '\0');
    const std::size_t size = LZ4F_compressFrame(out.data(), out.size(), records.data(), records.size(), nullptr);
    if (LZ4F_isError(size) != 0U) throw std::runtime_error(std::string("lz4: ") + LZ4F_getErrorName(size));
    out.resize(size);
    return out;
  }
  return records;
}

const char* compression_name(McapCompression compression) {
  switch (compression) {
    case McapCompression::zstd:
      return "zstd";
    case McapCompression::lz4:
      return "lz4";
    case McapCompression::none:
      break;
  }
  return "";
}

}  // namespace

McapCompression parse_mcap_compression(const std::string& text) {
  if (text == "zstd") return McapCompression::zstd;
  if (text == "lz4") return McapCompression::lz4;
  if (text == "none") return McapCompression::none;
  throw std::invalid_argument("--compression must be zstd, lz4 or none, not '" + text + "'");
}

McapWriter::McapWriter(const std::filesystem::path& path, McapCompression compression, std::string library,
                       std::size_t chunk_bytes)
    : path_(path),
      out_(path, std::ios::binary | std::ios::trunc),
      compression_(compression),
      chunk_bytes_(chunk_bytes) {
  if (!out_) throw std::runtime_error("cannot open '" + path.string() + "' for writing");
  write_bytes(kMagic);
  std::string header;
  put_string(header, "");  // profile: none of the registered ones (ros1, ros2) applies
  put_string(header, library);
  write_record(kHeader, header);
}

McapWriter::~McapWriter() {
  try {
    close();
  } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor must not throw; close() reports to callers that ask
  }
}

void McapWriter::write_bytes(std::string_view bytes) {
  out_.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out_) throw std::runtime_error("cannot write to '" + path_.string() + "'");
  offset_ += bytes.size();
}

void McapWriter::write_record(std::uint8_t opcode, std::string_view body) { write_bytes(record(opcode, body)); }

std::uint16_t McapWriter::add_schema(const std::string& name, const std::string& encoding, const std::string& data) {
  const auto id = static_cast<std::uint16_t>(schema_records_.size() + 1);
  std::string body;
  put_u16(body, id);
  put_string(body, name);
  put_string(body, encoding);
  put_string(body, data);
  chunk_ += record(kSchema, body);
  schema_records_.push_back(std::move(body));
  return id;
}

std::uint16_t McapWriter::add_channel(std::uint16_t schema_id, const std::string& topic,
                                      const std::string& message_encoding,
                                      const std::map<std::string, std::string>& metadata) {
  const auto id = static_cast<std::uint16_t>(channel_records_.size() + 1);
  std::string body;
  put_u16(body, id);
  put_u16(body, schema_id);
  put_string(body, topic);
  put_string(body, message_encoding);
  std::string pairs;
  for (const auto& [key, value] : metadata) {
    put_string(pairs, key);
    put_string(pairs, value);
  }
  put_string(body, pairs);
  chunk_ += record(kChannel, body);
  channel_records_.push_back(std::move(body));
  channel_message_counts_[id];  // listed in the statistics even when it never carries a message
  return id;
}

void McapWriter::write_message(std::uint16_t channel_id, std::uint64_t log_time_ns, std::uint64_t publish_time_ns,
                               std::string_view data) {
  if (closed_) throw std::logic_error("write_message after close");
  std::string body;
  body.reserve(22 + data.size());
  put_u16(body, channel_id);
  put_u32(body, static_cast<std::uint32_t>(channel_message_counts_[channel_id]));  // per-channel sequence
  put_u64(body, log_time_ns);
  put_u64(body, publish_time_ns);
  body.append(data);
  chunk_index_[channel_id].emplace_back(log_time_ns, chunk_.size());
  chunk_ += record(kMessage, body);
  if (!chunk_has_messages_) {
    chunk_start_time_ = chunk_end_time_ = log_time_ns;
    chunk_has_messages_ = true;
  }
  chunk_start_time_ = std::min(chunk_start_time_, log_time_ns);
  chunk_end_time_ = std::max(chunk_end_time_, log_time_ns);
  if (message_count_ == 0) start_time_ = end_time_ = log_time_ns;
  start_time_ = std::min(start_time_, log_time_ns);
  end_time_ = std::max(end_time_, log_time_ns);
  ++message_count_;
  ++channel_message_counts_[channel_id];
  if (chunk_.size() >= chunk_bytes_) flush_chunk();
}

void McapWriter::flush_chunk() {
  if (chunk_.empty()) return;
  const std::string compressed = compress(compression_, chunk_);
  std::string body;
  body.reserve(40 + compressed.size());
  put_u64(body, chunk_start_time_);
  put_u64(body, chunk_end_time_);
  put_u64(body, chunk_.size());
  put_u32(body, crc32_of(chunk_));
  put_string(body, compression_name(compression_));
  put_u64(body, compressed.size());
  body.append(compressed);

  ChunkIndex index;
  index.start_time = chunk_start_time_;
  index.end_time = chunk_end_time_;
  index.offset = offset_;
  index.compressed_size = compressed.size();
  index.uncompressed_size = chunk_.size();
  write_record(kChunk, body);
  index.length = offset_ - index.offset;
  const std::uint64_t indexes_start = offset_;
  for (const auto& [channel, entries] : chunk_index_) {
    std::string message_index;
    put_u16(message_index, channel);
    put_u32(message_index, static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [time, position] : entries) {
      put_u64(message_index, time);
      put_u64(message_index, position);
    }
    index.message_index_offsets[channel] = offset_;
    write_record(kMessageIndex, message_index);
  }
  index.message_index_length = offset_ - indexes_start;
  chunk_indexes_.push_back(std::move(index));
  chunk_.clear();
  chunk_index_.clear();
  chunk_has_messages_ = false;
  chunk_start_time_ = chunk_end_time_ = 0;
}

void McapWriter::close() {
  if (closed_) return;
  closed_ = true;
  flush_chunk();
  std::string data_end;
  put_u32(data_end, 0);  // no data section CRC: chunks carry their own
  write_record(kDataEnd, data_end);

  // Summary: one group per record kind, each located by a summary offset record.
  const std::uint64_t summary_start = offset_;
  std::string summary;
  std::vector<std::tuple<std::uint8_t, std::uint64_t, std::uint64_t>> groups;
  auto group = [&](std::uint8_t opcode, const std::vector<std::string>& bodies) {
    if (bodies.empty()) return;
    const std::uint64_t start = summary_start + summary.size();
    for (const auto& body : bodies) summary += record(opcode, body);
    groups.emplace_back(opcode, start, summary_start + summary.size() - start);
  };
  group(kSchema, schema_records_);
  group(kChannel, channel_records_);
  std::string statistics;
  put_u64(statistics, message_count_);
  put_u16(statistics, static_cast<std::uint16_t>(schema_records_.size()));
  put_u32(statistics, static_cast<std::uint32_t>(channel_records_.size()));
  put_u32(statistics, 0);  // attachments
  put_u32(statistics, 0);  // metadata
  put_u32(statistics, static_cast<std::uint32_t>(chunk_indexes_.size()));
  put_u64(statistics, start_time_);
  put_u64(statistics, end_time_);
  std::string counts;
  for (const auto& [channel, count] : channel_message_counts_) {
    put_u16(counts, channel);
    put_u64(counts, count);
  }
  put_string(statistics, counts);
  group(kStatistics, {statistics});
  std::vector<std::string> chunk_index_bodies;
  for (const ChunkIndex& index : chunk_indexes_) {
    std::string body;
    put_u64(body, index.start_time);
    put_u64(body, index.end_time);
    put_u64(body, index.offset);
    put_u64(body, index.length);
    std::string offsets;
    for (const auto& [channel, offset] : index.message_index_offsets) {
      put_u16(offsets, channel);
      put_u64(offsets, offset);
    }
    put_string(body, offsets);
    put_u64(body, index.message_index_length);
    put_string(body, compression_name(compression_));
    put_u64(body, index.compressed_size);
    put_u64(body, index.uncompressed_size);
    chunk_index_bodies.push_back(std::move(body));
  }
  group(kChunkIndex, chunk_index_bodies);
  const std::uint64_t summary_offset_start = summary_start + summary.size();
  for (const auto& [opcode, start, length] : groups) {
    std::string body;
    put_u8(body, opcode);
    put_u64(body, start);
    put_u64(body, length);
    summary += record(kSummaryOffset, body);
  }
  // The footer's CRC covers the summary through the footer's summary_offset_start field.
  std::string footer;
  put_u8(footer, kFooter);
  put_u64(footer, 20);
  put_u64(footer, summary_start);
  put_u64(footer, summary_offset_start);
  const std::uint32_t crc = crc32_of(footer, crc32_of(summary));
  put_u32(footer, crc);
  write_bytes(summary);
  write_bytes(footer);
  write_bytes(kMagic);
  out_.flush();
  if (!out_) throw std::runtime_error("cannot write to '" + path_.string() + "'");
  out_.close();
}

std::string file_descriptor_set(const google::protobuf::Descriptor& descriptor) {
  google::protobuf::FileDescriptorSet set;
  std::set<std::string> added;
  // Imports first, each file once: the order protoc itself writes a set in.
  auto add = [&](auto&& self, const google::protobuf::FileDescriptor* file) -> void {
    if (!added.insert(std::string(file->name())).second) return;
    for (int i = 0; i < file->dependency_count(); ++i) self(self, file->dependency(i));
    file->CopyTo(set.add_file());
  };
  add(add, descriptor.file());
  return set.SerializeAsString();
}

}  // namespace occgeo::client
