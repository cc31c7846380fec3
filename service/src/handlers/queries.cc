#include <algorithm>
#include <boost/asio/post.hpp>
#include <variant>
#include <vector>

#include "../validation.h"
#include "handlers.h"
#include "model_geometry.h"
#include "occgeo/geometry/collision.h"

namespace occgeo::service {

namespace {

// The robot a query names and the footprint to check: the query's override or the robot's own.
struct QueryTarget {
  std::shared_ptr<Robot> robot;
  geometry::Footprint footprint;
  geometry::Pose2 pose;
};

std::optional<QueryTarget> resolve_target(const SessionPtr& session, const char* kind, std::uint64_t request_id,
                                          const std::string& robot_id, const v1::Pose2D& pose, bool has_footprint,
                                          const v1::Footprint& footprint) {
  const std::string prefix = kind;
  auto robot = session->core().find_robot(robot_id);
  if (!robot) {
    session->send_error(v1::ERROR_UNKNOWN_ROBOT, prefix + ".robot_id", "no robot '" + robot_id + "' is registered",
                        request_id);
    return std::nullopt;
  }
  if (auto error = check_pose(pose, prefix + ".pose", session->core().config().limits)) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, error->field, error->message, request_id);
    return std::nullopt;
  }
  QueryTarget target{robot, robot->model().footprint, {pose.x(), pose.y(), pose.theta()}};
  if (has_footprint) {
    FieldError error;
    auto override_footprint = footprint_from_proto(footprint, prefix + ".footprint", error);
    if (!override_footprint) {
      session->send_error(v1::ERROR_INVALID_ARGUMENT, error.field, error.message, request_id);
      return std::nullopt;
    }
    target.footprint = *override_footprint;
  }
  return target;
}

void set_cell(const geometry::CellIndex& cell, v1::CellIndex& out) {
  out.set_ix(cell.ix);
  out.set_iy(cell.iy);
}

void set_vector(const Eigen::Vector3d& v, v1::Vector3& out) {
  out.set_x(v.x());
  out.set_y(v.y());
  out.set_z(v.z());
}

double footprint_height(const geometry::Footprint& footprint) {
  return std::visit([](const auto& shape) { return shape.height; }, footprint);
}

// The models a query asks about, in its order without repeats; all three (GRID, OCTOMAP, PTEM)
// when it names none. An unknown value is answered with ERROR_INVALID_ARGUMENT naming
// `<kind>.models[i]`, and nullopt is returned.
std::optional<std::vector<v1::Model>> resolve_models(const SessionPtr& session, const char* kind,
                                                     std::uint64_t request_id,
                                                     const google::protobuf::RepeatedField<int>& asked) {
  if (asked.empty()) return std::vector<v1::Model>{v1::MODEL_GRID, v1::MODEL_OCTOMAP, v1::MODEL_PTEM};
  std::vector<v1::Model> models;
  for (int i = 0; i < asked.size(); ++i) {
    const int value = asked.Get(i);
    if (value != v1::MODEL_GRID && value != v1::MODEL_OCTOMAP && value != v1::MODEL_PTEM) {
      session->send_error(v1::ERROR_INVALID_ARGUMENT, std::string(kind) + ".models[" + std::to_string(i) + "]",
                          "must be MODEL_GRID, MODEL_OCTOMAP or MODEL_PTEM, got " + std::to_string(value), request_id);
      return std::nullopt;
    }
    const auto model = static_cast<v1::Model>(value);
    if (std::find(models.begin(), models.end(), model) == models.end()) models.push_back(model);
  }
  return models;
}

}  // namespace

