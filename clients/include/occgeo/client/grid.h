#pragma once

#include "occgeo/mapfile/certainty_image.h"
#include "occgeo/v1/query.pb.h"

namespace occgeo::client {

// The cells of a GridReply as a certainty window (row 0 at min_iy, 255 unobserved), ready for
// mapfile::image_from_certainty or for lookups.
mapfile::CertaintyWindow certainty_window(const v1::GridReply& grid);

}  // namespace occgeo::client
