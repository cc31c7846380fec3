#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include "occgeo/mapfile/certainty_image.h"
#include "occgeo/mapfile/map_file.h"

namespace occgeo::mapfile {

// An 8-bit RGB colour.
struct Rgb {
  std::uint8_t r = 0;
  std::uint8_t g = 0;
  std::uint8_t b = 0;
  friend bool operator==(const Rgb&, const Rgb&) = default;
};

// Colours of the picture. Grey levels are the map; overlays use saturated colours no map cell can have.
inline constexpr Rgb kUnknownColour{128, 128, 128};
inline constexpr Rgb kTrajectoryColour{255, 0, 0};
inline constexpr Rgb kCircleColour{255, 0, 255};
// Restricted discs are the map blended halfway towards this colour, so what lies under them stays readable.
inline constexpr Rgb kRestrictedTint{255, 160, 0};
inline constexpr Rgb kMarkerColour{0, 96, 255};

// A width x height RGB canvas, row-major, row 0 at the top.
class RgbImage {
 public:
  RgbImage(std::uint32_t width, std::uint32_t height, Rgb fill);

  [[nodiscard]] std::uint32_t width() const { return width_; }
  [[nodiscard]] std::uint32_t height() const { return height_; }
  // The pixel's colour; throws std::out_of_range naming the pixel when it is outside the canvas.
  [[nodiscard]] Rgb at(std::uint32_t col, std::uint32_t row) const;
  // Sets the pixel's colour; pixels outside the canvas are ignored, so overlays may run over its edges.
  void set(std::int64_t col, std::int64_t row, Rgb colour);
  // Three bytes (red, green, blue) per pixel, as encode_png_rgb8 takes them.
  [[nodiscard]] const std::vector<std::uint8_t>& bytes() const { return bytes_; }

 private:
  std::uint32_t width_;
  std::uint32_t height_;
  std::vector<std::uint8_t> bytes_;
};

// A world point (metres) and heading (radians), e.g. a robot's base_link pose.
struct PicturePose {
  double x = 0.0;
  double y = 0.0;
  double theta = 0.0;
};

// A circle in the world, e.g. a PTEM cluster: its outline is drawn, and the disc of restricted_radius_m around the
// same centre (0: none) is tinted.
struct PictureCircle {
  MapPoint center;
  double radius_m = 0.0;
  double restricted_radius_m = 0.0;
};

// What is drawn over the map, in this order: restricted discs, circle outlines, the trajectory, the markers.
struct PictureOverlays {
  std::vector<PictureCircle> circles;
  std::vector<MapPoint> trajectory;  // a polyline through world points, metres
  std::vector<PicturePose> markers;  // each a small triangle pointing along theta
  std::uint32_t line_width_px = 1;   // of outlines and the trajectory, image pixels
};

// A picture of an axis-aligned map: the canvas and where it lies in the world.
struct MapPicture {
  RgbImage image{1, 1, kUnknownColour};
  double origin_x = 0.0;      // world x of the canvas' left edge, metres
  double origin_y = 0.0;      // world y of the canvas' bottom edge, metres
  double pixel_size_m = 0.0;  // side of one canvas pixel, metres

  // World point of the centre of canvas pixel (col, row), metres.
  [[nodiscard]] MapPoint pixel_center(double col, double row) const;
  // Canvas column and row (fractional, pixel centres at .5) of world point p.
  [[nodiscard]] MapPoint canvas_of(const MapPoint& p) const;
  // Writes the canvas as an RGB PNG file; throws std::runtime_error naming the file on failure.
  void write_png(const std::filesystem::path& path) const;
};

// The colour of a HIMM cell value: unobserved (kUnobservedCertainty) is kUnknownColour; free certainties
// (c < occupied_threshold) are light greys from white at 0 down to above 170; occupied ones are dark greys from black
// at max_certainty up to below 85. The three kinds thus never share a grey. Preconditions as CertaintyGreyLevels.
[[nodiscard]] Rgb certainty_colour(std::uint8_t value, int max_certainty, int occupied_threshold);

// The window with every cell a scale x scale block of certainty_colour; row 0 of the canvas is the window's top row.
// Throws MapFileError when the cell count or the certainty parameters are inconsistent, or scale is 0.
[[nodiscard]] MapPicture render_certainty(const CertaintyWindow& window, std::uint32_t scale);

// A map_server image with every pixel a scale x scale block: occupied pixels black, free ones white, unknown ones
// kUnknownColour (map_server's trinary reading). Throws MapFileError when the image is inconsistent or scale is 0.
[[nodiscard]] MapPicture render_occupancy(const OccupancyImage& image, std::uint32_t scale);

// Draws the overlays onto the picture in world coordinates; anything outside the canvas is clipped.
void draw_overlays(MapPicture& picture, const PictureOverlays& overlays);

}  // namespace occgeo::mapfile
