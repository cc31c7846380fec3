#pragma once

// A temporary folder for tests that write files.

#include <chrono>
#include <filesystem>
#include <random>
#include <string>

namespace occgeo::testing {

// A fresh folder under the system temp directory, removed with everything in it when this goes out of scope.
class TempDir {
 public:
  TempDir() {
    std::random_device entropy;
    const auto stamp = std::chrono::steady_clock::now().time_since_epoch().count();
    path_ = std::filesystem::temp_directory_path() /
            ("occgeo-test-" + std::to_string(stamp) + "_" + std::to_string(entropy()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace occgeo::testing