void handle_collision_query(const SessionPtr& session, const v1::CollisionQuery& query) {
  auto target = resolve_target(session, "collision", query.request_id(), query.robot_id(), query.pose(),
                               query.has_footprint(), query.footprint());
  if (!target) return;
  auto models = resolve_models(session, "collision", query.request_id(), query.models());
  if (!models) return;
  asio::post(session->core().query_pool(), [session, target = std::move(*target), models = std::move(*models),
                                            request_id = query.request_id()] {
    run_guarded(session, "collision", request_id, [&] {
      const WorldSnapshot snapshot = target.robot->world().snapshots();
      v1::ServerMessage reply;
      auto* out = reply.mutable_collision();
      out->set_request_id(request_id);
      for (const v1::Model model : models) {
        if (model == v1::MODEL_GRID) {
          const geometry::CollisionResult result =
              geometry::check_collision({target.footprint, target.pose}, *snapshot.grid);
          out->set_cells_tested(static_cast<std::uint32_t>(result.cells_tested));
          if (!result.hit) continue;
          out->set_hit(true);
          if (result.cell) {
            set_cell(*result.cell, *out->mutable_cell());
            const Eigen::Vector2d center = geometry::GridGeometry(snapshot.grid->cell_size()).center_of(*result.cell);
            out->mutable_cell_center()->set_x(center.x());
            out->mutable_cell_center()->set_y(center.y());
            set_vector(Eigen::Vector3d(center.x(), center.y(), 0.0), *out->mutable_contact());
          }
        } else if (model == v1::MODEL_OCTOMAP) {
          const mapping::OctoCollision result = collide_octomap(*snapshot.octomap, target.footprint, target.pose);
          if (!result.hit) continue;
          out->set_hit(true);
          set_vector(result.contact_W, *out->mutable_contact());
        } else {
          const PtemContact result = collide_ptem(*snapshot.ptem, target.footprint, target.pose);
          if (!result.hit) continue;
          out->set_hit(true);
          set_vector(Eigen::Vector3d(result.point_W.x(), result.point_W.y(), 0.0), *out->mutable_contact());
        }
        out->set_model(model);
        break;
      }
      session->send(std::move(reply));
    });
  });
}

void handle_clearance_query(const SessionPtr& session, const v1::ClearanceQuery& query) {
  auto target = resolve_target(session, "clearance", query.request_id(), query.robot_id(), query.pose(),
                               query.has_footprint(), query.footprint());
  if (!target) return;
  const LimitsConfig& limits = session->core().config().limits;
  double max_distance = query.max_distance_m();
  if (!std::isfinite(max_distance) || max_distance < 0.0 || max_distance > limits.max_query_distance_m) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "clearance.max_distance_m",
                        "must be between 0 and " + std::to_string(limits.max_query_distance_m) + " m",
                        query.request_id());
    return;
  }
  auto models = resolve_models(session, "clearance", query.request_id(), query.models());
  if (!models) return;
  if (max_distance == 0.0) max_distance = session->core().config().queries.clearance_max_distance_m;
  asio::post(session->core().query_pool(), [session, target = std::move(*target), models = std::move(*models),
                                            request_id = query.request_id(), max_distance] {
    run_guarded(session, "clearance", request_id, [&] {
      const WorldSnapshot snapshot = target.robot->world().snapshots();
      const geometry::ClearanceRequest request{target.footprint, target.pose, max_distance};
      v1::ServerMessage reply;
      auto* out = reply.mutable_clearance();
      out->set_request_id(request_id);
      out->set_clearance_m(max_distance);
      // Keeps the nearest answer over the models; ties go to the model asked first.
      const auto offer = [&](v1::Model model, bool found, double clearance_m, const Eigen::Vector2d& point_W,
                             const std::optional<geometry::CellIndex>& cell) {
        if (!found || (out->found() && clearance_m >= out->clearance_m())) return;
        out->set_found(true);
        out->set_clearance_m(clearance_m);
        out->set_model(model);
        out->mutable_nearest_point()->set_x(point_W.x());
        out->mutable_nearest_point()->set_y(point_W.y());
        if (cell) {
          set_cell(*cell, *out->mutable_nearest_cell());
        } else {
          out->clear_nearest_cell();
        }
      };
      for (const v1::Model model : models) {
        if (model == v1::MODEL_GRID) {
          // The distance field answers (within one cell of exact, falling back to the exact search itself
          // when the query reaches beyond the field).
          const geometry::ClearanceResult result = snapshot.distance->compute_clearance(request);
          offer(model, result.found, result.clearance_m, result.nearest_point_W, result.nearest_cell);
        } else if (model == v1::MODEL_OCTOMAP) {
          const OctoMapColumns columns(*snapshot.octomap, footprint_height(target.footprint));
          const geometry::ClearanceResult result = geometry::compute_clearance(request, columns);
          offer(model, result.found, result.clearance_m, result.nearest_point_W, result.nearest_cell);
        } else {
          const PtemClearance result = ptem_clearance(*snapshot.ptem, target.footprint, target.pose, max_distance);
          offer(model, result.found, result.clearance_m, result.nearest_point_W, std::nullopt);
        }
      }
      session->send(std::move(reply));
    });
  });
}

