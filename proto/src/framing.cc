#include "occgeo/proto/framing.h"

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/message_lite.h>

namespace occgeo::proto {

namespace {
// A 32-bit varint takes at most five bytes.
constexpr std::size_t kMaxPrefixBytes = 5;
}  // namespace

void FrameDecoder::append(const char* data, std::size_t size) {
  // Drop consumed bytes before growing, so the buffer stays proportional to one frame.
  if (start_ > 0 && start_ * 2 >= buffer_.size()) {
    buffer_.erase(0, start_);
    start_ = 0;
  }
  buffer_.append(data, size);
}

FrameStatus FrameDecoder::next(google::protobuf::MessageLite& out) {
  const auto* bytes = reinterpret_cast<const std::uint8_t*>(buffer_.data() + start_);
  const std::size_t available = buffer_.size() - start_;

  std::size_t prefix_bytes = 0;
  while (prefix_bytes < available && prefix_bytes < kMaxPrefixBytes && (bytes[prefix_bytes] & 0x80U) != 0) {
    ++prefix_bytes;
  }
  if (prefix_bytes == kMaxPrefixBytes) return FrameStatus::malformed;
  if (prefix_bytes == available) return FrameStatus::need_more;
  ++prefix_bytes;  // the last prefix byte, without the continuation bit

  google::protobuf::io::CodedInputStream prefix(bytes, static_cast<int>(prefix_bytes));
  std::uint32_t length = 0;
  if (!prefix.ReadVarint32(&length)) return FrameStatus::malformed;
  if (length > max_frame_bytes_) {
    rejected_frame_bytes_ = length;
    return FrameStatus::too_large;
  }
  if (available < prefix_bytes + length) return FrameStatus::need_more;

  // Parsed straight from the buffer: protobuf's flat-array path, without a stream wrapped round the bytes.
  if (!out.ParseFromArray(bytes + prefix_bytes, static_cast<int>(length))) return FrameStatus::malformed;
  start_ += prefix_bytes + length;
  if (start_ == buffer_.size()) {
    buffer_.clear();
    start_ = 0;
  }
  return FrameStatus::frame;
}

std::string encode_frame(const google::protobuf::MessageLite& message) {
  std::string out;
  append_frame(message, out);
  return out;
}

void append_frame(const google::protobuf::MessageLite& message, std::string& out) {
  const std::size_t size = message.ByteSizeLong();
  const std::size_t start = out.size();
  const auto prefix_bytes =
      static_cast<std::size_t>(google::protobuf::io::CodedOutputStream::VarintSize32(static_cast<std::uint32_t>(size)));
  out.resize(start + prefix_bytes + size);
  auto* target = reinterpret_cast<std::uint8_t*>(out.data() + start);
  target = google::protobuf::io::CodedOutputStream::WriteVarint32ToArray(static_cast<std::uint32_t>(size), target);
  message.SerializeWithCachedSizesToArray(target);
}

}  // namespace occgeo::proto
