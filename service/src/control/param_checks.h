#pragma once

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string_view>

// Parameter and input checks shared by the control algorithms (bearcat, wander, pointbug).
namespace occgeo::service::control::detail {

// Throws std::invalid_argument "<field> <requirement> (got <value>)" unless ok.
inline void require(bool ok, std::string_view field, std::string_view requirement, double value) {
  if (ok) return;
  std::ostringstream message;
  message << field << ' ' << requirement << " (got " << value << ')';
  throw std::invalid_argument(message.str());
}

inline void require_positive(std::string_view field, double value) {
  require(std::isfinite(value) && value > 0.0, field, "must be positive and finite", value);
}

inline void require_non_negative(std::string_view field, double value) {
  require(std::isfinite(value) && value >= 0.0, field, "must be non-negative and finite", value);
}

}  // namespace occgeo::service::control::detail
