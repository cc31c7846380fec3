#include <algorithm>
#include <boost/asio/post.hpp>
#include <variant>
#include <vector>

#include "../validation.h"
#include "handlers.h"
#include "model_geometry.h"
#include "occgeo/geometry/collision.h"
#include "queries_common.h"
#include "query_kernels.h"

namespace occgeo::service {

std::optional<QueryTarget> resolve_robot_footprint(const SessionPtr& session, const std::string& kind,
                                                   std::uint64_t request_id, const std::string& robot_id,
                                                   bool has_footprint, const v1::Footprint& footprint,
                                                   bool leaves_thread) {
  const RobotQueryView& robot = session->core().robot_for_this_thread(robot_id);
  if (!robot.model) {
    session->send_error(v1::ERROR_UNKNOWN_ROBOT, kind + ".robot_id", "no robot '" + robot_id + "' is registered",
                        request_id);
    return std::nullopt;
  }
  QueryTarget target;
  target.model = robot.model.get();
  target.world = robot.world;
  if (leaves_thread) target.keep_model = robot.model;
  if (has_footprint) {
    FieldError error;
    auto override_footprint = footprint_from_proto(footprint, kind + ".footprint", error);
    if (!override_footprint) {
      session->send_error(v1::ERROR_INVALID_ARGUMENT, error.field, error.message, request_id);
      return std::nullopt;
    }
    target.override_footprint = std::move(*override_footprint);
  }
  return target;
}

std::optional<geometry::Pose2> resolve_pose(const SessionPtr& session, const v1::Pose2D& pose, const std::string& field,
                                            std::uint64_t request_id) {
  if (auto error = check_pose(pose, field, session->core().config().limits)) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, error->field, error->message, request_id);
    return std::nullopt;
  }
  return geometry::Pose2{pose.x(), pose.y(), pose.theta()};
}

std::optional<ModelList> resolve_models(const SessionPtr& session, const std::string& kind, std::uint64_t request_id,
                                        const google::protobuf::RepeatedField<int>& asked) {
  if (asked.empty()) return ModelList{v1::MODEL_GRID, v1::MODEL_OCTOMAP, v1::MODEL_PTEM};
  ModelList models;
  for (int i = 0; i < asked.size(); ++i) {
    const int value = asked.Get(i);
    if (value != v1::MODEL_GRID && value != v1::MODEL_OCTOMAP && value != v1::MODEL_PTEM) {
      session->send_error(v1::ERROR_INVALID_ARGUMENT, kind + ".models[" + std::to_string(i) + "]",
                          "must be MODEL_GRID, MODEL_OCTOMAP or MODEL_PTEM, got " + std::to_string(value), request_id);
      return std::nullopt;
    }
    const auto model = static_cast<v1::Model>(value);
    if (std::find(models.begin(), models.end(), model) == models.end()) models.push_back(model);
  }
  return models;
}

std::shared_ptr<World> resolve_world(const SessionPtr& session, const std::string& kind, std::uint64_t request_id,
                                     const std::string& world) {
  const std::string name = world.empty() ? session->core().config().default_world : world;
  auto found = session->core().find_world(name);
  if (!found) {
    session->send_error(v1::ERROR_UNKNOWN_WORLD, kind + ".world", "no world '" + name + "' exists", request_id);
  }
  return found;
}

bool check_count(const SessionPtr& session, std::size_t count, std::size_t limit, const std::string& field,
                 std::uint64_t request_id) {
  if (count >= 1 && count <= limit) return true;
  session->send_error(v1::ERROR_INVALID_ARGUMENT, field,
                      "must hold 1 to " + std::to_string(limit) + " entries, got " + std::to_string(count), request_id);
  return false;
}

namespace {

// Checks a clearance search radius; 0 means the server default.
std::optional<double> resolve_max_distance(const SessionPtr& session, double max_distance, const std::string& field,
                                           std::uint64_t request_id) {
  const LimitsConfig& limits = session->core().config().limits;
  if (!std::isfinite(max_distance) || max_distance < 0.0 || max_distance > limits.max_query_distance_m) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, field,
                        "must be between 0 and " + std::to_string(limits.max_query_distance_m) + " m", request_id);
    return std::nullopt;
  }
  return max_distance == 0.0 ? session->core().config().queries.clearance_max_distance_m : max_distance;
}

}  // namespace

