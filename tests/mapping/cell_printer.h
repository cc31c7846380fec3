#pragma once

#include <ostream>

#include "occgeo/geometry/cell.h"

namespace occgeo::geometry {

// Lets gtest print cells in failure messages.
inline void PrintTo(const CellIndex& c, std::ostream* out) { *out << "(" << c.ix << ", " << c.iy << ")"; }

}  // namespace occgeo::geometry
