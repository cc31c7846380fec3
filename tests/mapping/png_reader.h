#pragma once

// A minimal PNG reader for tests: splits a file into chunks (checking the signature and every CRC) and inflates the
// pixels of the 8-bit, filter-0, non-interlaced files occgeo_mapfile writes. Not a general decoder.
#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace occgeo::testing {

inline std::uint32_t png_u32(const std::vector<std::uint8_t>& bytes, std::size_t at) {
  return (std::uint32_t{bytes.at(at)} << 24U) | (std::uint32_t{bytes.at(at + 1)} << 16U) |
         (std::uint32_t{bytes.at(at + 2)} << 8U) | std::uint32_t{bytes.at(at + 3)};
}

struct PngChunk {
  std::string type;
  std::vector<std::uint8_t> data;
};

inline std::vector<std::uint8_t> read_file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Splits a PNG into chunks, checking the signature and every CRC.
inline std::vector<PngChunk> png_chunks(const std::vector<std::uint8_t>& png) {
  const std::vector<std::uint8_t> signature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  EXPECT_GE(png.size(), signature.size());
  if (png.size() < signature.size()) return {};
  EXPECT_TRUE(std::equal(signature.begin(), signature.end(), png.begin()));
  std::vector<PngChunk> chunks;
  std::size_t at = signature.size();
  while (at + 12 <= png.size()) {
    const std::uint32_t length = png_u32(png, at);
    if (at + 12 + length > png.size()) break;
    PngChunk chunk;
    chunk.type.assign(png.begin() + static_cast<std::ptrdiff_t>(at + 4),
                      png.begin() + static_cast<std::ptrdiff_t>(at + 8));
    chunk.data.assign(png.begin() + static_cast<std::ptrdiff_t>(at + 8),
                      png.begin() + static_cast<std::ptrdiff_t>(at + 8 + length));
    const uLong crc = crc32(0L, png.data() + at + 4, static_cast<uInt>(4 + length));
    EXPECT_EQ(png_u32(png, at + 8 + length), static_cast<std::uint32_t>(crc)) << chunk.type;
    chunks.push_back(std::move(chunk));
    at += 12 + length;
  }
  EXPECT_EQ(at, png.size());
  return chunks;
}

// A decoded image: samples without the filter bytes, `channels` per pixel, row 0 at the top.
struct PngImage {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::uint32_t channels = 0;  // 1: grey, 3: RGB
  std::vector<std::uint8_t> samples;
};

// Decodes a file of the kind occgeo_mapfile writes (IHDR, one IDAT, IEND; every row filter 0); a failed expectation
// and an empty image otherwise.
inline PngImage decode_png(const std::vector<std::uint8_t>& png) {
  const auto chunks = png_chunks(png);
  PngImage image;
  EXPECT_EQ(chunks.size(), 3U);
  if (chunks.size() != 3 || chunks[0].type != "IHDR" || chunks[1].type != "IDAT" || chunks[2].type != "IEND" ||
      chunks[0].data.size() != 13) {
    ADD_FAILURE() << "not an IHDR, IDAT, IEND file";
    return {};
  }
  image.width = png_u32(chunks[0].data, 0);
  image.height = png_u32(chunks[0].data, 4);
  EXPECT_EQ(chunks[0].data[8], 8) << "bit depth";
  image.channels = chunks[0].data[9] == 2 ? 3 : 1;
  const std::size_t row_bytes = static_cast<std::size_t>(image.width) * image.channels + 1;
  std::vector<std::uint8_t> raw(row_bytes * image.height + 16);
  uLongf raw_size = static_cast<uLongf>(raw.size());
  const int status =
      uncompress(raw.data(), &raw_size, chunks[1].data.data(), static_cast<uLong>(chunks[1].data.size()));
  EXPECT_EQ(status, Z_OK);
  EXPECT_EQ(raw_size, row_bytes * image.height);
  if (status != Z_OK || raw_size != row_bytes * image.height) return {};
  for (std::uint32_t row = 0; row < image.height; ++row) {
    EXPECT_EQ(raw[row * row_bytes], 0) << "row " << row << " filter";
    const auto begin = raw.begin() + static_cast<std::ptrdiff_t>(row * row_bytes + 1);
    image.samples.insert(image.samples.end(), begin, begin + static_cast<std::ptrdiff_t>(row_bytes - 1));
  }
  return image;
}

}  // namespace occgeo::testing
