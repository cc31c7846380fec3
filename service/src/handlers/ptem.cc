#include <boost/asio/post.hpp>
#include <cmath>
#include <string>
#include <vector>

#include "handlers.h"
#include "queries_common.h"

namespace occgeo::service {

void handle_ptem_query(const SessionPtr& session, std::uint64_t request_id, const v1::PtemQuery& query) {
  const ServerConfig& config = session->core().config();
  const std::string name = query.world().empty() ? config.default_world : query.world();
  auto world = session->core().find_world(name);
  if (!world) {
    session->send_error(v1::ERROR_UNKNOWN_WORLD, "ptem.world", "no world '" + name + "' exists", request_id);
    return;
  }
  const auto count = static_cast<std::size_t>(query.points_size());
  if (count > config.limits.max_ptem_query_points) {
    session->send_error(v1::ERROR_INVALID_ARGUMENT, "ptem.points",
                        "has " + std::to_string(count) + " points, over the limit of " +
                            std::to_string(config.limits.max_ptem_query_points) + " (limits.max_ptem_query_points)",
                        request_id);
    return;
  }
  std::vector<Eigen::Vector2d> points_W;
  points_W.reserve(count);
  const double bound = config.limits.max_abs_coordinate_m;
  for (int i = 0; i < query.points_size(); ++i) {
    const v1::Point2D& point = query.points(i);
    const std::string field = "ptem.points[" + std::to_string(i) + "]";
    if (!std::isfinite(point.x()) || std::abs(point.x()) > bound) {
      session->send_error(v1::ERROR_INVALID_ARGUMENT, field + ".x",
                          "must be finite and within ±" + std::to_string(bound) + " m", request_id);
      return;
    }
    if (!std::isfinite(point.y()) || std::abs(point.y()) > bound) {
      session->send_error(v1::ERROR_INVALID_ARGUMENT, field + ".y",
                          "must be finite and within ±" + std::to_string(bound) + " m", request_id);
      return;
    }
    points_W.emplace_back(point.x(), point.y());
  }
  // A few points' threats take microseconds, less than the hand-off to the query pool and back: those are answered on
  // the network thread; many points, or the cluster list, go to the pool.
  const bool answer_inline = points_W.size() <= kMaxInlinePtemPoints && !query.include_clusters();
  run_query(session, "ptem", request_id, answer_inline,
            [session, world, request_id, points_W = std::move(points_W), include_clusters = query.include_clusters(),
             answer_inline] {
              // The grid and the PTEM of one publication: version names the sensor message both include. Inline
              // answers use the network thread's cached snapshot; the query pool's threads take their own copy.
              WorldSnapshot own;
              const WorldSnapshot& snapshot =
                  answer_inline ? world->snapshots_for_this_thread() : (own = world->snapshots());
              const mapping::PtemSnapshot& ptem = *snapshot.ptem;
              v1::ServerMessage reply;
              auto* out = reply.mutable_ptem();
              reply.set_request_id(request_id);
              out->set_world(world->name());
              out->set_version(snapshot.grid->version());
              out->set_threshold_f_r(ptem.restricted_threshold().value_or(0.0));
              out->set_construction(ptem_construction_name(world->ptem_params().construction));
              out->set_cluster_count(static_cast<std::uint32_t>(ptem.clusters().size()));
              out->set_scans(ptem.scan_count());
              out->set_latest_stamp_s(ptem.latest_stamp_s().value_or(0.0));
              out->mutable_samples()->Reserve(static_cast<int>(points_W.size()));
              for (const Eigen::Vector2d& p_W : points_W) {
                const mapping::PtemThreat threat = ptem.threat_and_gradient(p_W);
                auto* sample = out->add_samples();
                sample->set_threat(threat.value);
                sample->mutable_gradient()->set_x(threat.gradient_W.x());
                sample->mutable_gradient()->set_y(threat.gradient_W.y());
                sample->set_restricted(ptem.restricted(p_W));
              }
              if (include_clusters) {
                for (const mapping::PtemCluster& cluster : ptem.clusters()) {
                  auto* c = out->add_clusters();
                  c->mutable_center()->set_x(cluster.centre_W.x());
                  c->mutable_center()->set_y(cluster.centre_W.y());
                  c->set_radius_m(cluster.radius_m);
                  c->set_sigma_m(cluster.sigma_m);
                  c->set_age_scans(cluster.age_scans);
                  c->set_age_s(cluster.age_s);
                  c->set_threshold_reachable(cluster.threshold_reachable);
                }
              }
              session->send(reply);
            });
}

}  // namespace occgeo::service
