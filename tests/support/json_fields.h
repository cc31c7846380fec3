#pragma once

// Fields of the flat one-object JSON summaries the programs print (occgeo-sim --json, occgeo --json).

#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

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

// The array of numbers stored under key; throws std::runtime_error naming the key when it is absent.
inline std::vector<double> json_number_array(const std::string& json, const std::string& key) {
  const std::regex pattern("\"" + key + "\"\\s*:\\s*\\[([^\\]]*)\\]");
  std::smatch match;
  if (!std::regex_search(json, match, pattern)) throw std::runtime_error("no array '" + key + "' in " + json);
  std::vector<double> values;
  std::stringstream items(match[1]);
  for (std::string item; std::getline(items, item, ',');) values.push_back(std::stod(item));
  return values;
}

}  // namespace occgeo::testing
