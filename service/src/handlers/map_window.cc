// Map windows: a box of the HIMM grid as certainty values (whole, or only what changed since a version, for clients
// that follow the map), and the occupied octree voxels in a box.
#include <boost/asio/post.hpp>
#include <cmath>
#include <string>

#include "handlers.h"
#include "queries_common.h"
#include "query_kernels.h"

namespace occgeo::service {

namespace {

void set_cell(const geometry::CellIndex& cell, v1::CellIndex& out) {
  out.set_ix(cell.ix);
  out.set_iy(cell.iy);
}

bool finite_within(double value, double limit) { return std::isfinite(value) && std::abs(value) <= limit; }

}  // namespace

void handle_grid_window(const SessionPtr& session, std::uint64_t request_id, const v1::GridWindowRequest& request) {
  auto world = resolve_world(session, "grid_window", request_id, request.world());
  if (!world) return;
  const LimitsConfig& limits = session->core().config().limits;
  const auto check_corner = [&](const v1::Point2D& p, const char* name) {
    if (finite_within(p.x(), limits.max_abs_coordinate_m) && finite_within(p.y(), limits.max_abs_coordinate_m)) {
      return true;
    }
    session->send_error(v1::ERROR_INVALID_ARGUMENT, std::string("grid_window.") + name,
                        "must be finite and within " + std::to_string(limits.max_abs_coordinate_m) + " m of the origin",
                        request_id);
    return false;
  };
  if (!check_corner(request.min_corner(), "min_corner") || !check_corner(request.max_corner(), "max_corner")) return;
  if (request.max_corner().x() < request.min_corner().x() || request.max_corner().y() < request.min_corner().y()) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "grid_window.max_corner", "must not be below min_corner on x or y",
                        request_id);
    return;
  }
  const std::size_t max_cells = limits.max_grid_reply_cells;
  asio::post(session->core().query_pool(), [session, world, request, request_id, max_cells] {
    run_guarded(session, "grid_window", request_id, [&] {
      const auto snapshot = world->snapshot();
      const geometry::GridGeometry geometry(snapshot->cell_size());
      const geometry::CellIndex min = geometry.cell_of({request.min_corner().x(), request.min_corner().y()});
      const geometry::CellIndex max = geometry.cell_of({request.max_corner().x(), request.max_corner().y()});
      const std::int64_t width = std::int64_t{max.ix} - min.ix + 1;
      const std::int64_t height = std::int64_t{max.iy} - min.iy + 1;
      if (static_cast<std::uint64_t>(width * height) > max_cells) {
        session->send_error(v1::ERROR_INVALID_ARGUMENT, "grid_window.max_corner",
                            "the window spans " + std::to_string(width) + " x " + std::to_string(height) +
                                " cells, over limits.max_grid_reply_cells (" + std::to_string(max_cells) + ")",
                            request_id);
        return;
      }
      v1::ServerMessage reply;
      auto* out = reply.mutable_grid_window();
      reply.set_request_id(request_id);
      out->set_world(world->name());
      out->set_cell_size_m(snapshot->cell_size());
      out->set_version(snapshot->version());
      out->set_occupied_threshold(static_cast<std::uint32_t>(snapshot->occupied_threshold()));
      out->set_max_certainty(static_cast<std::uint32_t>(snapshot->max_certainty()));
      set_cell(min, *out->mutable_min_cell());
      out->set_width(static_cast<std::uint32_t>(width));
      out->set_height(static_cast<std::uint32_t>(height));
      // A version from the future (the grid was replaced, e.g. reloaded) cannot be followed: start over.
      if (request.since_version() == 0 || request.since_version() > snapshot->version()) {
        const std::vector<std::uint8_t> cells =
            snapshot->window(min, static_cast<int>(width), static_cast<int>(height));
        out->set_cells(cells.data(), cells.size());
      } else {
        for (const mapping::CellBox& part : snapshot->changed_since(request.since_version(), {min, max})) {
          const int part_width = part.max.ix - part.min.ix + 1;
          const int part_height = part.max.iy - part.min.iy + 1;
          const std::vector<std::uint8_t> cells = snapshot->window(part.min, part_width, part_height);
          v1::GridBlock* block = out->add_changed();
          set_cell(part.min, *block->mutable_min_cell());
          block->set_width(static_cast<std::uint32_t>(part_width));
          block->set_height(static_cast<std::uint32_t>(part_height));
          block->set_cells(cells.data(), cells.size());
        }
      }
      session->send(reply);
    });
  });
}

void handle_octree_window(const SessionPtr& session, std::uint64_t request_id, const v1::OctreeWindowRequest& request) {
  auto world = resolve_world(session, "octree_window", request_id, request.world());
  if (!world) return;
  const double limit = session->core().config().limits.max_abs_coordinate_m;
  const Eigen::Vector3d min_W(request.min_corner().x(), request.min_corner().y(), request.min_corner().z());
  const Eigen::Vector3d max_W(request.max_corner().x(), request.max_corner().y(), request.max_corner().z());
  for (const auto& [corner, name] : {std::pair{min_W, "min_corner"}, std::pair{max_W, "max_corner"}}) {
    if (!corner.allFinite() || corner.cwiseAbs().maxCoeff() > limit) {
      session->send_error(v1::ERROR_INVALID_ARGUMENT, std::string("octree_window.") + name,
                          "must be finite and within " + std::to_string(limit) + " m of the origin", request_id);
      return;
    }
  }
  if ((max_W.array() < min_W.array()).any()) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "octree_window.max_corner", "must not be below min_corner",
                        request_id);
    return;
  }
  asio::post(session->core().query_pool(), [session, world, request_id, min_W, max_W] {
    run_guarded(session, "octree_window", request_id, [&] {
      const WorldSnapshot snapshot = world->snapshots();
      v1::ServerMessage reply;
      auto* out = reply.mutable_octree_window();
      reply.set_request_id(request_id);
      out->set_world(world->name());
      out->set_version(snapshot.octomap->version());
      out->set_resolution_m(snapshot.octomap->resolution());
      bool too_many = false;
      snapshot.octomap->for_each_occupied(min_W, max_W, [&](const mapping::OctoVoxel& voxel) {
        if (static_cast<std::size_t>(out->voxels_size()) >= kMaxOctreeWindowVoxels) {
          too_many = true;
          return false;
        }
        v1::OctreeVoxel* v = out->add_voxels();
        v->mutable_center()->set_x(voxel.center_W.x());
        v->mutable_center()->set_y(voxel.center_W.y());
        v->mutable_center()->set_z(voxel.center_W.z());
        v->set_size_m(voxel.size_m);
        v->set_probability(voxel.probability);
        return true;
      });
      if (too_many) {
        session->send_error(v1::ERROR_INVALID_ARGUMENT, "octree_window.max_corner",
                            "the box holds more than " + std::to_string(kMaxOctreeWindowVoxels) +
                                " occupied voxels; ask for a smaller one",
                            request_id);
        return;
      }
      session->send(reply);
    });
  });
}

}  // namespace occgeo::service
