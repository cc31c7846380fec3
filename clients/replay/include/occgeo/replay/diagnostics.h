#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <ostream>
#include <string>

namespace occgeo::replay {

// Counts data quirks by kind and prints the first few of each kind to a stream (rate-limited per kind), so a log
// with thousands of bad lines neither floods the terminal nor goes unnoticed.
class Diagnostics {
 public:
  // Warnings go to `err` (nullptr: count only); at most `print_limit` are printed per kind.
  explicit Diagnostics(std::ostream* err = nullptr, int print_limit = 3) : err_(err), print_limit_(print_limit) {}

  // Counts one quirk of `kind` found at 1-based `line_number` (0: no line) and prints `message` unless rate-limited.
  void warn(const std::string& kind, std::size_t line_number, const std::string& message);

  // Counts a line of a type the replay does not use (e.g. CARMEN PARAM, NEFF, comments); not a warning.
  void ignore_line(const std::string& type) { ++ignored_lines_[type]; }

  // Counts one beam at the format's max-range sentinel, sent as "no return"; normal data, not a warning.
  void count_no_return(std::uint64_t beams = 1) { no_return_beams_ += beams; }

  // Counts one beam the sensor itself flagged as a failed measurement (e.g. URG-04LX codes 0-19 mm), sent below
  // range_min so it neither clears nor marks: such a beam says nothing about the space along it.
  void count_invalid_reading(std::uint64_t beams = 1) { invalid_beams_ += beams; }

  [[nodiscard]] std::uint64_t warnings() const;
  [[nodiscard]] const std::map<std::string, std::uint64_t>& warnings_by_kind() const { return warnings_; }
  [[nodiscard]] std::uint64_t count(const std::string& kind) const;
  [[nodiscard]] const std::map<std::string, std::uint64_t>& ignored_lines() const { return ignored_lines_; }
  [[nodiscard]] std::uint64_t no_return_beams() const { return no_return_beams_; }
  [[nodiscard]] std::uint64_t invalid_beams() const { return invalid_beams_; }

 private:
  std::ostream* err_;
  int print_limit_;
  std::map<std::string, std::uint64_t> warnings_;
  std::map<std::string, std::uint64_t> ignored_lines_;
  std::uint64_t no_return_beams_ = 0;
  std::uint64_t invalid_beams_ = 0;
};

}  // namespace occgeo::replay
