#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "occgeo/sim/sim_world.h"

namespace occgeo::sim {

// Default vertical extent of a shape, metres above the ground.
inline constexpr double kDefaultShapeBaseHeight_m = 0.0;
inline constexpr double kDefaultShapeTopHeight_m = 2.0;

// One prism-shaped obstacle: a circle or a convex polygon (boxes become 4-point polygons) extruded from base_height_m
// up to top_height_m. Coordinates are in the world frame for static shapes and relative to the obstacle's centre for
// moving ones.
struct Shape {
  enum class Kind { circle, polygon };
  Kind kind = Kind::circle;
  std::string name;                     // for messages, e.g. "shapes[2] (box)"
  Eigen::Vector2d center{0.0, 0.0};     // circle centre, metres
  double radius_m = 0.0;                // circle radius, metres
  std::vector<Eigen::Vector2d> points;  // convex polygon, counter-clockwise, metres
  double base_height_m = kDefaultShapeBaseHeight_m;
  double top_height_m = kDefaultShapeTopHeight_m;
  // False for a surface the robot drives over although the laser sees it: a ramp's slope where it crosses the scan
  // plane (seed 000 Fig 5.1). Ground-truth collision ignores it.
  bool solid = true;
  // A ramp's surface: a polygon whose material ends at the plane rising along slope_direction (unit, world frame) at
  // slope_rise (height per metre) from base_height_m where slope_direction · p = slope_start_m, capped at
  // top_height_m. slope_rise = 0: a flat-topped prism.
  Eigen::Vector2d slope_direction{1.0, 0.0};
  double slope_start_m = 0.0;
  double slope_rise = 0.0;

  static Shape circle(const Eigen::Vector2d& center, double radius_m);
  // A box of the given length (along its yaw) and width centred at center. Throws WorldError on a non-positive size.
  static Shape box(const Eigen::Vector2d& center, double length_m, double width_m, double yaw_rad);
  // A convex polygon (either winding; stored counter-clockwise). Throws WorldError unless it has at least 3 points,
  // positive area and is convex.
  static Shape polygon(std::vector<Eigen::Vector2d> points);

  // A box-shaped ramp (non-solid: the robot drives up it) of the given length along yaw and width, rising from
  // base_height_m at its low edge (-length/2 along yaw) to top_height_m at its high edge. Throws WorldError on a
  // non-positive size.
  static Shape ramp(const Eigen::Vector2d& center, double length_m, double width_m, double yaw_rad);
  // The shape's outline where its material holds height_m (a ramp's part whose surface is at or above it), nullopt
  // when nothing; the shape itself when it is not a ramp.
  [[nodiscard]] std::optional<Shape> slice_at(double height_m) const;

  // The same shape shifted by offset.
  [[nodiscard]] Shape translated(const Eigen::Vector2d& offset) const;
  // True when the closed height interval [base, top] holds height_m.
  [[nodiscard]] bool spans_height(double height_m) const {
    return base_height_m <= height_m && height_m <= top_height_m;
  }
  // True when the open height intervals (base, top) and (lo, hi) share a point.
  [[nodiscard]] bool overlaps_heights(double lo_m, double hi_m) const {
    return base_height_m < hi_m && lo_m < top_height_m;
  }
};

// An obstacle whose centre moves along waypoints at constant speed, starting at the first waypoint at t = 0. One-shot
// obstacles stop at the last waypoint; looping ones continue from the last back to the first and round again.
struct MovingObstacle {
  Shape shape;  // relative to the obstacle's centre
  std::vector<Eigen::Vector2d> waypoints;
  double speed_mps = 0.0;
  bool loop = false;
  double start_s = 0.0;  // sim time it sets off from its first waypoint; it stands there until then