void handle_status_request(const SessionPtr& session, const v1::StatusRequest& request) {
  ServerCore& core = session->core();
  v1::ServerMessage reply;
  auto* status = reply.mutable_status();
  status->set_request_id(request.request_id());
  status->set_server_version("occgeod 0.1.0");
  status->set_clients(core.sessions.load());
  status->set_uptime_s(core.uptime_s());
  for (const auto& robot : core.robots()) {
    const RobotState state = robot->state();
    auto* out = status->add_robots();
    out->set_id(robot->model().id);
    out->set_world(robot->world().name());
    out->set_model(robot->model().model);
    out->set_connected(state.connected);
    if (state.X_WB) {
      out->mutable_pose()->set_x(state.X_WB->x);
      out->mutable_pose()->set_y(state.X_WB->y);
      out->mutable_pose()->set_theta(state.X_WB->theta);
    }
    out->set_scans_ingested(state.scans_ingested);
    out->set_scans_rejected(state.scans_rejected);
    const ControlState control = robot->control().state();
    out->set_behaviour(control.behaviour);
    out->set_behaviour_state(state.behaviour_state);
    out->set_estop(control.estop);
    if (control.lease) {
      out->mutable_lease_holder()->set_session_id(control.lease->session_id);
      out->mutable_lease_holder()->set_client_name(control.lease->client_name);
      out->set_lease_expires_in_s(std::max(
          0.0, std::chrono::duration<double>(control.lease->expires_at - std::chrono::steady_clock::now()).count()));
    }
    out->set_sensor_stale(control.sensor_stale);
    out->set_last_linear_mps(state.last_linear_mps);
    out->set_last_angular_radps(state.last_angular_radps);
  }
  for (const auto& world : core.worlds()) {
    const WorldSnapshot snapshots = world->snapshots();
    const auto& snapshot = snapshots.grid;
    auto* out = status->add_worlds();
    out->set_name(world->name());
    out->set_cell_size_m(snapshot->cell_size());
    out->set_version(snapshot->version());
    out->set_tiles(snapshot->tile_count());
    out->set_occupied_cells(snapshot->occupied_cell_count());
    out->set_ptem_construction(ptem_construction_name(world->ptem_params().construction));
    out->set_ptem_clusters(static_cast<std::uint32_t>(snapshots.ptem->clusters().size()));
    out->set_ptem_scans(snapshots.ptem->scan_count());
    out->set_octomap_version(snapshots.octomap->version());
    out->set_octomap_nodes(snapshots.octomap->node_count());
    out->set_octomap_leaves(snapshots.octomap->leaf_count());
    out->set_octomap_resolution_m(snapshots.octomap->resolution());
  }
  session->send(std::move(reply));
}

void handle_grid_request(const SessionPtr& session, const v1::GridRequest& request) {
  const std::string name = request.world().empty() ? session->core().config().default_world : request.world();
  auto world = session->core().find_world(name);
  if (!world) {
    session->send_error(v1::ERROR_UNKNOWN_WORLD, "grid.world", "no world '" + name + "' exists", request.request_id());
    return;
  }
  const std::size_t max_cells = session->core().config().limits.max_grid_reply_cells;
  asio::post(session->core().query_pool(), [session, world, request_id = request.request_id(), max_cells] {
    run_guarded(session, "grid", request_id, [&] {
      const auto snapshot = world->snapshot();
      v1::ServerMessage reply;
      auto* out = reply.mutable_grid();
      out->set_request_id(request_id);
      out->set_world(world->name());
      out->set_cell_size_m(snapshot->cell_size());
      out->set_occupied_threshold(static_cast<std::uint32_t>(snapshot->occupied_threshold()));
      out->set_max_certainty(static_cast<std::uint32_t>(snapshot->max_certainty()));
      out->set_version(snapshot->version());
      if (const auto box = snapshot->tile_bounds()) {
        const std::int64_t width = std::int64_t{box->max.ix} - box->min.ix + 1;
        const std::int64_t height = std::int64_t{box->max.iy} - box->min.iy + 1;
        if (static_cast<std::uint64_t>(width * height) > max_cells) {
          session->send_error(v1::ERROR_INVALID_ARGUMENT, "grid.world",
                              "world '" + world->name() + "' spans " + std::to_string(width) + " x " +
                                  std::to_string(height) + " cells, over the reply limit of " +
                                  std::to_string(max_cells),
                              request_id);
          return;
        }
        set_cell(box->min, *out->mutable_min_cell());
        out->set_width(static_cast<std::uint32_t>(width));
        out->set_height(static_cast<std::uint32_t>(height));
        const std::vector<std::uint8_t> cells =
            snapshot->window(box->min, static_cast<int>(width), static_cast<int>(height));
        out->set_cells(cells.data(), cells.size());
      }
      session->send(std::move(reply));
    });
  });
}

}  // namespace occgeo::service
