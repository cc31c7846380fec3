#pragma once

#include <cmath>
#include <string_view>

#include "occgeo/geometry/checks.h"

// Parameter and input checks shared by the control algorithms (bearcat, wander, pointbug), in geometry's one wording
// of a refused value.
namespace occgeo::service::control::detail {

using geometry::require;

inline void require_positive(std::string_view field, double value) {
  require(std::isfinite(value) && value > 0.0, field, "must be positive and finite", value);
}

inline void require_non_negative(std::string_view field, double value) {
  require(std::isfinite(value) && value >= 0.0, field, "must be non-negative and finite", value);
}

}  // namespace occgeo::service::control::detail
