#include "occgeo/replay/mcap.h"

#include "occgeo/client/mcap_format.h"

#include <lz4frame.h>
#include <zlib.h>
#include <zstd.h>

#include <cstring>
#include <fstream>

namespace occgeo::replay {
namespace {

using namespace mcap;  // opcodes and magic
constexpr std::uint64_t kRecordPrefix = kRecordPrefixBytes;
// Largest chunk we decompress: guards memory against a forged uncompressed_size.
constexpr std::uint64_t kMaxChunkBytes = std::uint64_t{1} << 31;

std::uint64_t le(const char* p, int bytes) {
  std::uint64_t value = 0;
  for (int i = bytes - 1; i >= 0; --i) value = (value << 8) | static_cast<std::uint8_t>(p[i]);
  return value;
}

std::string opcode_name(std::uint8_t opcode) {
  switch (opcode) {
    case kHeader:
      return "Header";
    case kFooter:
      return "Footer";
    case kSchema:
      return "Schema";
    case kChannel:
      return "Channel";
    case kMessage:
      return "Message";
    case kChunk:
      return "Chunk";
    default:
      return "record 0x" + std::to_string(opcode);
  }
}

std::uint32_t crc32_of(std::string_view bytes) {
  uLong crc = ::crc32(0L, Z_NULL, 0);
  std::size_t done = 0;
  while (done < bytes.size()) {
    const auto piece = static_cast<uInt>(std::min<std::size_t>(bytes.size() - done, 1U << 30));
    crc = ::crc32(crc, reinterpret_cast<const Bytef*>(bytes.data() + done), piece);
    done += piece;
  }
  return static_cast<std::uint32_t>(crc);
}

}  // namespace

std::string_view McapFields::take(std::uint64_t count, const char* what) {
  if (count > body_.size() - position_) {
    throw McapError(file_ + ": offset " + std::to_string(offset_) + ": " + record_ + " record cut short: " + what +
                        " needs " + std::to_string(count) + " byte(s), " + std::to_string(body_.size() - position_) +
                        " left",
                    offset_);
  }
  const auto out = body_.substr(position_, static_cast<std::size_t>(count));
  position_ += static_cast<std::size_t>(count);
  return out;
}

std::uint8_t McapFields::u8(const char* what) { return static_cast<std::uint8_t>(le(take(1, what).data(), 1)); }
std::uint16_t McapFields::u16(const char* what) { return static_cast<std::uint16_t>(le(take(2, what).data(), 2)); }
std::uint32_t McapFields::u32(const char* what) { return static_cast<std::uint32_t>(le(take(4, what).data(), 4)); }
std::uint64_t McapFields::u64(const char* what) { return le(take(8, what).data(), 8); }
std::string_view McapFields::string(const char* what) { return take(u32(what), what); }
std::string_view McapFields::bytes32(const char* what) { return take(u32(what), what); }
std::string_view McapFields::bytes64(const char* what) { return take(u64(what), what); }

McapReader::McapReader(const std::filesystem::path& path) : name_(path.string()) {
  auto file = std::make_unique<std::ifstream>(path, std::ios::binary);
  if (!*file) throw std::runtime_error("cannot open '" + name_ + "'");
  std::error_code ec;
  size_ = std::filesystem::file_size(path, ec);
  if (ec) throw std::runtime_error("cannot read the size of '" + name_ + "': " + ec.message());
  input_ = std::move(file);
  char magic[8];
  read_exact(magic, 8, 0, "the opening magic");
  if (std::string_view(magic, 8) != kMagic) fail("not an MCAP file (bad magic)", 0);
}

McapReader::McapReader(std::unique_ptr<std::istream> input, std::string name, std::uint64_t size)
    : input_(std::move(input)), name_(std::move(name)), size_(size) {
  char magic[8];
  read_exact(magic, 8, 0, "the opening magic");
  if (std::string_view(magic, 8) != kMagic) fail("not an MCAP file (bad magic)", 0);
}

McapReader::~McapReader() = default;

void McapReader::fail(const std::string& what, std::uint64_t offset) const {
  throw McapError(name_ + ": offset " + std::to_string(offset) + ": " + what, offset);
}

void McapReader::read_exact(char* out, std::uint64_t count, std::uint64_t record_offset, const char* what) {
  if (count > size_ - std::min(size_, position_)) {
    fail(std::string("file cut short: ") + what + " needs " + std::to_string(count) + " byte(s), " +
             std::to_string(size_ - std::min(size_, position_)) + " left",
         record_offset);
  }
  input_->read(out, static_cast<std::streamsize>(count));
  if (static_cast<std::uint64_t>(input_->gcount()) != count) {
    fail(std::string("file cut short while reading ") + what, record_offset);
  }
  position_ += count;
}

double McapReader::progress() const {
  return size_ == 0 ? 1.0 : std::min(1.0, static_cast<double>(position_) / static_cast<double>(size_));
}

std::optional<McapMessage> McapReader::next() {
  for (;;) {
    if (in_chunk_) {
      if (chunk_position_ >= chunk_.size()) {
        in_chunk_ = false;
        continue;
      }
      const std::string_view rest = std::string_view(chunk_).substr(chunk_position_);
      if (rest.size() < kRecordPrefix)
        fail("record inside the chunk cut short (no room for its header)", chunk_offset_);
      const auto opcode = static_cast<std::uint8_t>(rest[0]);
      const std::uint64_t length = le(rest.data() + 1, 8);
      if (length > rest.size() - kRecordPrefix) {
        fail(opcode_name(opcode) + " record inside the chunk cut short: needs " + std::to_string(length) +
                 " byte(s), " + std::to_string(rest.size() - kRecordPrefix) + " left",
             chunk_offset_);
      }
      chunk_position_ += kRecordPrefix + static_cast<std::size_t>(length);
      if (take_record(opcode, rest.substr(kRecordPrefix, static_cast<std::size_t>(length)), chunk_offset_)) {
        return message_;
      }
      continue;
    }
    if (done_) return std::nullopt;
    const std::uint64_t offset = position_;
    if (position_ == size_) fail("file ends without a Footer record (truncated)", offset);
    char prefix[kRecordPrefix];
    read_exact(prefix, kRecordPrefix, offset, "a record header");
    const auto opcode = static_cast<std::uint8_t>(prefix[0]);
    const std::uint64_t length = le(prefix + 1, 8);
    if (length > size_ - position_) {
      fail(opcode_name(opcode) + " record cut short: needs " + std::to_string(length) + " byte(s), " +
               std::to_string(size_ - position_) + " left in the file",
           offset);
    }
    record_.resize(static_cast<std::size_t>(length));
    read_exact(record_.data(), length, offset, "a record");
    if (opcode == kFooter) {
      char magic[8];
      read_exact(magic, 8, position_, "the closing magic");
      if (std::string_view(magic, 8) != kMagic) fail("bad closing magic after the Footer", position_ - 8);
      done_ = true;
      return std::nullopt;
    }
    if (take_record(opcode, record_, offset)) return message_;
  }
}

bool McapReader::take_record(std::uint8_t opcode, std::string_view body, std::uint64_t record_offset) {
  McapFields fields(body, name_, record_offset, opcode_name(opcode));
  switch (opcode) {
    case kHeader:
      profile_ = std::string(fields.string("profile"));
      return false;
    case kSchema: {
      McapSchema schema;
      schema.id = fields.u16("schema id");
      schema.name = std::string(fields.string("schema name"));
      schema.encoding = std::string(fields.string("schema encoding"));
      schema.data = std::string(fields.bytes32("schema data"));
      if (schema.id == 0) fail("Schema record with the reserved id 0", record_offset);
      schemas_[schema.id] = std::move(schema);
      return false;
    }
    case kChannel: {
      McapChannel channel;
      channel.id = fields.u16("channel id");
      channel.schema_id = fields.u16("channel schema id");
      channel.topic = std::string(fields.string("channel topic"));
      channel.message_encoding = std::string(fields.string("channel message encoding"));
      fields.bytes32("channel metadata");
      if (channel.schema_id != 0 && schemas_.count(channel.schema_id) == 0) {
        fail("channel '" + channel.topic + "' names schema " + std::to_string(channel.schema_id) +
                 ", which no earlier Schema record defines",
             record_offset);
      }
      channels_[channel.id] = std::move(channel);
      return false;
    }
    case kMessage: {
      const std::uint16_t channel_id = fields.u16("message channel id");
      fields.u32("message sequence");
      message_.log_time_ns = fields.u64("message log time");
      message_.publish_time_ns = fields.u64("message publish time");
      message_.data = fields.rest();
      message_.offset = record_offset;
      const auto channel = channels_.find(channel_id);
      if (channel == channels_.end()) {
        fail("message on channel " + std::to_string(channel_id) + ", which no earlier Channel record defines",
             record_offset);
      }
      message_.channel = &channel->second;
      const auto schema = schemas_.find(channel->second.schema_id);
      message_.schema = schema == schemas_.end() ? nullptr : &schema->second;
      return true;
    }
    case kChunk:
      if (in_chunk_) fail("Chunk record inside a chunk", record_offset);
      load_chunk(body, record_offset);
      return false;
    default:
      return false;  // indexes, statistics, attachments, metadata: not needed to read the messages in order
  }
}

void McapReader::load_chunk(std::string_view body, std::uint64_t record_offset) {
  McapFields fields(body, name_, record_offset, "Chunk");
  fields.u64("chunk start time");
  fields.u64("chunk end time");
  const std::uint64_t uncompressed_size = fields.u64("chunk uncompressed size");
  const std::uint32_t expected_crc = fields.u32("chunk uncompressed crc");
  const std::string compression(fields.string("chunk compression"));
  const std::string_view records = fields.bytes64("chunk records");
  if (uncompressed_size > kMaxChunkBytes) {
    fail("chunk claims " + std::to_string(uncompressed_size) + " uncompressed bytes, more than the 2 GiB accepted",
         record_offset);
  }
  // The claim is checked against what the compressed bytes can hold before any memory is taken for it, so a damaged
  // or hostile size costs little: no compression holds exactly its size, an LZ4 frame at most 255 times its own
  // (the format's limit), and a zstd frame says its content size in its header.
  const std::uint64_t compressed_size = records.size();
  if (!compression.empty() && compression != "lz4" && compression != "zstd") {
    fail("chunk compression '" + compression + "' is not supported (none, lz4 or zstd)", record_offset);
  }
  if (compression.empty() && compressed_size != uncompressed_size) {
    fail("uncompressed chunk holds " + std::to_string(compressed_size) + " byte(s) but claims " +
             std::to_string(uncompressed_size),
         record_offset);
  }
  if (compression == "lz4" && uncompressed_size > 255 * compressed_size + 64) {
    fail("lz4 chunk of " + std::to_string(compressed_size) + " byte(s) cannot hold the " +
             std::to_string(uncompressed_size) + " it claims",
         record_offset);
  }
  if (compression == "zstd") {
    // A frame header can claim any content size, so the claim is also held to a ratio no recorded sensor data
    // reaches (about 256:1), which bounds the memory a damaged chunk can take to 256 times its own size.
    const unsigned long long content = ZSTD_getFrameContentSize(records.data(), records.size());
    if (content == ZSTD_CONTENTSIZE_ERROR || (content != ZSTD_CONTENTSIZE_UNKNOWN && content != uncompressed_size) ||
        uncompressed_size > 256 * compressed_size + 65536) {
      fail("zstd chunk of " + std::to_string(compressed_size) + " byte(s) does not hold the " +
               std::to_string(uncompressed_size) + " byte(s) it claims",
           record_offset);
    }
  }
  chunk_.resize(static_cast<std::size_t>(uncompressed_size));
  if (compression.empty()) {
    if (records.size() != uncompressed_size) {
      fail("uncompressed chunk holds " + std::to_string(records.size()) + " byte(s) but claims " +
               std::to_string(uncompressed_size),
           record_offset);
    }
    std::memcpy(chunk_.data(), records.data(), records.size());
  } else if (compression == "zstd") {
    const std::size_t got = ZSTD_decompress(chunk_.data(), chunk_.size(), records.data(), records.size());
    if (ZSTD_isError(got) != 0U)
      fail(std::string("zstd chunk does not decompress: ") + ZSTD_getErrorName(got), record_offset);
    if (got != uncompressed_size) {
      fail("zstd chunk decompresses to " + std::to_string(got) + " byte(s), not the " +
               std::to_string(uncompressed_size) + " it claims",
           record_offset);
    }
  } else if (compression == "lz4") {
    LZ4F_dctx* context = nullptr;
    if (LZ4F_isError(LZ4F_createDecompressionContext(&context, LZ4F_VERSION)) != 0U) {
      fail("out of memory for lz4", record_offset);
    }
    std::size_t in_done = 0;
    std::size_t out_done = 0;
    std::size_t hint = 1;
    while (hint != 0 && in_done < records.size()) {
      std::size_t out_room = chunk_.size() - out_done;
      std::size_t in_room = records.size() - in_done;
      hint = LZ4F_decompress(context, chunk_.data() + out_done, &out_room, records.data() + in_done, &in_room, nullptr);
      if (LZ4F_isError(hint) != 0U) {
        const std::string error = LZ4F_getErrorName(hint);
        LZ4F_freeDecompressionContext(context);
        fail("lz4 chunk does not decompress: " + error, record_offset);
      }
      in_done += in_room;
      out_done += out_room;
      if (in_room == 0 && out_room == 0) break;  // no progress: the frame is incomplete
    }
    LZ4F_freeDecompressionContext(context);
    if (hint != 0 || out_done != uncompressed_size) {
      fail("lz4 chunk decompresses to " + std::to_string(out_done) + " byte(s) of the " +
               std::to_string(uncompressed_size) + " it claims (cut short or corrupt)",
           record_offset);
    }
  } else {
    fail("chunk compression '" + compression + "' is not supported (none, zstd and lz4 are)", record_offset);
  }
  // A CRC of 0 means the writer did not compute one.
  if (expected_crc != 0) {
    const std::uint32_t actual = crc32_of(chunk_);
    if (actual != expected_crc) {
      fail("chunk CRC mismatch: records hash to " + std::to_string(actual) + ", the chunk says " +
               std::to_string(expected_crc) + "; the chunk is corrupt and none of its messages is used",
           record_offset);
    }
  }
  chunk_position_ = 0;
  chunk_offset_ = record_offset;
  in_chunk_ = true;
}

bool is_mcap_file(const std::filesystem::path& path) {
  std::ifstream file(path, std::ios::binary);
  char magic[8] = {};
  file.read(magic, 8);
  return file.gcount() == 8 && std::string_view(magic, 8) == kMagic;
}

}  // namespace occgeo::replay
