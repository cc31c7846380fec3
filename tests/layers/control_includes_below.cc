// A behaviour reading only its own layer and those below: the layer check passes it.
#include "model_geometry.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/mapping/grid_snapshot.h"
#include "occgeo/service/control/bearcat.h"
#include "param_checks.h"