namespace {

// A collision or clearance request, single or batch, once validated.
struct PoseQuery {
  QueryTarget target;
  geometry::Pose2 pose;                // single forms
  std::vector<geometry::Pose2> poses;  // batch forms
  double max_distance_m = 0.0;         // clearance only
  ModelList models;
};

// Validates the fields the four pose queries share, in this order: robot and footprint, the poses (one, or a list of
// 1..limits.max_batch_queries), max_distance_m (clearance only), models. `kind` names the request in error fields.
template <typename Query>
std::optional<PoseQuery> resolve_pose_query(const SessionPtr& session, const std::string& kind,
                                            std::uint64_t request_id, const Query& query) {
  constexpr bool kBatch = requires(const Query& q) { q.poses(); };
  constexpr bool kClearance = requires(const Query& q) { q.max_distance_m(); };
  bool leaves_thread = false;
  if constexpr (kBatch) leaves_thread = static_cast<std::size_t>(query.poses_size()) > kMaxInlineEntries;
  auto target = resolve_robot_footprint(session, kind, request_id, query.robot_id(), query.has_footprint(),
                                        query.footprint(), leaves_thread);
  if (!target) return std::nullopt;
  PoseQuery out{std::move(*target), {}, {}, 0.0, {}};
  if constexpr (kBatch) {
    if (!check_count(session, static_cast<std::size_t>(query.poses_size()),
                     session->core().config().limits.max_batch_queries, kind + ".poses", request_id)) {
      return std::nullopt;
    }
    out.poses.reserve(static_cast<std::size_t>(query.poses_size()));
    for (int i = 0; i < query.poses_size(); ++i) {
      const auto pose = resolve_pose(session, query.poses(i), kind + ".poses[" + std::to_string(i) + "]", request_id);
      if (!pose) return std::nullopt;
      out.poses.push_back(*pose);
    }
  } else {
    const auto pose = resolve_pose(session, query.pose(), kind + ".pose", request_id);
    if (!pose) return std::nullopt;
    out.pose = *pose;
  }
  if constexpr (kClearance) {
    const auto max_distance =
        resolve_max_distance(session, query.max_distance_m(), kind + ".max_distance_m", request_id);
    if (!max_distance) return std::nullopt;
    out.max_distance_m = *max_distance;
  }
  auto models = resolve_models(session, kind, request_id, query.models());
  if (!models) return std::nullopt;
  out.models = *models;
  return out;
}

// Empties a reply for the next answer. The body's message stays allocated when it is one a pose query answers
// with: filling the same kind again then allocates nothing (a hit's contact point aside).
void clear_keeping_body(v1::ServerMessage& reply) {
  switch (reply.body_case()) {
    case v1::ServerMessage::kCollision:
      reply.mutable_collision()->Clear();
      return;
    case v1::ServerMessage::kClearance:
      reply.mutable_clearance()->Clear();
      return;
    case v1::ServerMessage::kCollisionBatch:
      reply.mutable_collision_batch()->Clear();
      return;
    case v1::ServerMessage::kClearanceBatch:
      reply.mutable_clearance_batch()->Clear();
      return;
    default:
      reply.Clear();
  }
}

// Answers a validated pose query on one snapshot of the robot's world: `fill(snapshot, query, reply)` builds the
// reply from the shared kernels.
template <typename Fill>
void answer_pose_query(const SessionPtr& session, const char* kind, std::uint64_t request_id, PoseQuery query,
                       Fill fill) {
  if (query.poses.size() <= kMaxInlineEntries) {
    // Answered here, on the network thread's cached snapshot: the work refers to the query and session in place, and
    // the reply is this thread's own, kept between answers (send() serialises it before returning).
    run_query(session, kind, request_id, true, [&session, &query, &fill] {
      thread_local v1::ServerMessage reply;
      clear_keeping_body(reply);
      fill(query.target.world->snapshots_for_this_thread(), query, reply);
      session->send(reply);
    });
    return;
  }
  // The query pool's threads take their own snapshot, so they keep no stale one alive between batches.
  run_query(session, kind, request_id, false, [session, query = std::move(query), fill] {
    const WorldSnapshot snapshot = query.target.world->snapshots();
    v1::ServerMessage reply;
    fill(snapshot, query, reply);
    session->send(reply);
  });
}

}  // namespace

void handle_collision_query(const SessionPtr& session, std::uint64_t request_id, const v1::CollisionQuery& query) {
  auto resolved = resolve_pose_query(session, "collision", request_id, query);
  if (!resolved) return;
  answer_pose_query(session, "collision", request_id, std::move(*resolved),
                    [request_id](const WorldSnapshot& snapshot, const PoseQuery& q, v1::ServerMessage& reply) {
                      auto* out = reply.mutable_collision();
                      reply.set_request_id(request_id);
                      answer_collision(snapshot, q.target.footprint(), geometry::bounding_radius(q.target.footprint()),
                                       q.pose, q.models, *out);
                    });
}

void handle_clearance_query(const SessionPtr& session, std::uint64_t request_id, const v1::ClearanceQuery& query) {
  auto resolved = resolve_pose_query(session, "clearance", request_id, query);
  if (!resolved) return;
  answer_pose_query(session, "clearance", request_id, std::move(*resolved),
                    [request_id](const WorldSnapshot& snapshot, const PoseQuery& q, v1::ServerMessage& reply) {
                      auto* out = reply.mutable_clearance();
                      reply.set_request_id(request_id);
                      answer_clearance(snapshot, q.target.footprint(), q.pose, q.max_distance_m, q.models, *out);
                    });
}

