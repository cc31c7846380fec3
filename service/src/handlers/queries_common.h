#pragma once

#include <array>
#include <boost/asio/post.hpp>
#include <cstdint>
#include <functional>
#include <initializer_list>
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

// The robot a query names and the footprint to check: the query's override or the robot's own. Answered on the
// calling thread, it refers to the robot through that thread's cache (ServerCore::robot_for_this_thread) and copies
// nothing; `keep_model` holds the model for work that leaves the thread.
struct QueryTarget {
  std::shared_ptr<const RobotModel> keep_model;  // set only for work answered on another thread
  const RobotModel* model = nullptr;
  World* world = nullptr;
  std::optional<geometry::Footprint> override_footprint;

  [[nodiscard]] const geometry::Footprint& footprint() const {
    return override_footprint ? *override_footprint : model->footprint;
  }
};

// The robot and footprint a query names; `leaves_thread`: the work will run on another thread (the query pool), so
// the target keeps the robot's model alive itself.
std::optional<QueryTarget> resolve_robot_footprint(const SessionPtr& session, const std::string& kind,
                                                   std::uint64_t request_id, const std::string& robot_id,
                                                   bool has_footprint, const v1::Footprint& footprint,
                                                   bool leaves_thread);

// The models a query asks about, in its order without repeats; at most the three there are, so they are kept inline
// (no allocation per query).
class ModelList {
 public:
  ModelList() = default;
  ModelList(std::initializer_list<v1::Model> models) {
    for (const v1::Model model : models) push_back(model);
  }
  void push_back(v1::Model model) { models_.at(size_++) = model; }
  [[nodiscard]] const v1::Model* data() const { return models_.data(); }
  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] const v1::Model* begin() const { return models_.data(); }
  [[nodiscard]] const v1::Model* end() const { return models_.data() + size_; }

 private:
  std::array<v1::Model, 3> models_{};
  std::size_t size_ = 0;
};

// GRID, OCTOMAP, PTEM when the query names none.
std::optional<ModelList> resolve_models(const SessionPtr& session, const std::string& kind, std::uint64_t request_id,
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
// The same for a PtemQuery's points: a threat and its gradient at one point take well under a microsecond.
inline constexpr std::size_t kMaxInlinePtemPoints = 32;

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
