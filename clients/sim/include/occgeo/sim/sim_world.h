#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/pose.h"
#include "occgeo/sim/raycast.h"
#include "occgeo/sim/world.h"

namespace occgeo::sim {

// The ground truth the simulation runs against, whichever file format it came from: what a laser beam hits and
// whether the robot's body overlaps an obstacle, both at a sim time (worlds with moving obstacles change over time).
class SimWorld {
 public:
  virtual ~SimWorld() = default;

  // Casts a level ray at height_m above the ground from p_W along the unit vector direction_W at sim time time_s and
  // returns where it first enters an obstacle, or nullopt when that is not closer than max_range_m. Only obstacles
  // whose vertical extent holds height_m are seen. RayHit::pixels is filled only by pixel worlds.
  [[nodiscard]] virtual std::optional<RayHit> cast(const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W,
                                                   double max_range_m, double time_s, double height_m) const = 0;

  // A description of the first obstacle the box footprint (from z = 0 up to footprint.height) placed at base_link pose
  // X_WB overlaps with positive area at sim time time_s, or nullopt when it is clear. Touching is not a collision.
  [[nodiscard]] virtual std::optional<std::string> find_collision(const geometry::BoxFootprint& footprint,
                                                                  const geometry::Pose2& X_WB, double time_s) const = 0;

  // True when obstacles move, so a standing robot can still be run into.
  [[nodiscard]] virtual bool has_moving_obstacles() const { return false; }

 protected:
  SimWorld() = default;
  SimWorld(const SimWorld&) = default;
  SimWorld(SimWorld&&) = default;
  SimWorld& operator=(const SimWorld&) = default;
  SimWorld& operator=(SimWorld&&) = default;
};

// A map_server pixel world (World) behind the SimWorld interface. Obstacle pixels are infinitely tall: every height
// sees them.
class PixelWorld final : public SimWorld {
 public:
  explicit PixelWorld(World world) : world_(std::move(world)) {}

  [[nodiscard]] const World& grid() const { return world_; }

  [[nodiscard]] std::optional<RayHit> cast(const Eigen::Vector2d& p_W, const Eigen::Vector2d& direction_W,
                                           double max_range_m, double time_s, double height_m) const override;
  [[nodiscard]] std::optional<std::string> find_collision(const geometry::BoxFootprint& footprint,
                                                          const geometry::Pose2& X_WB, double time_s) const override;

 private:
  World world_;
};

// Loads either world format: a ROS map_server YAML (has `image:`) as a PixelWorld, or a shape world YAML (has
// `shapes:` or `occgeo_world: 1`, see shape_world.h) as a ShapeWorld. Throws WorldError naming the file and the
// problem.
std::unique_ptr<SimWorld> load_sim_world(const std::filesystem::path& yaml_path);

}  // namespace occgeo::sim
