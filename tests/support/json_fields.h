#pragma once

// Fields of the JSON the programs print (occgeo-sim --json, occgeo --json, occgeo-load --json) and the server logs,
// read with nlohmann-json: key order, spacing and nesting change nothing.

#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace occgeo::testing {

namespace detail {

// The value stored under key in `value` or anything nested in it, depth first in document order; nullptr when none.
inline const nlohmann::ordered_json* find_key(const nlohmann::ordered_json& value, const std::string& key) {
  if (value.is_object()) {
    if (const auto found = value.find(key); found != value.end()) return &*found;
  }
  if (value.is_structured()) {
    for (const auto& item : value) {
      if (const auto* found = find_key(item, key)) return found;
    }
  }
  return nullptr;
}

// The documents in `text`: the whole text when it is one JSON document, else each line that is one (a program that
// prints progress lines before its summary), last line first.
inline std::vector<nlohmann::ordered_json> documents(const std::string& text) {
  auto whole = nlohmann::ordered_json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!whole.is_discarded()) return {std::move(whole)};
  std::vector<nlohmann::ordered_json> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    auto document = nlohmann::ordered_json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (!document.is_discarded() && document.is_structured()) lines.insert(lines.begin(), std::move(document));
  }
  return lines;
}

// The value stored under key in the JSON of `text` (see documents()); nullopt when no document holds it.
inline std::optional<nlohmann::ordered_json> json_field(const std::string& text, const std::string& key) {
  for (const auto& document : documents(text)) {
    if (const auto* found = find_key(document, key)) return *found;
  }
  return std::nullopt;
}

inline nlohmann::ordered_json required_field(const std::string& text, const std::string& key,
                                             bool (nlohmann::ordered_json::*is_kind)() const noexcept,
                                             const char* kind) {
  const auto value = json_field(text, key);
  if (!value) throw std::runtime_error("no '" + key + "' in " + text);
  if (!((*value).*is_kind)()) throw std::runtime_error("'" + key + "' is not " + kind + " in " + text);
  return *value;
}

}  // namespace detail

namespace detail {

// A number, or a string holding one: proto3's JSON mapping (occgeo --json) writes 64-bit integers as strings.
inline std::optional<double> as_number(const nlohmann::ordered_json& value) {
  if (value.is_number()) return value.get<double>();
  if (!value.is_string()) return std::nullopt;
  const std::string text = value.get<std::string>();
  std::size_t used = 0;
  try {
    const double number = std::stod(text, &used);
    if (used == text.size()) return number;
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

}  // namespace detail

// The number stored under key, at any depth (a 64-bit integer printed as a string counts); throws
// std::runtime_error naming the key when it is absent or not a number. Keys that appear more than once give the first
// in document order, so ask for keys that appear once.
inline double json_number(const std::string& json, const std::string& key) {
  const auto value = detail::json_field(json, key);
  if (!value) throw std::runtime_error("no '" + key + "' in " + json);
  const auto number = detail::as_number(*value);
  if (!number) throw std::runtime_error("'" + key + "' is not a number in " + json);
  return *number;
}

// The number stored under key, or nullopt when the JSON holds none.
inline std::optional<double> json_optional_number(const std::string& json, const std::string& key) {
  const auto value = detail::json_field(json, key);
  if (!value) return std::nullopt;
  return detail::as_number(*value);
}

// The boolean stored under key; throws std::runtime_error naming the key when it is absent.
inline bool json_bool(const std::string& json, const std::string& key) {
  return detail::required_field(json, key, &nlohmann::ordered_json::is_boolean, "a boolean").get<bool>();
}

// The string stored under key; throws std::runtime_error naming the key when it is absent.
inline std::string json_string(const std::string& json, const std::string& key) {
  return detail::required_field(json, key, &nlohmann::ordered_json::is_string, "a string").get<std::string>();
}

// The array of numbers stored under key; throws std::runtime_error naming the key when it is absent.
inline std::vector<double> json_number_array(const std::string& json, const std::string& key) {
  return detail::required_field(json, key, &nlohmann::ordered_json::is_array, "an array").get<std::vector<double>>();
}

}  // namespace occgeo::testing
