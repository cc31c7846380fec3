// occgeo_mapfile's PNG encoder, checked by decoding with zlib: header fields, CRCs and the inflated rows.
#include <gtest/gtest.h>

#include <random>
#include <stdexcept>

#include "occgeo/mapfile/png.h"
#include "png_reader.h"

namespace occgeo::mapfile {
namespace {

using occgeo::testing::decode_png;
using occgeo::testing::png_chunks;
using occgeo::testing::png_u32;

std::vector<std::uint8_t> random_bytes(std::size_t count, unsigned seed) {
  std::vector<std::uint8_t> bytes(count);
  std::mt19937 rng(seed);
  for (auto& b : bytes) b = static_cast<std::uint8_t>(rng() % 256);
  return bytes;
}

TEST(Png, GreyHeaderAndInflatedRowsMatchThePixels) {
  constexpr std::uint32_t kWidth = 37, kHeight = 5;
  const std::vector<std::uint8_t> pixels = random_bytes(kWidth * kHeight, 3);
  const std::vector<std::uint8_t> png = encode_png_gray8(kWidth, kHeight, pixels);
  const auto chunks = png_chunks(png);
  ASSERT_EQ(chunks.size(), 3U);
  ASSERT_EQ(chunks[0].type, "IHDR");
  ASSERT_EQ(chunks[0].data.size(), 13U);
  EXPECT_EQ(png_u32(chunks[0].data, 0), kWidth);
  EXPECT_EQ(png_u32(chunks[0].data, 4), kHeight);
  EXPECT_EQ(chunks[0].data[8], 8);   // bit depth
  EXPECT_EQ(chunks[0].data[9], 0);   // greyscale
  EXPECT_EQ(chunks[0].data[10], 0);  // deflate
  EXPECT_EQ(chunks[0].data[11], 0);  // adaptive filtering method
  EXPECT_EQ(chunks[0].data[12], 0);  // not interlaced
  EXPECT_EQ(chunks[1].type, "IDAT");
  EXPECT_EQ(chunks[2].type, "IEND");
  EXPECT_TRUE(chunks[2].data.empty());
  const auto image = decode_png(png);
  EXPECT_EQ(image.channels, 1U);
  EXPECT_EQ(image.samples, pixels);
}

TEST(Png, RgbHeaderAndInflatedRowsMatchThePixels) {
  constexpr std::uint32_t kWidth = 11, kHeight = 7;
  const std::vector<std::uint8_t> pixels = random_bytes(3 * kWidth * kHeight, 5);
  const std::vector<std::uint8_t> png = encode_png_rgb8(kWidth, kHeight, pixels);
  const auto chunks = png_chunks(png);
  ASSERT_EQ(chunks.size(), 3U);
  EXPECT_EQ(chunks[0].data[9], 2);  // truecolour
  const auto image = decode_png(png);
  EXPECT_EQ(image.width, kWidth);
  EXPECT_EQ(image.height, kHeight);
  EXPECT_EQ(image.channels, 3U);
  EXPECT_EQ(image.samples, pixels);
}

TEST(Png, RejectsInconsistentSizes) {
  EXPECT_THROW(encode_png_gray8(3, 2, std::vector<std::uint8_t>(5)), std::invalid_argument);
  EXPECT_THROW(encode_png_gray8(0, 2, {}), std::invalid_argument);
  EXPECT_THROW(encode_png_rgb8(3, 2, std::vector<std::uint8_t>(6)), std::invalid_argument);
  EXPECT_THROW(encode_png_rgb8(1, 0, {}), std::invalid_argument);
}

}  // namespace
}  // namespace occgeo::mapfile
