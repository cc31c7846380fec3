#pragma once

// Tests check the text of the errors users see: these helpers catch one and return its message.

#include <stdexcept>
#include <string>

namespace occgeo::testing {

// The message of the std::invalid_argument that f throws, or "" when it does not throw.
template <typename F>
std::string invalid_argument_message(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

}  // namespace occgeo::testing
