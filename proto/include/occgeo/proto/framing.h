#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace google::protobuf {
class MessageLite;
}

namespace occgeo::proto {

// Outcome of trying to take one frame out of a FrameDecoder.
enum class FrameStatus {
  need_more,  // the buffered bytes hold no complete frame yet
  frame,      // one message was decoded and consumed
  too_large,  // the length prefix is over the limit; the stream cannot be trusted any more
  malformed,  // the prefix or the message bytes do not decode; the stream cannot be trusted
};

// Splits a byte stream into varint-length-delimited protobuf messages (protobuf's own delimited
// format, parsed with google::protobuf::util::ParseDelimitedFromCodedStream).
class FrameDecoder {
 public:
  explicit FrameDecoder(std::size_t max_frame_bytes) : max_frame_bytes_(max_frame_bytes) {}

  // Adds received bytes to the buffer.
  void append(const char* data, std::size_t size);
  // Decodes the next complete frame into `out` when there is one.
  FrameStatus next(google::protobuf::MessageLite& out);
  // Length of the last frame's prefix when next() returned too_large.
  [[nodiscard]] std::size_t rejected_frame_bytes() const { return rejected_frame_bytes_; }
  // Bytes received but not yet decoded.
  [[nodiscard]] std::size_t buffered() const { return buffer_.size() - start_; }

 private:
  std::size_t max_frame_bytes_;
  std::size_t rejected_frame_bytes_ = 0;
  std::string buffer_;
  std::size_t start_ = 0;
};

// Serialises `message` as one delimited frame (varint length prefix + bytes).
std::string encode_frame(const google::protobuf::MessageLite& message);
// The same frame appended to `out`, serialised in place (no temporary string).
void append_frame(const google::protobuf::MessageLite& message, std::string& out);

}  // namespace occgeo::proto
