#pragma once

#include <cstdint>

namespace occgeo::proto {

// The version of the occgeo.v1 protocol this build speaks, sent in Hello.protocol_version and Welcome; the server
// refuses any other with ERROR_PROTOCOL_VERSION. Version 2 carries request_id on the ClientMessage / ServerMessage
// envelope instead of inside each request and reply body; version 3 names behaviours and their states by the
// Behaviour and BehaviourState enums instead of strings.
inline constexpr std::uint32_t kProtocolVersion = 3;

// ClientMessage bodies numbered from this field on are requests, each answered by one ServerMessage (the reply of the
// same number, or an Error) carrying the request's request_id; those below (hello, spec, odometry, sensor data) are
// not (session.proto).
inline constexpr int kFirstRequestBodyField = 10;

}  // namespace occgeo::proto
