#pragma once

// The small checks and the FieldError maker that validation.cc and validation_*.cc share; the rest of the server
// includes validation.h.

#include <cmath>
#include <string>
#include <utility>

#include "validation.h"

namespace occgeo::service {

inline bool finite_positive(double v) { return std::isfinite(v) && v > 0.0; }

inline FieldError field_error(std::string field, std::string message) { return {std::move(field), std::move(message)}; }

}  // namespace occgeo::service
