#include "occgeo/mapfile/png.h"

#include <zlib.h>

#include <fstream>
#include <stdexcept>

namespace occgeo::mapfile {
namespace {

// PNG colour types (IHDR byte 9).
constexpr std::uint8_t kColourGrey = 0;
constexpr std::uint8_t kColourRgb = 2;

void put_u32(std::vector<std::uint8_t>& out, std::uint32_t value) {
  out.push_back(static_cast<std::uint8_t>(value >> 24U));
  out.push_back(static_cast<std::uint8_t>(value >> 16U));
  out.push_back(static_cast<std::uint8_t>(value >> 8U));
  out.push_back(static_cast<std::uint8_t>(value));
}

// Appends one chunk: length, type, data, CRC-32 of type and data.
void put_chunk(std::vector<std::uint8_t>& out, const char (&type)[5], const std::vector<std::uint8_t>& data) {
  put_u32(out, static_cast<std::uint32_t>(data.size()));
  const std::size_t type_at = out.size();
  out.insert(out.end(), type, type + 4);
  out.insert(out.end(), data.begin(), data.end());
  const uLong crc = crc32(0L, out.data() + type_at, static_cast<uInt>(4 + data.size()));
  put_u32(out, static_cast<std::uint32_t>(crc));
}

// The PNG file of 8-bit samples, `channels` per pixel (1: grey, 3: RGB).
std::vector<std::uint8_t> encode(std::uint32_t width, std::uint32_t height, std::uint32_t channels,
                                 std::uint8_t colour_type, const std::vector<std::uint8_t>& pixels) {
  if (width == 0 || height == 0) throw std::invalid_argument("png: width and height must be positive");
  const std::size_t row_bytes = static_cast<std::size_t>(width) * channels;
  if (pixels.size() != row_bytes * height) {
    throw std::invalid_argument("png: pixels.size() " + std::to_string(pixels.size()) + " != " +
                                (channels == 1 ? std::string() : std::to_string(channels) + " * ") + "width * height");
  }
  // Raw scanlines: a filter-type byte (0, none) before each row.
  std::vector<std::uint8_t> raw;
  raw.reserve((row_bytes + 1) * height);
  for (std::uint32_t row = 0; row < height; ++row) {
    raw.push_back(0);
    const auto begin = pixels.begin() + static_cast<std::ptrdiff_t>(row * row_bytes);
    raw.insert(raw.end(), begin, begin + static_cast<std::ptrdiff_t>(row_bytes));
  }
  uLongf compressed_size = compressBound(static_cast<uLong>(raw.size()));
  std::vector<std::uint8_t> compressed(compressed_size);
  if (compress2(compressed.data(), &compressed_size, raw.data(), static_cast<uLong>(raw.size()), 9) != Z_OK) {
    throw std::runtime_error("png: zlib compression failed");
  }
  compressed.resize(compressed_size);

  std::vector<std::uint8_t> out = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<std::uint8_t> header;
  put_u32(header, width);
  put_u32(header, height);
  header.insert(header.end(), {8, colour_type, 0, 0, 0});  // bit depth 8, colour type, deflate, filter 0, no interlace
  put_chunk(out, "IHDR", header);
  put_chunk(out, "IDAT", compressed);
  put_chunk(out, "IEND", {});
  return out;
}

void write_bytes(const std::filesystem::path& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write '" + path.string() + "'");
}

}  // namespace

std::vector<std::uint8_t> encode_png_gray8(std::uint32_t width, std::uint32_t height,
                                           const std::vector<std::uint8_t>& pixels) {
  return encode(width, height, 1, kColourGrey, pixels);
}

std::vector<std::uint8_t> encode_png_rgb8(std::uint32_t width, std::uint32_t height,
                                          const std::vector<std::uint8_t>& pixels) {
  return encode(width, height, 3, kColourRgb, pixels);
}

void write_png_gray8(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                     const std::vector<std::uint8_t>& pixels) {
  write_bytes(path, encode_png_gray8(width, height, pixels));
}

void write_png_rgb8(const std::filesystem::path& path, std::uint32_t width, std::uint32_t height,
                    const std::vector<std::uint8_t>& pixels) {
  write_bytes(path, encode_png_rgb8(width, height, pixels));
}

}  // namespace occgeo::mapfile
