#pragma once

#include <cstdio>
#include <string>
#include <string_view>

namespace occgeo::client {

// `text` as a JSON string literal: quotes and backslashes escaped, control characters as \u00XX, so that what the
// tools print with --json always parses.
inline std::string json_string(std::string_view text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", static_cast<unsigned>(c));
      out += escaped;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

}  // namespace occgeo::client
