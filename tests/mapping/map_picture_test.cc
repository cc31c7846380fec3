// Map pictures (occgeo_mapfile): certainty colours at known cells, the canvas size with the scale, circle outlines at
// the right radius with their restricted discs tinted, trajectory pixels on the line, pose markers, and the PNG file.
#include "occgeo/mapfile/map_picture.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "../support/temp_dir.h"
#include "png_reader.h"

namespace occgeo::mapfile {
namespace {

constexpr Rgb kWhite{255, 255, 255};
constexpr Rgb kBlack{0, 0, 0};

// 10 x 6 cells of 0.1 m from cell (-5, -3), i.e. x in [-0.5, 0.5), y in [-0.3, 0.3); all free (0) except those set.
CertaintyWindow window() {
  CertaintyWindow w;
  w.cell_size_m = 0.1;
  w.min_ix = -5;
  w.min_iy = -3;
  w.width = 10;
  w.height = 6;
  w.max_certainty = 15;
  w.occupied_threshold = 3;
  w.cells.assign(60, 0);
  return w;
}

// 4 m x 4 m of free 0.1 m cells from (0, 0): 40 x 40 cells.
CertaintyWindow free_square() {
  CertaintyWindow w = window();
  w.min_ix = 0;
  w.min_iy = 0;
  w.width = 40;
  w.height = 40;
  w.cells.assign(1600, 0);
  return w;
}

void set_cell(CertaintyWindow& w, std::uint32_t ix, std::uint32_t iy, std::uint8_t value) {
  w.cells[static_cast<std::size_t>(iy) * w.width + ix] = value;
}

bool is_grey(Rgb c) { return c.r == c.g && c.g == c.b; }

TEST(MapPicture, CertaintyColoursAtKnownCellsWithRowZeroAtTheTop) {
  CertaintyWindow w = window();
  set_cell(w, 0, 0, 15);                    // bottom-left: fully occupied
  set_cell(w, 9, 5, kUnobservedCertainty);  // top-right: never seen
  set_cell(w, 4, 2, 3);                     // just occupied
  set_cell(w, 5, 2, 2);                     // free, but not certain
  const MapPicture picture = render_certainty(w, 1);
  ASSERT_EQ(picture.image.width(), 10U);
  ASSERT_EQ(picture.image.height(), 6U);
  EXPECT_EQ(picture.image.at(0, 5), kBlack);
  EXPECT_EQ(picture.image.at(9, 0), kUnknownColour);
  EXPECT_EQ(picture.image.at(1, 1), kWhite);
  const Rgb just_occupied = picture.image.at(4, 3);
  const Rgb unsure_free = picture.image.at(5, 3);
  EXPECT_TRUE(is_grey(just_occupied) && is_grey(unsure_free));
  EXPECT_LT(just_occupied.r, 85);
  EXPECT_GT(just_occupied.r, 0);
  EXPECT_GT(unsure_free.r, 170);
  EXPECT_LT(unsure_free.r, 255);
  // Every certainty keeps its side of unknown's grey.
  for (int c = 0; c <= 15; ++c) {
    const Rgb colour = certainty_colour(static_cast<std::uint8_t>(c), 15, 3);
    if (c < 3) {
      EXPECT_GT(colour.r, kUnknownColour.r) << c;
    } else {
      EXPECT_LT(colour.r, kUnknownColour.r) << c;
    }
  }
  EXPECT_NEAR(picture.pixel_size_m, 0.1, 1e-12);
  EXPECT_NEAR(picture.origin_x, -0.5, 1e-12);
  EXPECT_NEAR(picture.origin_y, -0.3, 1e-12);
}

TEST(MapPicture, ScaleMultipliesTheSizeAndRepeatsEachCell) {
  CertaintyWindow w = window();
  set_cell(w, 2, 1, 15);
  const MapPicture picture = render_certainty(w, 4);
  EXPECT_EQ(picture.image.width(), 40U);
  EXPECT_EQ(picture.image.height(), 24U);
  EXPECT_EQ(picture.image.bytes().size(), 40U * 24U * 3U);
  EXPECT_NEAR(picture.pixel_size_m, 0.025, 1e-12);
  // Cell (2, 1) is window row 1, canvas rows (6 - 1 - 1) * 4 .. + 3, columns 8 .. 11.
  for (std::uint32_t row = 16; row < 20; ++row) {
    for (std::uint32_t col = 8; col < 12; ++col) EXPECT_EQ(picture.image.at(col, row), kBlack) << col << ", " << row;
  }
  EXPECT_EQ(picture.image.at(7, 16), kWhite);
  EXPECT_EQ(picture.image.at(8, 15), kWhite);
  EXPECT_EQ(picture.image.at(12, 19), kWhite);
  EXPECT_EQ(picture.image.at(11, 20), kWhite);
  EXPECT_THROW((void)render_certainty(w, 0), MapFileError);
}

TEST(MapPicture, RejectsInconsistentWindows) {
  CertaintyWindow w = window();
  w.cells.pop_back();
  EXPECT_THROW((void)render_certainty(w, 1), MapFileError);
  w = window();
  set_cell(w, 0, 0, 16);
  EXPECT_THROW((void)render_certainty(w, 1), MapFileError);
  w = window();
  w.occupied_threshold = 0;
  EXPECT_THROW((void)render_certainty(w, 1), MapFileError);
}

TEST(MapPicture, CircleOutlineLiesAtItsRadiusAndTheRestrictedDiscIsTinted) {
  // 4 m x 4 m of 0.1 m cells from (0, 0) at scale 2: 0.05 m pixels, 80 x 80.
  const CertaintyWindow w = free_square();
  MapPicture picture = render_certainty(w, 2);
  PictureOverlays overlays;
  // Centre (2, 2) is the corner between pixels (39, 39)-(40, 40); radius 1 m = 20 pixels, restricted 0.5 m.
  overlays.circles.push_back({{2.0, 2.0}, 1.0, 0.5});
  draw_overlays(picture, overlays);
  // Along the row just below the centre (pixel centres 0.5 px off the axis), the outline is 20 pixels out.
  EXPECT_EQ(picture.image.at(59, 40), kCircleColour);  // centre 59.5: distance hypot(19.5, 0.5) = 19.506
  EXPECT_EQ(picture.image.at(20, 40), kCircleColour);  // 20.5 to the left
  EXPECT_EQ(picture.image.at(40, 20), kCircleColour);  // and straight up
  EXPECT_EQ(picture.image.at(61, 40), kWhite);         // 21.5 px out: outside
  EXPECT_EQ(picture.image.at(57, 40), kWhite);         // 17.5 px: between the disc and the outline
  // Inside 10 px: halfway from white to the tint.
  const Rgb tinted = picture.image.at(40, 40);
  EXPECT_EQ(tinted, (Rgb{255, 208, 128}));
  EXPECT_EQ(picture.image.at(49, 40), tinted);  // 9.5 px out
  EXPECT_EQ(picture.image.at(51, 40), kWhite);  // 11.5 px out
  // Diagonally: pixel (54, 26) has its centre hypot(14.5, 13.5) = 19.81 px out, (53, 25) hypot(13.5, 14.5) too.
  EXPECT_EQ(picture.image.at(54, 26), kCircleColour);
  EXPECT_EQ(picture.image.at(53, 25), kCircleColour);
  EXPECT_EQ(picture.image.at(55, 24), kWhite);  // hypot(15.5, 15.5) = 21.92 px: outside
}

TEST(MapPicture, TrajectoryPixelsLieOnTheLineAndMarkersPointAlongTheirHeading) {
  const CertaintyWindow w = free_square();
  MapPicture picture = render_certainty(w, 1);
  PictureOverlays overlays;
  // Diagonal from (0.55, 0.55) to (3.05, 3.05) then along y = 3.05 to x = 3.95; pixel (col, 39 - col) holds (col, col).
  overlays.trajectory = {{0.55, 0.55}, {3.05, 3.05}, {3.95, 3.05}};
  draw_overlays(picture, overlays);
  for (std::uint32_t k = 5; k <= 30; ++k) EXPECT_EQ(picture.image.at(k, 39 - k), kTrajectoryColour) << k;
  for (std::uint32_t col = 30; col <= 39; ++col) EXPECT_EQ(picture.image.at(col, 9), kTrajectoryColour) << col;
  EXPECT_EQ(picture.image.at(10, 39 - 12), kWhite);  // off the diagonal
  EXPECT_EQ(picture.image.at(4, 35), kWhite);        // before its start
  // Every trajectory pixel's centre lies within a pixel of the polyline (canvas (5.5, 34.5) - (30.5, 9.5) -
  // (39.5, 9.5)).
  for (std::uint32_t row = 0; row < 40; ++row) {
    for (std::uint32_t col = 0; col < 40; ++col) {
      if (picture.image.at(col, row) != kTrajectoryColour) continue;
      const double x = col + 0.5;
      const double y = row + 0.5;
      const double to_diagonal = x <= 30.5 ? std::abs(x + y - 40.0) / std::sqrt(2.0) : 1e9;
      const double to_top = x >= 30.5 ? std::abs(y - 9.5) : 1e9;
      EXPECT_LE(std::min(to_diagonal, to_top), 1.0) << col << ", " << row;
    }
  }

  // A marker at (2, 1) heading +y: its tip pixels are above the pose (smaller rows), none below its base.
  MapPicture marked = render_certainty(w, 1);
  PictureOverlays marker;
  marker.markers.push_back({2.0, 1.0, std::numbers::pi / 2.0});
  draw_overlays(marked, marker);
  EXPECT_EQ(marked.image.at(20, 25), kMarkerColour);  // 5 px ahead, on the axis (pose at canvas (20, 30))
  EXPECT_EQ(marked.image.at(20, 32), kWhite);         // behind the pose
  EXPECT_EQ(marked.image.at(26, 29), kWhite);         // wider than its base
}

TEST(MapPicture, OverlaysOffTheCanvasAreClipped) {
  CertaintyWindow w = window();
  MapPicture picture = render_certainty(w, 1);
  PictureOverlays overlays;
  overlays.circles.push_back({{100.0, 100.0}, 5.0, 5.0});
  overlays.trajectory = {{-1e9, 0.0}, {1e9, 0.05}, {std::nan(""), 0.0}};
  overlays.markers.push_back({50.0, -50.0, 1.0});
  EXPECT_NO_THROW(draw_overlays(picture, overlays));
}

TEST(MapPicture, OccupancyImagePixelsReadAsMapServerDoes) {
  OccupancyImage image;
  image.width = 3;
  image.height = 1;
  image.resolution = 0.05;
  image.pixels = {0, 254, 205};
  const MapPicture picture = render_occupancy(image, 2);
  ASSERT_EQ(picture.image.width(), 6U);
  ASSERT_EQ(picture.image.height(), 2U);
  EXPECT_EQ(picture.image.at(1, 1), kBlack);
  EXPECT_EQ(picture.image.at(2, 0), kWhite);
  EXPECT_EQ(picture.image.at(5, 1), kUnknownColour);
}

TEST(MapPicture, WritesAnRgbPngOfTheCanvas) {
  occgeo::testing::TempDir dir;
  CertaintyWindow w = window();
  set_cell(w, 0, 0, 15);
  const MapPicture picture = render_certainty(w, 3);
  const auto path = dir.path() / "map.png";
  picture.write_png(path);
  const auto decoded = occgeo::testing::decode_png(occgeo::testing::read_file_bytes(path));
  EXPECT_EQ(decoded.width, 30U);
  EXPECT_EQ(decoded.height, 18U);
  EXPECT_EQ(decoded.channels, 3U);
  EXPECT_EQ(decoded.samples, picture.image.bytes());
}

}  // namespace
}  // namespace occgeo::mapfile
