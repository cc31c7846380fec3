// Every message decoder: the bytes of one frame's body parsed as a ClientMessage (what the server
// decodes from clients) and as a ServerMessage (what the clients decode from a server), each with
// every submessage in its oneof. A grid reply is also taken through the clients' conversion to a
// map image, which must refuse inconsistent replies with an error rather than read out of bounds.
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_support.h"
#include "occgeo/client/grid.h"
#include "occgeo/mapfile/certainty_image.h"
#include "occgeo/mapfile/map_file.h"
#include "occgeo/v1/session.pb.h"

namespace {

using occgeo::fuzz::require;

// A parsed message serializes, and parses back to the same serialization.
template <typename Message>
void check_round_trip(const Message& message) {
  const std::string bytes = message.SerializeAsString();
  require(bytes.size() == message.ByteSizeLong(), "the serialization is as long as ByteSizeLong says");
  Message again;
  require(again.ParseFromString(bytes), "a serialized message parses");
  require(again.SerializeAsString() == bytes, "a message survives serialization unchanged");
}

void convert_grid_reply(const occgeo::v1::GridReply& reply) {
  const auto window = occgeo::client::certainty_window(reply);
  try {
    const auto image = occgeo::mapfile::image_from_certainty(window);
    require(image.pixels.size() == static_cast<std::size_t>(image.width) * image.height,
            "an image has one pixel per cell");
  } catch (const occgeo::mapfile::MapFileError&) {
    // Refused with a message: what an inconsistent reply must get.
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto* bytes = reinterpret_cast<const char*>(data);
  const int length = static_cast<int>(size);

  occgeo::v1::ClientMessage client_message;
  if (client_message.ParseFromArray(bytes, length)) {
    check_round_trip(client_message);
  }

  occgeo::v1::ServerMessage server_message;
  if (server_message.ParseFromArray(bytes, length)) {
    check_round_trip(server_message);
    if (server_message.has_grid()) convert_grid_reply(server_message.grid());
  }
  return 0;
}
