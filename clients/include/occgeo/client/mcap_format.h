#pragma once

// The MCAP container's constants, shared by the writer (`occgeo record`) and the reader (`occgeo replay`).

#include <cstdint>
#include <string_view>

namespace occgeo::mcap {

// Record opcodes.
enum Opcode : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

// The opening and closing magic.
inline constexpr std::string_view kMagic{"\x89MCAP0\r\n", 8};

// Every record starts with its opcode and a uint64 length.
inline constexpr std::uint64_t kRecordPrefixBytes = 9;

}  // namespace occgeo::mcap
