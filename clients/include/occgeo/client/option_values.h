#pragma once

// Number parsing shared by the command-line tools (occgeo, occgeo-sim, occgeo-load, occgeo replay and record), so
// that they accept the same spellings and word their errors alike: "option '--flag' needs ..., got '...'".

#include <charconv>
#include <cmath>
#include <optional>
#include <string_view>

namespace occgeo::client {

// The whole of text as a finite number; nullopt for anything else (empty, trailing characters, inf, nan).
inline std::optional<double> finite_number(std::string_view text) {
  double value = 0.0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size() || !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

}  // namespace occgeo::client
