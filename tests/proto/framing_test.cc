#include "occgeo/proto/framing.h"

#include <gtest/gtest.h>

#include "occgeo/v1/session.pb.h"

namespace occgeo::proto {
namespace {

v1::ClientMessage status_request(std::uint64_t id) {
  v1::ClientMessage message;
  message.mutable_status();
  message.set_request_id(id);
  return message;
}

TEST(FrameDecoder, DecodesFramesSplitAtEveryByte) {
  std::string stream;
  for (std::uint64_t id = 1; id <= 3; ++id) stream += encode_frame(status_request(id));
  FrameDecoder decoder(1024);
  std::vector<std::uint64_t> ids;
  for (const char byte : stream) {
    decoder.append(&byte, 1);
    v1::ClientMessage message;
    while (decoder.next(message) == FrameStatus::frame) ids.push_back(message.request_id());
  }
  EXPECT_EQ(ids, (std::vector<std::uint64_t>{1, 2, 3}));
  EXPECT_EQ(decoder.buffered(), 0U);
}

TEST(FrameDecoder, EmptyMessageIsAZeroLengthFrame) {
  const std::string frame = encode_frame(v1::ClientMessage());
  ASSERT_EQ(frame, std::string(1, '\0'));
  FrameDecoder decoder(16);
  decoder.append(frame.data(), frame.size());
  v1::ClientMessage message;
  EXPECT_EQ(decoder.next(message), FrameStatus::frame);
  EXPECT_EQ(message.body_case(), v1::ClientMessage::BODY_NOT_SET);
}

TEST(FrameDecoder, LengthOverTheLimitIsRejectedBeforeTheBodyArrives) {
  FrameDecoder decoder(100);
  const std::string prefix = "\xE5\x00";  // varint 101
  decoder.append(prefix.data(), 1);
  v1::ClientMessage message;
  EXPECT_EQ(decoder.next(message), FrameStatus::need_more);
  decoder.append(prefix.data() + 1, 1);
  EXPECT_EQ(decoder.next(message), FrameStatus::too_large);
  EXPECT_EQ(decoder.rejected_frame_bytes(), 101U);
}

TEST(FrameDecoder, OverlongVarintIsMalformed) {
  FrameDecoder decoder(1U << 30);
  const std::string prefix(6, '\xFF');
  decoder.append(prefix.data(), prefix.size());
  v1::ClientMessage message;
  EXPECT_EQ(decoder.next(message), FrameStatus::malformed);
}

TEST(FrameDecoder, BodyThatIsNotAMessageIsMalformed) {
  FrameDecoder decoder(100);
  const std::string frame = std::string("\x03", 1) + "\xFF\xFF\xFF";  // field 0 / bad wire type
  decoder.append(frame.data(), frame.size());
  v1::ClientMessage message;
  EXPECT_EQ(decoder.next(message), FrameStatus::malformed);
}

}  // namespace
}  // namespace occgeo::proto
