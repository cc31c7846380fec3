#include "occgeo/sim/sim_world.h"

#include <yaml-cpp/yaml.h>

#include <sstream>

#include "occgeo/sim/footprint_collision.h"
#include "occgeo/sim/shape_world.h"

namespace occgeo::sim {

std::optional<RayHit> PixelWorld::cast(const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W,
                                       double max_range_m, double /*time_s*/, double /*height_m*/) const {
  return cast_ray(world_, p_W, direction_W, max_range_m);
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
