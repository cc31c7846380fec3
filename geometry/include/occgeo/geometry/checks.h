#pragma once

#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>

namespace occgeo::geometry {

// The one wording of a refused parameter or input in every library: "<field> <requirement>, got <value>", e.g.
// "OctoMapParams.prob_hit must be in (0.5, 1), got 0.4", thrown as std::invalid_argument, so that a user reads the
// same kind of message whichever model or behaviour refused a value.
[[noreturn]] inline void fail_requirement(std::string_view field, std::string_view requirement,
                                          std::string_view value) {
  std::string message;
  message.reserve(field.size() + requirement.size() + value.size() + 8);
  message.append(field).append(" ").append(requirement).append(", got ").append(value);
  throw std::invalid_argument(message);
}

// A number as error messages show it: its shortest natural form, e.g. "0.1", "-1", "inf", "nan".
inline std::string number_text(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

inline void require(bool ok, std::string_view field, std::string_view requirement, double value) {
  if (!ok) fail_requirement(field, requirement, number_text(value));
}

inline void require(bool ok, std::string_view field, std::string_view requirement, std::string_view value) {
  if (!ok) fail_requirement(field, requirement, value);
}

// A requirement with no single value to show (e.g. "min must not exceed max"): the sentence as given.
inline void require(bool ok, const std::string& sentence) {
  if (!ok) throw std::invalid_argument(sentence);
}

}  // namespace occgeo::geometry
