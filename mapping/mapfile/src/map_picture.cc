#include "occgeo/mapfile/map_picture.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "occgeo/mapfile/png.h"

namespace occgeo::mapfile {
namespace {

// Grey bands of certainty_colour: free certainties stay above kFreeFloor, occupied ones below kOccupiedCeiling, and
// unknown sits at 128 between them.
constexpr double kFreeFloor = 170.0;
constexpr double kOccupiedCeiling = 85.0;
// Side of a pose marker's triangle (tip to base), canvas pixels: fixed so it shows at any scale.
constexpr double kMarkerLength_px = 9.0;
// Step along a trajectory segment between stamped points, canvas pixels; below 1 so no pixel is skipped.
constexpr double kLineStep_px = 0.25;

Rgb grey(double level) {
  const auto v = static_cast<std::uint8_t>(std::clamp(std::lround(level), 0L, 255L));
  return {v, v, v};
}

Rgb blend(Rgb base, Rgb tint) {
  const auto mix = [](std::uint8_t a, std::uint8_t b) { return static_cast<std::uint8_t>((a + b + 1) / 2); };
  return {mix(base.r, tint.r), mix(base.g, tint.g), mix(base.b, tint.b)};
}

void check_scale(std::uint32_t scale) {
  if (scale == 0) throw MapFileError("map picture: scale must be at least 1");
}

// Canvas pixel range [lo, hi] of pixels whose centres may lie within [a, b] (canvas coordinates), clipped.
std::pair<std::int64_t, std::int64_t> span(double a, double b, std::uint32_t size) {
  const double lo = std::max(std::floor(a) - 1.0, 0.0);
  const double hi = std::min(std::ceil(b) + 1.0, static_cast<double>(size) - 1.0);
  return {static_cast<std::int64_t>(lo), static_cast<std::int64_t>(hi)};
}

bool finite(const MapPoint& p) { return std::isfinite(p.x) && std::isfinite(p.y); }

// Sets the line_width x line_width block of pixels around canvas point p.
void stamp(RgbImage& image, const MapPoint& p, std::uint32_t line_width, Rgb colour) {
  const auto width = static_cast<std::int64_t>(line_width);
  const auto col = static_cast<std::int64_t>(std::floor(p.x)) - (width - 1) / 2;
  const auto row = static_cast<std::int64_t>(std::floor(p.y)) - (width - 1) / 2;
  for (std::int64_t dr = 0; dr < width; ++dr) {
    for (std::int64_t dc = 0; dc < width; ++dc) image.set(col + dc, row + dr, colour);
  }
}

void draw_restricted_disc(MapPicture& picture, const MapPoint& c, double radius_px) {
  if (!(radius_px > 0.0)) return;
  RgbImage& image = picture.image;
  const auto [col_lo, col_hi] = span(c.x - radius_px, c.x + radius_px, image.width());
  const auto [row_lo, row_hi] = span(c.y - radius_px, c.y + radius_px, image.height());
  for (std::int64_t row = row_lo; row <= row_hi; ++row) {
    for (std::int64_t col = col_lo; col <= col_hi; ++col) {
      const double dx = static_cast<double>(col) + 0.5 - c.x;
      const double dy = static_cast<double>(row) + 0.5 - c.y;
      if (std::hypot(dx, dy) <= radius_px) {
        const auto u_col = static_cast<std::uint32_t>(col);
        const auto u_row = static_cast<std::uint32_t>(row);
        image.set(col, row, blend(image.at(u_col, u_row), kRestrictedTint));
      }
    }
  }
}

// The pixels whose centres lie within half a line width of the circle.
void draw_outline(MapPicture& picture, const MapPoint& c, double radius_px, std::uint32_t line_width) {
  RgbImage& image = picture.image;
  const double half = 0.5 * static_cast<double>(line_width);
  const auto [col_lo, col_hi] = span(c.x - radius_px - half, c.x + radius_px + half, image.width());
  const auto [row_lo, row_hi] = span(c.y - radius_px - half, c.y + radius_px + half, image.height());
  for (std::int64_t row = row_lo; row <= row_hi; ++row) {
    for (std::int64_t col = col_lo; col <= col_hi; ++col) {
      const double d = std::hypot(static_cast<double>(col) + 0.5 - c.x, static_cast<double>(row) + 0.5 - c.y);
      if (std::abs(d - radius_px) <= half) image.set(col, row, kCircleColour);
    }
  }
}

// Clips segment a-b to the box [lo, hi] x [lo_y, hi_y] (Liang-Barsky); false when nothing of it is inside.
bool clip(MapPoint& a, MapPoint& b, double lo_x, double hi_x, double lo_y, double hi_y) {
  double t0 = 0.0;
  double t1 = 1.0;
  const double dx = b.x - a.x;
  const double dy = b.y - a.y;
  const auto edge = [&](double p, double q) {
    if (p == 0.0) return q >= 0.0;
    const double t = q / p;
    if (p < 0.0) {
      t0 = std::max(t0, t);
    } else {
      t1 = std::min(t1, t);
    }
    return t0 <= t1;
  };
  if (!edge(-dx, a.x - lo_x) || !edge(dx, hi_x - a.x) || !edge(-dy, a.y - lo_y) || !edge(dy, hi_y - a.y)) return false;
  const MapPoint start{a.x + t0 * dx, a.y + t0 * dy};
  b = {a.x + t1 * dx, a.y + t1 * dy};
  a = start;
  return true;
}

void draw_polyline(MapPicture& picture, const std::vector<MapPoint>& points, std::uint32_t line_width) {
  std::vector<MapPoint> canvas;
  canvas.reserve(points.size());
  for (const MapPoint& p : points) {
    if (finite(p)) canvas.push_back(picture.canvas_of(p));
  }
  if (canvas.size() == 1) stamp(picture.image, canvas.front(), line_width, kTrajectoryColour);
  // Segments are clipped to the canvas (with a line width of margin) first, so a far-off point costs nothing.
  const double margin = static_cast<double>(line_width) + 1.0;
  const double hi_x = static_cast<double>(picture.image.width()) + margin;
  const double hi_y = static_cast<double>(picture.image.height()) + margin;
  for (std::size_t i = 1; i < canvas.size(); ++i) {
    MapPoint a = canvas[i - 1];
    MapPoint b = canvas[i];
    if (!clip(a, b, -margin, hi_x, -margin, hi_y)) continue;
    const double length = std::hypot(b.x - a.x, b.y - a.y);
    const auto steps = static_cast<std::int64_t>(std::ceil(length / kLineStep_px));
    for (std::int64_t k = 0; k <= steps; ++k) {
      const double t = steps == 0 ? 0.0 : static_cast<double>(k) / static_cast<double>(steps);
      stamp(picture.image, {a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)}, line_width, kTrajectoryColour);
    }
  }
}

double cross(const MapPoint& o, const MapPoint& a, const MapPoint& b) {
  return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

// A filled triangle with its tip kMarkerLength_px ahead of the pose along theta and its base centred on the pose.
void draw_marker(MapPicture& picture, const PicturePose& pose) {
  if (!std::isfinite(pose.x) || !std::isfinite(pose.y) || !std::isfinite(pose.theta)) return;
  const MapPoint c = picture.canvas_of({pose.x, pose.y});
  // Canvas rows grow downwards, so the heading's y component flips.
  const double ux = std::cos(pose.theta);
  const double uy = -std::sin(pose.theta);
  const double half_base = 0.4 * kMarkerLength_px;
  const MapPoint tip{c.x + kMarkerLength_px * ux, c.y + kMarkerLength_px * uy};
  const MapPoint left{c.x - half_base * uy, c.y + half_base * ux};
  const MapPoint right{c.x + half_base * uy, c.y - half_base * ux};
  RgbImage& image = picture.image;
  const auto [col_lo, col_hi] = span(c.x - kMarkerLength_px, c.x + kMarkerLength_px, image.width());
  const auto [row_lo, row_hi] = span(c.y - kMarkerLength_px, c.y + kMarkerLength_px, image.height());
  for (std::int64_t row = row_lo; row <= row_hi; ++row) {
    for (std::int64_t col = col_lo; col <= col_hi; ++col) {
      const MapPoint p{static_cast<double>(col) + 0.5, static_cast<double>(row) + 0.5};
      const double d1 = cross(tip, left, p);
      const double d2 = cross(left, right, p);
      const double d3 = cross(right, tip, p);
      const bool has_negative = d1 < 0.0 || d2 < 0.0 || d3 < 0.0;
      const bool has_positive = d1 > 0.0 || d2 > 0.0 || d3 > 0.0;
      if (!(has_negative && has_positive)) image.set(col, row, kMarkerColour);
    }
  }
}

}  // namespace

RgbImage::RgbImage(std::uint32_t width, std::uint32_t height, Rgb fill)
    : width_(width), height_(height), bytes_(static_cast<std::size_t>(width) * height * 3) {
  for (std::size_t i = 0; i < bytes_.size(); i += 3) {
    bytes_[i] = fill.r;
    bytes_[i + 1] = fill.g;
    bytes_[i + 2] = fill.b;
  }
}

Rgb RgbImage::at(std::uint32_t col, std::uint32_t row) const {
  if (col >= width_ || row >= height_) {
    throw std::out_of_range("pixel (" + std::to_string(col) + ", " + std::to_string(row) + ") is outside the " +
                            std::to_string(width_) + " x " + std::to_string(height_) + " picture");
  }
  const std::size_t i = (static_cast<std::size_t>(row) * width_ + col) * 3;
  return {bytes_[i], bytes_[i + 1], bytes_[i + 2]};
}

void RgbImage::set(std::int64_t col, std::int64_t row, Rgb colour) {
  if (col < 0 || row < 0 || col >= static_cast<std::int64_t>(width_) || row >= static_cast<std::int64_t>(height_)) {
    return;
  }
  const std::size_t i = (static_cast<std::size_t>(row) * width_ + static_cast<std::size_t>(col)) * 3;
  bytes_[i] = colour.r;
  bytes_[i + 1] = colour.g;
  bytes_[i + 2] = colour.b;
}

MapPoint MapPicture::pixel_center(double col, double row) const {
  return {origin_x + (col + 0.5) * pixel_size_m,
          origin_y + (static_cast<double>(image.height()) - row - 0.5) * pixel_size_m};
}

MapPoint MapPicture::canvas_of(const MapPoint& p) const {
  return {(p.x - origin_x) / pixel_size_m, static_cast<double>(image.height()) - (p.y - origin_y) / pixel_size_m};
}

void MapPicture::write_png(const std::filesystem::path& path) const {
  write_png_rgb8(path, image.width(), image.height(), image.bytes());
}

Rgb certainty_colour(std::uint8_t value, int max_certainty, int occupied_threshold) {
  if (value == kUnobservedCertainty) return kUnknownColour;
  const double c = value;
  if (value < occupied_threshold) return grey(255.0 - (255.0 - kFreeFloor) * c / occupied_threshold);
  const double occupied_steps = max_certainty - occupied_threshold + 1;
  return grey(kOccupiedCeiling * (max_certainty - c) / occupied_steps);
}

MapPicture render_certainty(const CertaintyWindow& window, std::uint32_t scale) {
  check_scale(scale);
  if (window.width == 0 || window.height == 0) throw MapFileError("map picture: the window has no cells");
  if (window.cells.size() != static_cast<std::size_t>(window.width) * window.height) {
    throw MapFileError("map picture: " + std::to_string(window.cells.size()) + " cells for a " +
                       std::to_string(window.width) + " x " + std::to_string(window.height) + " window");
  }
  if (window.occupied_threshold < 1 || window.max_certainty < window.occupied_threshold || window.max_certainty > 15) {
    throw MapFileError("map picture: certainty parameters need 1 <= occupied_threshold (" +
                       std::to_string(window.occupied_threshold) + ") <= max_certainty (" +
                       std::to_string(window.max_certainty) + ") <= 15");
  }
  if (!(window.cell_size_m > 0.0) || !std::isfinite(window.cell_size_m)) {
    throw MapFileError("map picture: cell_size_m must be positive and finite");
  }
  std::array<Rgb, 256> colour_of{};
  for (int v = 0; v < 256; ++v) {
    if (v <= window.max_certainty || v == kUnobservedCertainty) {
      colour_of[static_cast<std::size_t>(v)] =
          certainty_colour(static_cast<std::uint8_t>(v), window.max_certainty, window.occupied_threshold);
    }
  }
  MapPicture picture{RgbImage(window.width * scale, window.height * scale, kUnknownColour),
                     window.min_ix * window.cell_size_m, window.min_iy * window.cell_size_m,
                     window.cell_size_m / scale};
  for (std::uint32_t iy = 0; iy < window.height; ++iy) {
    for (std::uint32_t ix = 0; ix < window.width; ++ix) {
      const std::uint8_t value = window.cells[static_cast<std::size_t>(iy) * window.width + ix];
      if (value > window.max_certainty && value != kUnobservedCertainty) {
        throw MapFileError("map picture: cell (" + std::to_string(ix) + ", " + std::to_string(iy) + ") holds " +
                           std::to_string(value) + ", above max_certainty " + std::to_string(window.max_certainty));
      }
      const Rgb colour = colour_of[value];
      const std::uint32_t top = (window.height - 1 - iy) * scale;
      for (std::uint32_t dr = 0; dr < scale; ++dr) {
        for (std::uint32_t dc = 0; dc < scale; ++dc) picture.image.set(ix * scale + dc, top + dr, colour);
      }
    }
  }
  return picture;
}

MapPicture render_occupancy(const OccupancyImage& image, std::uint32_t scale) {
  check_scale(scale);
  if (image.width == 0 || image.height == 0) throw MapFileError("map picture: the image has no pixels");
  if (image.pixels.size() != static_cast<std::size_t>(image.width) * image.height) {
    throw MapFileError("map picture: " + std::to_string(image.pixels.size()) + " pixels for a " +
                       std::to_string(image.width) + " x " + std::to_string(image.height) + " image");
  }
  if (!(image.resolution > 0.0) || !std::isfinite(image.resolution)) {
    throw MapFileError("map picture: resolution must be positive and finite");
  }
  MapPicture picture{RgbImage(image.width * scale, image.height * scale, kUnknownColour), image.origin_x,
                     image.origin_y, image.resolution / scale};
  for (std::uint32_t row = 0; row < image.height; ++row) {
    for (std::uint32_t col = 0; col < image.width; ++col) {
      Rgb colour = kUnknownColour;
      switch (image.state(col, row)) {
        case OccupancyImage::CellState::occupied:
          colour = {0, 0, 0};
          break;
        case OccupancyImage::CellState::free:
          colour = {255, 255, 255};
          break;
        case OccupancyImage::CellState::unknown:
          break;
      }
      for (std::uint32_t dr = 0; dr < scale; ++dr) {
        for (std::uint32_t dc = 0; dc < scale; ++dc) picture.image.set(col * scale + dc, row * scale + dr, colour);
      }
    }
  }
  return picture;
}

void draw_overlays(MapPicture& picture, const PictureOverlays& overlays) {
  const std::uint32_t line_width = std::max<std::uint32_t>(overlays.line_width_px, 1);
  for (const PictureCircle& circle : overlays.circles) {
    if (!finite(circle.center) || !std::isfinite(circle.restricted_radius_m)) continue;
    draw_restricted_disc(picture, picture.canvas_of(circle.center), circle.restricted_radius_m / picture.pixel_size_m);
  }
  for (const PictureCircle& circle : overlays.circles) {
    if (!finite(circle.center) || !std::isfinite(circle.radius_m) || circle.radius_m < 0.0) continue;
    draw_outline(picture, picture.canvas_of(circle.center), circle.radius_m / picture.pixel_size_m, line_width);
  }
  draw_polyline(picture, overlays.trajectory, line_width);
  for (const PicturePose& pose : overlays.markers) draw_marker(picture, pose);
}

}  // namespace occgeo::mapfile
