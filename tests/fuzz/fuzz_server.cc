// The server's handling of untrusted clients: a stream of ClientMessage frames from three sessions
// (driver, controller, anyone) taken through the same dispatch and handlers as a real connection,
// on a fresh ServerCore per input so every input is judged alone. Each record of the input is one
// byte choosing the session, then one varint-delimited ClientMessage; the stream ends at the first
// record that does not decode (a real session closes its connection there). Every session then
// disconnects and the core drains its ingest and query work, so crashes on worker threads count too.
#include <google/protobuf/io/coded_stream.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

#include "fake_session.h"
#include "fuzz_support.h"
#include "handlers/handlers.h"
#include "occgeo/service/config.h"
#include "occgeo/service/log.h"
#include "occgeo/v1/session.pb.h"

namespace {

using occgeo::service::FakeSession;
using occgeo::service::ServerConfig;
using occgeo::service::ServerCore;

constexpr std::size_t kSessions = 3;

// The defaults, with the per-message limits cut down so one input stays fast (each beam and point is a
// ray through the maps); the validation paths the limits guard are the same.
ServerConfig fuzz_config() {
  ServerConfig config;
  config.limits.max_frame_bytes = 65536;
  config.limits.max_beams = 1024;
  config.limits.max_sensor_range_m = 30.0;
  config.limits.max_point_cloud_points = 512;
  config.limits.max_ptem_query_points = 256;
  config.limits.max_grid_reply_cells = std::size_t{1} << 18;
  config.limits.max_octree_reply_bytes = std::size_t{1} << 18;
  config.limits.max_robots = 4;
  config.limits.max_batch_queries = 64;
  config.auth.operator_token = "fuzz-operator";
  config.validate();
  return config;
}

// Counts internal errors (a handler threw); reported at exit rather than treated as a crash, since
// the server survives them, but each one is a validation gap worth a look.
struct InternalErrors {
  std::uint64_t count = 0;
  std::string first;
  ~InternalErrors() {
    if (count > 0)
      std::fprintf(stderr, "fuzz_server: %llu ERROR_INTERNAL replies; first: %s\n",
                   static_cast<unsigned long long>(count), first.c_str());
  }
};
InternalErrors internal_errors;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool quiet = [] {
    occgeo::service::log::set_level(occgeo::service::log::Level::error);
    return true;
  }();
  (void)quiet;
  static const ServerConfig config = fuzz_config();

  ServerCore core(config);
  std::array<std::shared_ptr<FakeSession>, kSessions> sessions;
  for (auto& session : sessions) {
    session = std::make_shared<FakeSession>(core);
    session->info().id = core.next_session_id++;
  }

  std::size_t offset = 0;
  while (offset < size) {
    const auto& session = sessions[data[offset++] % kSessions];
    google::protobuf::io::CodedInputStream input(data + offset, static_cast<int>(size - offset));
    std::uint32_t length = 0;
    if (!input.ReadVarint32(&length) || length > config.limits.max_frame_bytes) break;
    const auto prefix = static_cast<std::size_t>(input.CurrentPosition());
    if (length > size - offset - prefix) break;
    occgeo::v1::ClientMessage message;
    if (!message.ParseFromArray(data + offset + prefix, static_cast<int>(length))) break;
    offset += prefix + length;
    occgeo::service::dispatch(session, std::move(message));
  }

  for (const auto& session : sessions) occgeo::service::handle_disconnect(core, session->info());
  core.drain();
  for (const auto& session : sessions) {
    for (const auto& reply : session->take_all()) {
      if (reply.has_error() && reply.error().code() == occgeo::v1::ERROR_INTERNAL) {
        if (internal_errors.count++ == 0)
          internal_errors.first = reply.error().field() + ": " + reply.error().message();
      }
    }
  }
  return 0;
}
