#include "occgeo/sim/run_picture.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "occgeo/sim/shape_world.h"

namespace occgeo::sim {
namespace {

// Largest side of a rasterised shape world, pixels: 1 km at 0.05 m, 1.2 GB of RGB.
constexpr double kMaxShapePictureSide_px = 20000.0;

constexpr mapfile::Rgb kObstacle{0, 0, 0};

mapfile::MapPicture pixel_world_picture(const World& world) {
  mapfile::MapPicture picture{
      mapfile::RgbImage(static_cast<std::uint32_t>(world.width()), static_cast<std::uint32_t>(world.height()),
                        mapfile::Rgb{255, 255, 255}),
      world.origin().x(), world.origin().y(), world.resolution_m()};
  for (int row = 0; row < world.height(); ++row) {
    for (int col = 0; col < world.width(); ++col) {
      if (world.is_obstacle({col, row})) picture.image.set(col, row, kObstacle);
    }
  }
  return picture;
}

// True when p is inside the shape or on its boundary (polygons are convex and counter-clockwise).
bool contains(const Shape& shape, const Eigen::Vector2d& p) {
  if (shape.kind == Shape::Kind::circle) return (p - shape.center).norm() <= shape.radius_m;
  for (std::size_t i = 0; i < shape.points.size(); ++i) {
    const Eigen::Vector2d& a = shape.points[i];
    const Eigen::Vector2d& b = shape.points[(i + 1) % shape.points.size()];
    const Eigen::Vector2d edge = b - a;
    const Eigen::Vector2d to_p = p - a;
    if (edge.x() * to_p.y() - edge.y() * to_p.x() < 0.0) return false;
  }
  return true;
}

// Lower-left and upper-right corners of the shape's bounding box, metres.
std::pair<Eigen::Vector2d, Eigen::Vector2d> box_of(const Shape& shape) {
  if (shape.kind == Shape::Kind::circle) {
    const Eigen::Vector2d r(shape.radius_m, shape.radius_m);
    return {shape.center - r, shape.center + r};
  }
  Eigen::Vector2d lo = shape.points.front();
  Eigen::Vector2d hi = shape.points.front();
  for (const Eigen::Vector2d& p : shape.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return {lo, hi};
}

mapfile::MapPicture shape_world_picture(const ShapeWorld& world, const std::vector<geometry::Pose2>& trajectory,
                                        double time_s) {
  std::vector<Shape> shapes = world.shapes();
  for (const MovingObstacle& moving : world.moving()) shapes.push_back(moving.shape_at(time_s));

  Eigen::Vector2d lo;
  Eigen::Vector2d hi;
  if (world.bounds()) {
    lo = world.bounds()->first;
    hi = world.bounds()->second;
  } else {
    lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    hi = -lo;
    for (const Shape& shape : shapes) {
      const auto [shape_lo, shape_hi] = box_of(shape);
      lo = lo.cwiseMin(shape_lo);
      hi = hi.cwiseMax(shape_hi);
    }
    for (const geometry::Pose2& pose : trajectory) {
      lo = lo.cwiseMin(Eigen::Vector2d(pose.x, pose.y));
      hi = hi.cwiseMax(Eigen::Vector2d(pose.x, pose.y));
    }
    if (!lo.allFinite() || !hi.allFinite()) {  // no shapes and no trajectory: the origin
      lo.setZero();
      hi.setZero();
    }
    lo -= Eigen::Vector2d::Constant(kShapePictureMargin_m);
    hi += Eigen::Vector2d::Constant(kShapePictureMargin_m);
  }
  // The tolerance keeps a side that is a whole number of pixels, bar rounding, from gaining a column.
  const double width_px = std::ceil((hi.x() - lo.x()) / kShapePictureResolution_m - 1e-9);
  const double height_px = std::ceil((hi.y() - lo.y()) / kShapePictureResolution_m - 1e-9);
  if (!(width_px <= kMaxShapePictureSide_px && height_px <= kMaxShapePictureSide_px)) {
    throw std::runtime_error("the shape world spans " + std::to_string(hi.x() - lo.x()) + " x " +
                             std::to_string(hi.y() - lo.y()) + " m, more than 20000 pixels of " +
                             std::to_string(kShapePictureResolution_m) + " m a side");
  }
  mapfile::MapPicture picture{
      mapfile::RgbImage(static_cast<std::uint32_t>(std::max(width_px, 1.0)),
                        static_cast<std::uint32_t>(std::max(height_px, 1.0)), mapfile::Rgb{255, 255, 255}),
      lo.x(), lo.y(), kShapePictureResolution_m};
  const double max_col = picture.image.width() - 1.0;
  const double max_row = picture.image.height() - 1.0;
  for (const Shape& shape : shapes) {
    const auto [shape_lo, shape_hi] = box_of(shape);
    // Canvas rows grow downwards: the box's top (largest y) is its first row.
    const mapfile::MapPoint top_left = picture.canvas_of({shape_lo.x(), shape_hi.y()});
    const mapfile::MapPoint bottom_right = picture.canvas_of({shape_hi.x(), shape_lo.y()});
    const auto col_lo = static_cast<std::int64_t>(std::clamp(std::floor(top_left.x), 0.0, max_col));
    const auto col_hi = static_cast<std::int64_t>(std::clamp(std::floor(bottom_right.x), 0.0, max_col));
    const auto row_lo = static_cast<std::int64_t>(std::clamp(std::floor(top_left.y), 0.0, max_row));
    const auto row_hi = static_cast<std::int64_t>(std::clamp(std::floor(bottom_right.y), 0.0, max_row));
    for (std::int64_t row = row_lo; row <= row_hi; ++row) {
      for (std::int64_t col = col_lo; col <= col_hi; ++col) {
        const mapfile::MapPoint c = picture.pixel_center(static_cast<double>(col), static_cast<double>(row));
        if (contains(shape, {c.x, c.y})) picture.image.set(col, row, kObstacle);
      }
    }
  }
  return picture;
}

}  // namespace

mapfile::MapPicture run_picture(const SimWorld& world, const std::vector<geometry::Pose2>& trajectory, double time_s) {
  mapfile::MapPicture picture;
  if (const auto* pixels = dynamic_cast<const PixelWorld*>(&world)) {
    picture = pixel_world_picture(pixels->grid());
  } else if (const auto* shapes = dynamic_cast<const ShapeWorld*>(&world)) {
    picture = shape_world_picture(*shapes, trajectory, time_s);
  } else {
    throw std::runtime_error("no picture for this kind of world");
  }
  mapfile::PictureOverlays overlays;
  for (const geometry::Pose2& pose : trajectory) overlays.trajectory.push_back({pose.x, pose.y});
  if (!trajectory.empty()) {
    overlays.markers.push_back({trajectory.back().x, trajectory.back().y, trajectory.back().theta});
  }
  mapfile::draw_overlays(picture, overlays);
  return picture;
}

}  // namespace occgeo::sim
