#pragma once

#include <algorithm>
#include <cstddef>
#include <string_view>

namespace occgeo::service {

// Compares a presented token with the configured one in time independent of where they differ: every byte of the
// longer string is visited whatever the contents, so only the lengths leak. Used by the socket's hello and by HTTP.
[[nodiscard]] inline bool constant_time_equal(std::string_view a, std::string_view b) {
  const std::size_t n = std::max(a.size(), b.size());
  unsigned difference = a.size() == b.size() ? 0U : 1U;
  for (std::size_t i = 0; i < n; ++i) {
    const auto x = static_cast<unsigned char>(i < a.size() ? a[i] : 0);
    const auto y = static_cast<unsigned char>(i < b.size() ? b[i] : 0);
    difference |= static_cast<unsigned>(x ^ y);
  }
  return difference == 0U;
}

}  // namespace occgeo::service
