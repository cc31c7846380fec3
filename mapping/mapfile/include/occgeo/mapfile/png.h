#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace occgeo::mapfile {

// The project's one PNG encoder: 8-bit samples, no interlace, zlib-compressed, filter 0 on every row. Pixels are
// row-major with row 0 at the top.

// A complete greyscale PNG file of `pixels` (one byte per pixel); throws std::invalid_argument when
// pixels.size() != width * height or a side is zero.
std::vector<std::uint8_t> encode_png_gray8(std::uint32_t width, std::uint32_t height,
                                           const std::vector<std::uint8_t>& pixels);

// A complete RGB PNG file of `pixels` (three bytes per pixel: red, green, blue); throws std::invalid_argument when
// pixels.size() != 3 * width * height or a side is zero.
std::vector<std::uint8_t> encode_png_rgb8(std::uint32_t width, std::uint32_t height,
                                          const std::vector<std::uint8_t>& pixels);

// Writes encode_png_gray8(...) to `path`; throws std::runtime_error naming the file on failure.
void write_png_gray8(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                     const std::vector<std::uint8_t>& pixels);

// Writes encode_png_rgb8(...) to `path`; throws std::runtime_error naming the file on failure.
void write_png_rgb8(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                    const std::vector<std::uint8_t>& pixels);

}  // namespace occgeo::mapfile