  // Where the centre is at sim time time_s (times before 0 give the first waypoint).
  [[nodiscard]] Eigen::Vector2d center_at(double time_s) const;
  // The shape in the world frame at sim time time_s.
  [[nodiscard]] Shape shape_at(double time_s) const { return shape.translated(center_at(time_s)); }
};

// Exact distance along the unit vector direction_W from p_W to where the ray enters the shape's interior (0 when p_W
// is inside), or nullopt when it never does (a tangent ray, or one running along an edge, passes). Ignores heights.
std::optional<double> ray_distance(const Shape& shape, const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W);

// The same entry as ray_distance, with the surface normal there (RayHit::pixels stays empty): a circle's is radial, a
// polygon's is the outward normal of the edge the ray entered through. Through a polygon vertex it is the normal of the
// adjoining edge the ray meets more head-on; from a start inside the shape, where no surface was crossed, it is
// -direction_W.
std::optional<RayHit> ray_hit(const Shape& shape, const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W);

// Where a 3-D ray from p_W along direction_W (world frame, need not be unit length; z up, the ground at z = 0) first
// enters the shape's prism (its outline extruded from base_height_m to top_height_m), as the ray parameter t >= 0 of
// the point p_W + t direction_W (0 when p_W is inside), or nullopt when it never does. Grazing a face is no entry.
std::optional<double> ray_entry_3d(const Shape& shape, const Eigen::Vector3d& p_W, const Eigen::Vector3d& direction_W);

// True when the box footprint at base_link pose X_WB and the shape overlap with positive area (ignoring heights).
bool footprint_overlaps(const Shape& shape, const geometry::BoxFootprint& footprint, const geometry::Pose2& X_WB);

// A world of analytic shapes, static and moving, with heights: the laser sees only shapes that span its scan plane,
// the robot's body collides with every shape its height range overlaps.
class ShapeWorld final : public SimWorld {
 public:
  ShapeWorld(std::vector<Shape> shapes, std::vector<MovingObstacle> moving,
             std::optional<std::pair<Eigen::Vector2d, Eigen::Vector2d>> bounds = std::nullopt)
      : shapes_(std::move(shapes)), moving_(std::move(moving)), bounds_(std::move(bounds)) {}

  // Parses a shape world YAML document (see clients/sim/README.md); source names it in messages. Throws WorldError
  // naming the source and the key at fault, including unknown keys.
  static ShapeWorld parse(const std::string& yaml_text, const std::string& source);
  // Reads and parses a shape world file; throws WorldError naming the file.
  static ShapeWorld load(const std::filesystem::path& yaml_path);

  [[nodiscard]] const std::vector<Shape>& shapes() const { return shapes_; }
  [[nodiscard]] const std::vector<MovingObstacle>& moving() const { return moving_; }
  // Optional [min corner, max corner] of the world, metres; informational only.
  [[nodiscard]] const std::optional<std::pair<Eigen::Vector2d, Eigen::Vector2d>>& bounds() const { return bounds_; }

  [[nodiscard]] std::optional<RayHit> cast(const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W,
                                           double max_range_m, double time_s, double height_m) const override;
  [[nodiscard]] std::optional<std::string> find_collision(const geometry::BoxFootprint& footprint,
                                                          const geometry::Pose2& X_WB, double time_s) const override;
  // The distance along the unit 3-D vector direction_W from p_W to the first shape the ray enters at sim time time_s,
  // or nullopt when none is closer than max_range_m. Every shape is seen, non-solid ones too (a depth sensor sees a
  // ramp's surface); the ground is not a shape (see cast_depth_ray).
  [[nodiscard]] std::optional<double> cast_3d(const Eigen::Vector3d& p_W, const Eigen::Vector3d& direction_W,
                                              double max_range_m, double time_s) const;
  [[nodiscard]] bool has_moving_obstacles() const override { return !moving_.empty(); }

 private:
  std::vector<Shape> shapes_;
  std::vector<MovingObstacle> moving_;
  std::optional<std::pair<Eigen::Vector2d, Eigen::Vector2d>> bounds_;
};

}  // namespace occgeo::sim
