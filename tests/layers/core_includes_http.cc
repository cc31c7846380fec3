// The server's core (sessions, handlers, durability) reaching up into the HTTP side and into the server beside it,
// both of which share its folders. The layer check refuses both (tests/CMakeLists.txt, Layers.*), in this order.
// clang-format off
#include "http/live_view.h"
#include "occgeo/service/server.h"
#include "handlers/robot_control.h"
// clang-format on
