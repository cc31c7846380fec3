// The worlds' layer (worlds, model ingest, durability) reaching up into the protocol's handlers and sessions, which
// share service/src with it. The layer check refuses both (tests/CMakeLists.txt, Layers.*), in this order; the
// ingest kernels beside it pass.
// clang-format off
#include "handlers/sensor_ingest.h"
#include "session.h"
#include "ingest/model_ingest.h"
// clang-format on
