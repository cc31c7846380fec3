#pragma once

#include <boost/asio/post.hpp>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "handlers.h"
#include "occgeo/geometry/footprint.h"
#include "occgeo/geometry/pose.h"

// Checks shared by the query handlers (queries.cc, queries_batch.cc, map_window.cc). Each sends the error reply
// itself (ERROR_INVALID_ARGUMENT / UNKNOWN_* naming the field) and returns nullopt when the request is refused.

namespace occgeo::service {

// The robot a query names and the footprint to check: the query's override or the robot's own.
struct QueryTarget {
  std::shared_ptr<Robot> robot;
  geometry::Footprint footprint;
};

std::optional<QueryTarget> resolve_robot_footprint(const SessionPtr& session, const std::string& kind,
                                                   std::uint64_t request_id, const std::string& robot_id,
                                                   bool has_footprint, const v1::Footprint& footprint);

// The models a query asks about, in its order without repeats; GRID, OCTOMAP, PTEM when it names none.
std::optional<std::vector<v1::Model>> resolve_models(const SessionPtr& session, const std::string& kind,
                                                     std::uint64_t request_id,
                                                     const google::protobuf::RepeatedField<int>& asked);

// The world a query names (empty: the server's default world).
std::shared_ptr<World> resolve_world(const SessionPtr& session, const std::string& kind, std::uint64_t request_id,
                                     const std::string& world);

// A checked pose (finite, within limits.max_abs_coordinate_m); field names it, e.g. "collision_batch.poses[3]".
std::optional<geometry::Pose2> resolve_pose(const SessionPtr& session, const v1::Pose2D& pose, const std::string& field,
                                            std::uint64_t request_id);

// Entries (poses, rays, points) a query may hold and still be answered inline on the session's network strand: a few
// footprint checks or lookups on an immutable published snapshot take microseconds, less than the two thread
// hand-offs (to the query pool and back) would add. Larger batches, swept motions and windows go to the query pool.
inline constexpr std::size_t kMaxInlineEntries = 8;

// Runs a query's work (guarded and timed, see run_guarded): on the caller's thread when answer_inline, else on the
// query pool.
template <typename Work>
void run_query(const SessionPtr& session, const char* kind, std::uint64_t request_id, bool answer_inline, Work work) {
  if (answer_inline) {
    run_guarded(session, kind, request_id, std::cref(work));
    return;
  }
  asio::post(session->core().query_pool(), [session, kind, request_id, work = std::move(work)] {
    run_guarded(session, kind, request_id, std::cref(work));
  });
}

// Checks 1 <= count <= limit for a repeated field.
bool check_count(const SessionPtr& session, std::size_t count, std::size_t limit, const std::string& field,
                 std::uint64_t request_id);

}  // namespace occgeo::service
