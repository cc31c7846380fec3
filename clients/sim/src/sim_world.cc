#include "occgeo/sim/sim_world.h"

#include <yaml-cpp/yaml.h>

#include <sstream>

#include "occgeo/sim/footprint_collision.h"
#include "occgeo/sim/shape_world.h"

namespace occgeo::sim {

namespace {

// The outward normal of the surface a pixel image draws, at obstacle pixel `hit`: the sum of the directions to the
// free pixels within two pixels, each weighted by 1 / distance (pixels beyond the image count as free). A specular
// sonar needs the drawn surface's normal, not the pixel face's: a disc drawn in pixels is a staircase of axis-aligned
// faces, which it would hear only from the four axis directions (and a pillar met diagonally not at all), where a
// round pillar echoes towards whichever transducer faces it. Where the sum cancels (a wall one pixel thin, with free
// space on both sides) or leans away from the face the ray entered, the face's normal stands.
Eigen::Vector2d drawn_surface_normal(const World& world, const Pixel& hit, const Eigen::Vector2d& face_normal_W) {
  constexpr int kRadius = 2;
  constexpr double kSmallestSum = 0.5;  // a straight face's sum is 4.2
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (int d_row = -kRadius; d_row <= kRadius; ++d_row) {
    for (int d_col = -kRadius; d_col <= kRadius; ++d_col) {
      if ((d_row == 0 && d_col == 0) || world.is_obstacle({hit.col + d_col, hit.row + d_row})) continue;
      const Eigen::Vector2d offset_W(d_col, -d_row);  // rows count downwards
      sum += offset_W / offset_W.squaredNorm();
    }
  }
  if (sum.norm() < kSmallestSum || sum.dot(face_normal_W) <= 0.0) return face_normal_W;
  return sum.normalized();
}

}  // namespace

std::optional<RayHit> PixelWorld::cast(const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W,
                                       double max_range_m, double /*time_s*/, double /*height_m*/) const {
  std::optional<RayHit> hit = cast_ray(world_, p_W, direction_W, max_range_m);
  if (hit && hit->pixels.size() == 1) hit->normal_W = drawn_surface_normal(world_, hit->pixels.front(), hit->normal_W);
  return hit;
}

std::optional<std::string> PixelWorld::find_collision(const geometry::BoxFootprint& footprint,
                                                      const geometry::Pose2& X_WB, double /*time_s*/) const {
  const auto pixel = sim::find_collision(world_, footprint, X_WB);
  if (!pixel) return std::nullopt;
  const Eigen::Vector2d center = world_.center_of(*pixel);
  std::ostringstream message;
  message << "the obstacle pixel (col " << pixel->col << ", row " << pixel->row << ") centred at (" << center.x()
          << ", " << center.y() << ")";
  return message.str();
}

std::unique_ptr<SimWorld> load_sim_world(const std::filesystem::path& yaml_path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(yaml_path.string());
  } catch (const YAML::BadFile&) {
    throw WorldError(yaml_path.string() + ": cannot open the file");
  } catch (const YAML::Exception& error) {
    throw WorldError(yaml_path.string() + ": not valid YAML: " + error.what());
  }
  if (root.IsMap() && root["image"]) return std::make_unique<PixelWorld>(load_world(yaml_path));
  if (root.IsMap() && (root["shapes"] || root["occgeo_world"])) {
    return std::make_unique<ShapeWorld>(ShapeWorld::load(yaml_path));
  }
  throw WorldError(yaml_path.string() +
                   ": neither a map_server world (no 'image:') nor a shape world (no 'shapes:' or 'occgeo_world:')");
}

}  // namespace occgeo::sim
