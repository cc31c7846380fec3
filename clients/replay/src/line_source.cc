#include "occgeo/replay/line_source.h"

#include <zlib.h>

#include <array>
#include <fstream>
#include <stdexcept>

namespace occgeo::replay {

bool is_gzip_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::array<char, 2> magic{};
  if (!in.read(magic.data(), magic.size())) return false;
  return static_cast<unsigned char>(magic[0]) == 0x1f && static_cast<unsigned char>(magic[1]) == 0x8b;
}

struct LineSource::Impl {
  gzFile gz = nullptr;
  std::ifstream plain;
  double size_bytes = 0.0;
};

LineSource::LineSource(const std::filesystem::path& path) : impl_(std::make_unique<Impl>()) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw std::runtime_error("cannot open '" + path.string() + "'");
  impl_->size_bytes = static_cast<double>(std::filesystem::file_size(path, ec));
  gzip_ = is_gzip_file(path);
  if (gzip_) {
    impl_->gz = gzopen(path.c_str(), "rb");
    if (impl_->gz == nullptr) throw std::runtime_error("cannot open '" + path.string() + "'");
    gzbuffer(impl_->gz, 1 << 16);
  } else {
    impl_->plain.open(path, std::ios::binary);
    if (!impl_->plain) throw std::runtime_error("cannot open '" + path.string() + "'");
  }
}

LineSource::~LineSource() {
  if (impl_ && impl_->gz != nullptr) gzclose(impl_->gz);
}

std::optional<std::string> LineSource::next() {
  std::string line;
  if (gzip_) {
    std::array<char, 8192> buffer{};
    bool any = false;
    while (gzgets(impl_->gz, buffer.data(), static_cast<int>(buffer.size())) != nullptr) {
      any = true;
      line += buffer.data();
      if (!line.empty() && line.back() == '\n') break;
    }
    if (!any) {
      int code = Z_OK;
      const char* message = gzerror(impl_->gz, &code);
      if (code != Z_OK && code != Z_STREAM_END) {
        throw std::runtime_error(std::string("gzip read error: ") + message);
      }
      return std::nullopt;
    }
  } else if (!std::getline(impl_->plain, line)) {
    return std::nullopt;
  }
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
  ++line_number_;
  return line;
}

double LineSource::progress() const {
  if (impl_->size_bytes <= 0.0) return 1.0;
  double position = 0.0;
  if (gzip_) {
    position = static_cast<double>(gzoffset(impl_->gz));
  } else {
    auto& plain = const_cast<std::ifstream&>(impl_->plain);  // tellg is non-const but does not change the stream
    const auto at = plain.tellg();
    position = at < 0 ? impl_->size_bytes : static_cast<double>(at);
  }
  return std::min(1.0, std::max(0.0, position / impl_->size_bytes));
}

}  // namespace occgeo::replay