void handle_collision_batch(const SessionPtr& session, std::uint64_t request_id, const v1::CollisionBatchQuery& query) {
  auto resolved = resolve_pose_query(session, "collision_batch", request_id, query);
  if (!resolved) return;
  answer_pose_query(session, "collision_batch", request_id, std::move(*resolved),
                    [request_id](const WorldSnapshot& snapshot, const PoseQuery& q, v1::ServerMessage& reply) {
                      auto* out = reply.mutable_collision_batch();
                      reply.set_request_id(request_id);
                      const double radius = geometry::bounding_radius(q.target.footprint());
                      out->mutable_results()->Reserve(static_cast<int>(q.poses.size()));
                      std::uint32_t hits = 0;
                      for (const geometry::Pose2& pose : q.poses) {
                        v1::CollisionReply* result = out->add_results();
                        answer_collision(snapshot, q.target.footprint(), radius, pose, q.models, *result);
                        hits += result->hit() ? 1 : 0;
                      }
                      out->set_hits(hits);
                    });
}

void handle_clearance_batch(const SessionPtr& session, std::uint64_t request_id, const v1::ClearanceBatchQuery& query) {
  auto resolved = resolve_pose_query(session, "clearance_batch", request_id, query);
  if (!resolved) return;
  answer_pose_query(session, "clearance_batch", request_id, std::move(*resolved),
                    [request_id](const WorldSnapshot& snapshot, const PoseQuery& q, v1::ServerMessage& reply) {
                      auto* out = reply.mutable_clearance_batch();
                      reply.set_request_id(request_id);
                      out->mutable_results()->Reserve(static_cast<int>(q.poses.size()));
                      for (const geometry::Pose2& pose : q.poses) {
                        answer_clearance(snapshot, q.target.footprint(), pose, q.max_distance_m, q.models,
                                         *out->add_results());
                      }
                    });
}

namespace {
void set_cell(const geometry::CellIndex& cell, v1::CellIndex& out) {
  out.set_ix(cell.ix);
  out.set_iy(cell.iy);
}
}  // namespace

void handle_status_request(const SessionPtr& session, std::uint64_t request_id, const v1::StatusRequest& request) {
  ServerCore& core = session->core();
  v1::ServerMessage reply;
  auto* status = reply.mutable_status();
  reply.set_request_id(request_id);
  status->set_server_version("occgeod 0.1.0");
  status->set_clients(core.sessions.load());
  status->set_uptime_s(core.uptime_s());
  status->set_resident_bytes(core.recent_resident_bytes());
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
    *out->mutable_guard() = state.guard;
    out->set_last_linear_mps(state.last_linear_mps);
    out->set_last_angular_radps(state.last_angular_radps);
    if (request.detailed()) {
      for (const Eigen::Vector2d& p : state.path()) {
        auto* point = out->add_path();
        point->set_x(p.x());
        point->set_y(p.y());
      }
      if (state.scan_W) {
        out->mutable_scan()->Reserve(static_cast<int>(state.scan_W->size()));
        for (const Eigen::Vector2f& p : *state.scan_W) {
          auto* point = out->add_scan();
          point->set_x(p.x());
          point->set_y(p.y());
        }
      }
      out->set_scan_stamp_s(state.scan_stamp_s.value_or(0.0));
    }
  }
  for (const auto& world : core.worlds()) {
    const WorldSnapshot& snapshots = world->snapshots_for_this_thread();
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
    const WorldMemory memory = world->memory();
    out->set_grid_bytes(memory.grid_bytes);
    out->set_distance_field_bytes(memory.distance_field_bytes);
    out->set_octomap_bytes(memory.octomap_bytes);
    out->set_ptem_bytes(memory.ptem_bytes);
  }
  session->send(reply);
}

void handle_grid_request(const SessionPtr& session, std::uint64_t request_id, const v1::GridRequest& request) {
  const std::string name = request.world().empty() ? session->core().config().default_world : request.world();
  auto world = session->core().find_world(name);
  if (!world) {
    session->send_error(v1::ERROR_UNKNOWN_WORLD, "grid.world", "no world '" + name + "' exists", request_id);
    return;
  }
  const std::size_t max_cells = session->core().config().limits.max_grid_reply_cells;
  asio::post(session->core().query_pool(), [session, world, request_id, max_cells] {
    run_guarded(session, "grid", request_id, [&] {
      const auto snapshot = world->snapshot();
      v1::ServerMessage reply;
      auto* out = reply.mutable_grid();
      reply.set_request_id(request_id);
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
      session->send(reply);
    });
  });
}

}  // namespace occgeo::service
