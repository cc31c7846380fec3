#pragma once

#include <sstream>
#include <string>

namespace occgeo::mapping {

// value as in error messages: shortest natural form, e.g. "0.1", "-1", "inf", "nan".
inline std::string format_number(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

}  // namespace occgeo::mapping
