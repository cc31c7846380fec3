#pragma once

// Fields of the flat one-object JSON summaries the programs print (occgeo-sim --json, occgeo --json).

#include <regex>
#include <stdexcept>
#include <string>

namespace occgeo::testing {

// The number stored under key; throws std::runtime_error naming the key when it is absent. Nested objects are not
// distinguished, so ask only for keys that appear once.
inline double json_number(const std::string& json, const std::string& key) {
  const std::regex pattern("\"" + key + "\"\\s*:\\s*(-?[0-9.eE+-]+)");
  std::smatch match;
  if (!std::regex_search(json, match, pattern)) throw std::runtime_error("no '" + key + "' in " + json);
  return std::stod(match[1]);
}

// The boolean stored under key; throws std::runtime_error naming the key when it is absent.
inline bool json_bool(const std::string& json, const std::string& key) {
  const std::regex pattern("\"" + key + "\"\\s*:\\s*(true|false)");
  std::smatch match;
  if (!std::regex_search(json, match, pattern)) throw std::runtime_error("no '" + key + "' in " + json);
  return match[1] == "true";
}

}  // namespace occgeo::testing
