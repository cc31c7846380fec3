// Raycast, occupancy and swept-motion queries: each request carries a list of entries (rays, points, motions) and
// is answered by one reply with one result per entry; one entry is the single form.
#include <boost/asio/post.hpp>
#include <cmath>
#include <string>
#include <vector>

#include "handlers.h"
#include "queries_common.h"
#include "query_kernels.h"

namespace occgeo::service {

void handle_raycast_query(const SessionPtr& session, std::uint64_t request_id, const v1::RaycastQuery& query) {
  auto world = resolve_world(session, "raycast", request_id, query.world());
  if (!world) return;
  if (!check_count(session, static_cast<std::size_t>(query.rays_size()),
                   session->core().config().limits.max_batch_queries, "raycast.rays", request_id)) {
    return;
  }
  std::vector<geometry::Pose2> rays;
  rays.reserve(static_cast<std::size_t>(query.rays_size()));
  for (int i = 0; i < query.rays_size(); ++i) {
    const auto ray = resolve_pose(session, query.rays(i), "raycast.rays[" + std::to_string(i) + "]", request_id);
    if (!ray) return;
    rays.push_back(*ray);
  }
  const double max_range = query.max_range_m();
  const double limit = session->core().config().limits.max_query_distance_m;
  if (!std::isfinite(max_range) || max_range <= 0.0 || max_range > limit) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "raycast.max_range_m",
                        "must be > 0 and at most " + std::to_string(limit) + " m", request_id);
    return;
  }
  const double height = query.height_m() == 0.0 ? kDefaultRayHeight_m : query.height_m();
  if (!std::isfinite(height) || std::abs(height) > session->core().config().limits.max_abs_coordinate_m) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "raycast.height_m",
                        "must be finite and within the coordinate limit", request_id);
    return;
  }
  auto models = resolve_models(session, "raycast", request_id, query.models());
  if (!models) return;
  const bool answer_inline = rays.size() <= kMaxInlineEntries;
  run_query(session, "raycast", request_id, answer_inline,
            [session, world, models = *models, request_id, rays = std::move(rays), max_range, height, answer_inline] {
              // Inline answers use the network thread's cached snapshot (no lock, no shared reference count); the
              // query pool's threads take their own copy.
              WorldSnapshot own;
              const WorldSnapshot& snapshot =
                  answer_inline ? world->snapshots_for_this_thread() : (own = world->snapshots());
              v1::ServerMessage reply;
              auto* out = reply.mutable_raycast();
              reply.set_request_id(request_id);
              out->set_version(snapshot.grid->version());
              out->mutable_results()->Reserve(static_cast<int>(rays.size()));
              for (const geometry::Pose2& ray : rays) {
                answer_raycast(snapshot, ray, max_range, height, models, *out->add_results());
              }
              session->send(reply);
            });
}

void handle_occupancy_query(const SessionPtr& session, std::uint64_t request_id, const v1::OccupancyQuery& query) {
  auto world = resolve_world(session, "occupancy", request_id, query.world());
  if (!world) return;
  if (!check_count(session, static_cast<std::size_t>(query.points_size()),
                   session->core().config().limits.max_batch_queries, "occupancy.points", request_id)) {
    return;
  }
  const double limit = session->core().config().limits.max_abs_coordinate_m;
  std::vector<Eigen::Vector3d> points;
  points.reserve(static_cast<std::size_t>(query.points_size()));
  for (int i = 0; i < query.points_size(); ++i) {
    const v1::Vector3& p = query.points(i);
    const Eigen::Vector3d p_W(p.x(), p.y(), p.z());
    if (!p_W.allFinite() || p_W.cwiseAbs().maxCoeff() > limit) {
      session->send_error(v1::ERROR_INVALID_ARGUMENT, "occupancy.points[" + std::to_string(i) + "]",
                          "must be finite and within " + std::to_string(limit) + " m of the origin", request_id);
      return;
    }
    points.push_back(p_W);
  }
  auto models = resolve_models(session, "occupancy", request_id, query.models());
  if (!models) return;
  const bool answer_inline = points.size() <= kMaxInlineEntries;
  run_query(session, "occupancy", request_id, answer_inline,
            [session, world, models = *models, request_id, points = std::move(points), answer_inline] {
              WorldSnapshot own;
              const WorldSnapshot& snapshot =
                  answer_inline ? world->snapshots_for_this_thread() : (own = world->snapshots());
              v1::ServerMessage reply;
              auto* out = reply.mutable_occupancy();
              reply.set_request_id(request_id);
              out->set_world(world->name());
              out->set_version(snapshot.grid->version());
              out->set_occupied_threshold(static_cast<std::uint32_t>(snapshot.grid->occupied_threshold()));
              out->mutable_samples()->Reserve(static_cast<int>(points.size()));
              for (const Eigen::Vector3d& p_W : points) {
                answer_occupancy(snapshot, p_W, models, *out->add_samples());
              }
              session->send(reply);
            });
}

