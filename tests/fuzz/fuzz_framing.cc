// The frame reader: arbitrary bytes from a socket -> varint-delimited ClientMessages. Besides not
// crashing, the reader must not depend on how the bytes arrive: fed whole or in arbitrary pieces it
// yields the same frames and ends in the same state, and every frame it yields re-encodes to itself.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_support.h"
#include "occgeo/proto/framing.h"
#include "occgeo/v1/session.pb.h"

namespace {

using occgeo::fuzz::require;
using occgeo::proto::FrameDecoder;
using occgeo::proto::FrameStatus;

struct Decoded {
  std::vector<std::string> frames;  // each frame's message, serialized again
  FrameStatus last = FrameStatus::need_more;
  std::size_t buffered = 0;
};

// Takes every complete frame out of `decoder`; false once the stream cannot be trusted any more.
bool drain(FrameDecoder& decoder, Decoded& out) {
  for (;;) {
    occgeo::v1::ClientMessage message;
    out.last = decoder.next(message);
    if (out.last != FrameStatus::frame) return out.last == FrameStatus::need_more;
    out.frames.push_back(message.SerializeAsString());
  }
}

Decoded decode_whole(std::string_view stream, std::size_t max_frame_bytes) {
  FrameDecoder decoder(max_frame_bytes);
  Decoded out;
  decoder.append(stream.data(), stream.size());
  drain(decoder, out);
  out.buffered = decoder.buffered();
  return out;
}

// Feeds the stream in pieces of 1..64 bytes chosen by a small generator seeded from the input.
Decoded decode_in_pieces(std::string_view stream, std::size_t max_frame_bytes, std::uint32_t seed) {
  FrameDecoder decoder(max_frame_bytes);
  Decoded out;
  std::uint32_t state = seed | 1U;
  std::size_t offset = 0;
  bool trusted = true;
  while (trusted && offset < stream.size()) {
    state ^= state << 13U;
    state ^= state >> 17U;
    state ^= state << 5U;
    const std::size_t piece = std::min<std::size_t>(1 + state % 64, stream.size() - offset);
    decoder.append(stream.data() + offset, piece);
    offset += piece;
    trusted = drain(decoder, out);
  }
  if (stream.empty()) drain(decoder, out);
  out.buffered = decoder.buffered();
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  // Byte 0 picks the frame limit (small ones make the over-limit path reachable); byte 1 seeds the piece sizes.
  constexpr std::array<std::size_t, 4> kLimits = {64, 1024, 65536, std::size_t{4} << 20};
  const std::size_t max_frame_bytes = kLimits[data[0] % kLimits.size()];
  const std::uint32_t seed = data[1];
  const std::string_view stream(reinterpret_cast<const char*>(data) + 2, size - 2);

  const Decoded whole = decode_whole(stream, max_frame_bytes);
  const Decoded pieces = decode_in_pieces(stream, max_frame_bytes, seed);
  require(whole.frames == pieces.frames, "the same frames whether the bytes arrive whole or in pieces");
  require(whole.last == pieces.last, "the same final state whether the bytes arrive whole or in pieces");
  if (whole.last == FrameStatus::need_more) {
    require(whole.buffered == pieces.buffered, "the same bytes left over whole or in pieces");
    require(whole.buffered <= stream.size(), "never more bytes buffered than received");
  }

  for (const std::string& frame : whole.frames) {
    occgeo::v1::ClientMessage message;
    require(message.ParseFromString(frame), "a decoded frame's message parses again");
    const std::string encoded = occgeo::proto::encode_frame(message);
    FrameDecoder again(encoded.size() + 16);
    again.append(encoded.data(), encoded.size());
    occgeo::v1::ClientMessage round_trip;
    require(again.next(round_trip) == FrameStatus::frame, "an encoded frame decodes");
    require(round_trip.SerializeAsString() == frame, "an encoded frame decodes to the same message");
    require(again.buffered() == 0, "an encoded frame is consumed whole");
  }
  return 0;
}
