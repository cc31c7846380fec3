#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace occgeo::replay {

// A complete PNG file (8-bit greyscale, no interlace, zlib-compressed, filter 0 on every row) of `pixels`, row-major,
// row 0 at the top; throws std::invalid_argument when pixels.size() != width * height or a side is zero.
std::vector<std::uint8_t> encode_png_gray8(std::uint32_t width, std::uint32_t height,
                                           const std::vector<std::uint8_t>& pixels);

// Writes encode_png_gray8(...) to `path`; throws std::runtime_error naming the file on failure.
void write_png_gray8(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                     const std::vector<std::uint8_t>& pixels);

}  // namespace occgeo::replay
