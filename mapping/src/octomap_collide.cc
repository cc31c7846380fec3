// FCL lives here only: the octree view of a snapshot and footprint collision against it.

#include <fcl/fcl.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <variant>

#include "octomap_internal.h"

namespace occgeo::mapping {

struct FclOctreeView {
  // Shares the snapshot's tree; FCL only reads it, so concurrent queries on one view are safe (each collide call
  // builds its own traversal state).
  fcl::CollisionObjectd object;
};

std::shared_ptr<const FclOctreeView> make_fcl_view(const std::shared_ptr<const octomap::OcTree>& tree) {
  auto geometry = std::make_shared<fcl::OcTreed>(tree);
  return std::make_shared<const FclOctreeView>(FclOctreeView{fcl::CollisionObjectd(geometry)});
}

namespace {

void require_dimension(double value, const char* field) {
  if (!std::isfinite(value) || value <= 0.0) {
    throw std::invalid_argument(std::string("collide: footprint ") + field + " must be finite and > 0");
  }
}

}  // namespace

OctoCollision collide_footprint(const FclOctreeView& view, const geometry::Footprint& footprint,
                                const geometry::Pose3& X_WB) {
  if (!X_WB.transform.matrix().allFinite()) throw std::invalid_argument("collide: X_WB must be finite");
  // Footprints stand on base_link's z = 0; FCL's shapes are centred on their frame, hence the shift by half a height.
  std::shared_ptr<fcl::CollisionGeometryd> shape;
  Eigen::Isometry3d X_BF = Eigen::Isometry3d::Identity();
  std::visit(
      [&](const auto& f) {
        using T = std::decay_t<decltype(f)>;
        if constexpr (std::is_same_v<T, geometry::BoxFootprint>) {
          require_dimension(f.length, "length");
          require_dimension(f.width, "width");
          require_dimension(f.height, "height");
          if (!std::isfinite(f.center_x)) throw std::invalid_argument("collide: footprint center_x must be finite");
          shape = std::make_shared<fcl::Boxd>(f.length, f.width, f.height);
          X_BF.translation() = Eigen::Vector3d{f.center_x, 0.0, f.height / 2};
        } else if constexpr (std::is_same_v<T, geometry::ConvexPolygonFootprint>) {
          require_dimension(f.height, "height");
          if (f.vertices_B.size() < 3) throw std::invalid_argument("collide: footprint polygon needs >= 3 vertices");
          geometry::PrismMesh mesh = geometry::prism_mesh(f);
          // The mesh stands on base_link's z = 0 already: X_BF stays identity.
          shape = std::make_shared<fcl::Convexd>(
              std::make_shared<const std::vector<Eigen::Vector3d>>(std::move(mesh.vertices_B)), mesh.face_count,
              std::make_shared<const std::vector<int>>(std::move(mesh.faces)));
        } else {
          require_dimension(f.radius, "radius");
          require_dimension(f.height, "height");
          shape = std::make_shared<fcl::Cylinderd>(f.radius, f.height);
          X_BF.translation() = Eigen::Vector3d{0.0, 0.0, f.height / 2};
        }
      },
      footprint);
  const fcl::CollisionObjectd body(shape, X_WB.transform * X_BF);

  fcl::CollisionRequestd request;
  request.num_max_contacts = 1;
  request.enable_contact = true;
  fcl::CollisionResultd result;
  fcl::collide(&body, &view.object, request, result);
  OctoCollision collision;
  if (result.isCollision()) {
    collision.hit = true;
    if (result.numContacts() > 0) collision.contact_W = result.getContact(0).pos;
  }
  return collision;
}

}  // namespace occgeo::mapping