void handle_swept_query(const SessionPtr& session, std::uint64_t request_id, const v1::SweptQuery& query) {
  auto target = resolve_robot_footprint(session, "swept", request_id, query.robot_id(), query.has_footprint(),
                                        query.footprint(), /*leaves_thread=*/true);
  if (!target) return;
  if (!check_count(session, static_cast<std::size_t>(query.motions_size()), kMaxSweptMotions, "swept.motions",
                   request_id)) {
    return;
  }
  const LimitsConfig& limits = session->core().config().limits;
  for (int i = 0; i < query.motions_size(); ++i) {
    const v1::SweptMotion& motion = query.motions(i);
    const std::string field = "swept.motions[" + std::to_string(i) + "]";
    const auto refuse = [&](const std::string& name, const std::string& message) {
      session->send_error(v1::ERROR_INVALID_ARGUMENT, field + "." + name, message, request_id);
    };
    if (motion.path_size() > 0) {
      if (static_cast<std::size_t>(motion.path_size()) > kMaxSweptPathPoses) {
        refuse("path", "holds more than " + std::to_string(kMaxSweptPathPoses) + " poses");
        return;
      }
      for (int k = 0; k < motion.path_size(); ++k) {
        if (!resolve_pose(session, motion.path(k), field + ".path[" + std::to_string(k) + "]", request_id)) return;
      }
      if (!std::isfinite(motion.path_dt_s()) || motion.path_dt_s() < 0.0) {
        refuse("path_dt_s", "must be finite and >= 0");
        return;
      }
      continue;
    }
    if (!resolve_pose(session, motion.start(), field + ".start", request_id)) return;
    if (!std::isfinite(motion.duration_s()) || motion.duration_s() < 0.0 || motion.duration_s() > kMaxSweptDuration_s) {
      refuse("duration_s", "must be between 0 and " + std::to_string(kMaxSweptDuration_s) + " s");
      return;
    }
    const double v = motion.linear_mps();
    const double w = motion.angular_radps();
    if (!std::isfinite(v) || !std::isfinite(w)) {
      refuse(std::isfinite(v) ? "angular_radps" : "linear_mps", "must be finite");
      return;
    }
    // The whole motion stays within the coordinate limit (it never leaves a disc of radius |v| T about the start).
    if (std::abs(v) * motion.duration_s() > limits.max_query_distance_m) {
      refuse("linear_mps", "the motion is longer than limits.max_query_distance_m (" +
                               std::to_string(limits.max_query_distance_m) + " m)");
      return;
    }
  }
  auto models = resolve_models(session, "swept", request_id, query.models());
  if (!models) return;
  // Conservative advancement may take many steps: always on the query pool.
  run_query(session, "swept", request_id, false,
            [session, target = std::move(*target), models = *models, request_id, query] {
              const WorldSnapshot snapshot = target.world->snapshots();
              v1::ServerMessage reply;
              auto* out = reply.mutable_swept();
              reply.set_request_id(request_id);
              for (const v1::SweptMotion& motion : query.motions()) {
                answer_swept(snapshot, target.footprint(), models, motion, *out->add_results());
              }
              session->send(reply);
            });
}

}  // namespace occgeo::service
