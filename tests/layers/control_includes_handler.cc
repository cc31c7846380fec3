// A behaviour reaching up into the handlers, both ways of spelling it: through the service's source root, and
// relative to this file. The layer check refuses both (tests/CMakeLists.txt, Layers.*), in this order.
// clang-format off
#include "handlers/robot_control.h"
#include "../../service/src/http/live_view.h"
#include "occgeo/geometry/pose.h"
// clang-format on
