#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

namespace occgeo::replay {

// Reads a text file line by line, transparently decompressing gzip input (detected by its magic bytes 1f 8b).
class LineSource {
 public:
  // Opens `path`; throws std::runtime_error naming the file if it cannot be opened.
  explicit LineSource(const std::filesystem::path& path);
  ~LineSource();
  LineSource(const LineSource&) = delete;
  LineSource& operator=(const LineSource&) = delete;

  // The next line without its end-of-line characters, or nullopt at the end of the file.
  std::optional<std::string> next();

  // 1-based number of the line last returned.
  [[nodiscard]] std::size_t line_number() const { return line_number_; }
  [[nodiscard]] bool is_gzip() const { return gzip_; }
  // Fraction of the (compressed) file consumed so far, 0..1, for progress reports.
  [[nodiscard]] double progress() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  bool gzip_ = false;
  std::size_t line_number_ = 0;
};

// True when `path` starts with the gzip magic bytes.
bool is_gzip_file(const std::filesystem::path& path);

}  // namespace occgeo::replay
