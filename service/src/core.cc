#include "core.h"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <boost/asio/post.hpp>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <future>
#include <latch>

#include "durability/world_store.h"
#include "model_geometry.h"
#include "occgeo/geometry/fnv1a.h"
#include "occgeo/proto/labels.h"
#include "occgeo/service/log.h"

namespace occgeo::service {

namespace {
// Snapshot generations (and those of the robot registry) are unique across worlds and cores, so a thread's cached
// snapshot or robot can never be mistaken for that of a world or core created later at the same address.
std::uint64_t next_snapshot_generation() {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

World::World(std::string name, mapping::HimmGrid grid, const WorldParams& params, IngestStrand strand,
             std::optional<IngestStrand> octree_lane, std::optional<IngestStrand> publish_lane)
    : name_(std::move(name)),
      grid_(std::move(grid)),
      ptem_params_(params.ptem),
      ptem_(params.ptem),
      octomap_params_(params.octomap),
      octomap_(params.octomap),
      distance_field_(params.distance_field),
      distance_field_params_(params.distance_field),
      strand_(std::move(strand)),
      // Published every message or every N messages (lockstep runs), the octree stays on the ingest strand.
      octree_lane_(params.octomap_publish_every_messages == 0 && params.octomap.min_publish_interval_s > 0.0
                       ? std::move(octree_lane)
                       : std::nullopt),
      publish_lane_(octree_lane_ ? std::move(publish_lane) : std::nullopt),
      octomap_timer_(octree_lane_ ? *octree_lane_ : strand_),
      octomap_publish_every_messages_(params.octomap_publish_every_messages) {
  auto grid_snapshot = grid_.snapshot();
  static_cast<void>(grid_.take_occupancy_changes());  // the field starts from the whole grid
  distance_field_.update(grid_snapshot);
  snapshot_ = {
      std::move(grid_snapshot),   ptem_.snapshot(),   moving_now_,
      distance_field_.snapshot(), octomap_.publish(), std::make_shared<const std::vector<OctreeBandSnapshot>>(),
      octree_band_requests_};
  snapshot_generation_.store(next_snapshot_generation(), std::memory_order_release);
}

void World::publish_on_strand(std::optional<mapping::CellBox> touched) {
  stage_on_strand(touched);
  publish_staged_on_strand();
}

void World::stage_on_strand(std::optional<mapping::CellBox> touched) {
  publish_staged_on_strand();  // a publication staged before is never dropped
  staged_ = StagedPublication{grid_.snapshot(), ptem_.snapshot(), moving_now_, grid_.take_occupancy_changes(), touched};
  latest_grid_on_strand_ = staged_->grid;
  latest_ptem_on_strand_ = staged_->ptem;
  latest_moving_on_strand_ = staged_->moving;
}

void World::publish_staged_on_strand() {
  if (!staged_) return;
  StagedPublication staged = std::move(*staged_);
  staged_.reset();
  if (!publish_lane_) {
    publish_here(staged);
    return;
  }
  // A lane that cannot keep up (a driver flooding scans without waiting for acks) slows ingest instead of holding an
  // ever longer queue of grid versions.
  if (publish_backlog_.load(std::memory_order_acquire) >= kPublishBacklogMessages) wait_for_publications_on_strand();
  {
    // While the lane has not yet taken the previous publication, this one joins it: a lane that falls behind makes
    // one field update and one publication for all the messages it missed, and their replies, posted after them,
    // still follow it.
    const std::lock_guard lock(pending_publication_mutex_);
    if (pending_publication_) {
      merge_publications(*pending_publication_, std::move(staged));
      merged_publications_.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    pending_publication_ = std::move(staged);
  }
  publish_backlog_.fetch_add(1, std::memory_order_acq_rel);
  asio::post(*publish_lane_, [self = shared_from_this()] {
    std::optional<StagedPublication> pending;
    {
      const std::lock_guard lock(self->pending_publication_mutex_);
      pending.swap(self->pending_publication_);
    }
    if (pending) self->publish_here(*pending);  // always set: each job is posted with the one it takes
    self->publish_backlog_.fetch_sub(1, std::memory_order_acq_rel);
  });
}

void World::merge_publications(StagedPublication& into, StagedPublication&& later) {
  into.grid = std::move(later.grid);
  into.ptem = std::move(later.ptem);
  into.moving = std::move(later.moving);
  // The field re-reads each logged cell from the latest grid, so the logs add up (a cell flipped twice is looked at
  // twice and ends as the grid has it); past the grid's own log limit, the areas the messages touched answer.
  if (into.changed && later.changed &&
      into.changed->size() + later.changed->size() <= mapping::HimmGrid::kMaxOccupancyChanges) {
    into.changed->insert(into.changed->end(), later.changed->begin(), later.changed->end());
  } else {
    into.changed.reset();
  }
  if (into.touched && later.touched) {
    into.touched = mapping::CellBox{
        {std::min(into.touched->min.ix, later.touched->min.ix), std::min(into.touched->min.iy, later.touched->min.iy)},
        {std::max(into.touched->max.ix, later.touched->max.ix), std::max(into.touched->max.iy, later.touched->max.iy)}};
  } else {
    into.touched.reset();  // one of them could reach anywhere in the grid's tiles
  }
}

void World::publish_here(StagedPublication& staged) {
  // The grid's log of flipped cells keeps this step in proportion to what changed; `touched` (the area the
  // messages could reach) is the fallback when the log overflowed.
  if (staged.changed) {
    distance_field_.update(staged.grid, std::span<const geometry::CellIndex>(*staged.changed));
  } else {
    distance_field_.update(staged.grid, staged.touched);
  }
  auto distance = distance_field_.snapshot();
  publications_.fetch_add(1, std::memory_order_relaxed);
  // The octree's snapshot is its own (publish_octomap_here), possibly from the octree lane.
  const std::lock_guard lock(snapshot_mutex_);
  snapshot_.grid = std::move(staged.grid);
  snapshot_.ptem = std::move(staged.ptem);
  snapshot_.moving = std::move(staged.moving);
  snapshot_.distance = std::move(distance);
  snapshot_generation_.store(next_snapshot_generation(), std::memory_order_release);
}

void World::after_publications_on_strand(std::function<void()> reply) {
  if (publish_lane_) {
    asio::post(*publish_lane_, std::move(reply));
  } else {
    reply();
  }
}

void World::wait_for_publications_on_strand() {
  if (!publish_lane_) return;
  std::promise<void> done;
  asio::post(*publish_lane_, [&done] { done.set_value(); });
  done.get_future().wait();
}

WorldSnapshot World::snapshots_on_strand() const {
  WorldSnapshot models = snapshots();
  if (latest_grid_on_strand_) models.grid = latest_grid_on_strand_;
  if (latest_ptem_on_strand_) models.ptem = latest_ptem_on_strand_;
  if (latest_moving_on_strand_) models.moving = latest_moving_on_strand_;
  return models;
}

void World::apply_octree_work_on_strand(std::vector<OctreeWork> work) {
  if (!octree_lane_) {
    apply_octree_work_here(work);
    return;
  }
  if (octree_backlog_.load(std::memory_order_acquire) >= kOctreeBacklogMessages) {
    with_octree_on_strand([](mapping::OctoMapModel&) {});  // the lane is far behind: let it catch up first
  }
  octree_backlog_.fetch_add(1, std::memory_order_acq_rel);
  asio::post(*octree_lane_, [self = shared_from_this(), work = std::move(work)] {
    self->apply_octree_work_here(work);
    self->octree_backlog_.fetch_sub(1, std::memory_order_acq_rel);
  });
}

void World::apply_octree_work_here(const std::vector<OctreeWork>& work) {
  for (const OctreeWork& step : work) step(octomap_);
  if (octomap_publish_every_messages_ > 0) {
    // Counted in messages, not wall time, so lockstep runs repeat exactly.
    if (++messages_since_octomap_ >= octomap_publish_every_messages_) {
      messages_since_octomap_ = 0;
      if (octomap_.version() != octomap_.snapshot()->version()) publish_octomap_here();
    }
    return;
  }
  if (octomap_.maybe_publish()) {
    store_octomap_snapshot_here(octomap_.snapshot());
  } else if (octomap_.version() != octomap_.snapshot()->version() && !octomap_timer_armed_) {
    // The tree changed but its last snapshot is too recent: publish it once the interval has passed.
    octomap_timer_armed_ = true;
    octomap_timer_.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(octomap_.params().min_publish_interval_s)));
    octomap_timer_.async_wait([weak = weak_from_this()](const boost::system::error_code& error) {
      if (error) return;
      if (auto self = weak.lock()) {
        self->octomap_timer_armed_ = false;
        if (self->octomap_.version() != self->octomap_.snapshot()->version()) self->publish_octomap_here();
      }
    });
  }
}

void World::publish_octomap_here() { store_octomap_snapshot_here(octomap_.publish()); }

void World::store_octomap_snapshot_here(std::shared_ptr<const mapping::OctoMapSnapshot> octomap) {
  for (const double top_m : octree_band_requests_->take()) {
    const bool known = std::any_of(octree_bands_.begin(), octree_bands_.end(),
                                   [&](const auto& band) { return band->top_m() == top_m; });
    if (!known && octree_bands_.size() < kMaxOctreeBands && std::isfinite(top_m) && top_m > 0.0) {
      octree_bands_.push_back(std::make_unique<OctreeBandField>(top_m, distance_field_params_));
    }
  }
  auto bands = std::make_shared<std::vector<OctreeBandSnapshot>>();
  for (const auto& band : octree_bands_) {
    band->update(*octomap);
    bands->push_back(band->snapshot());
  }
  const std::lock_guard lock(snapshot_mutex_);
  snapshot_.octomap = std::move(octomap);
  snapshot_.octree_bands = std::move(bands);
  snapshot_generation_.store(next_snapshot_generation(), std::memory_order_release);
}

void World::with_octree_on_strand(const std::function<void(mapping::OctoMapModel& octomap)>& fn) {
  if (!octree_lane_) {
    fn(octomap_);
    return;
  }
  std::promise<void> done;
  asio::post(*octree_lane_, [&] {
    try {
      fn(octomap_);
      done.set_value();
    } catch (...) {
      done.set_exception(std::current_exception());
    }
  });
  done.get_future().get();
}

std::shared_ptr<const mapping::OctoMapSnapshot> World::publish_octomap_on_strand() {
  std::shared_ptr<const mapping::OctoMapSnapshot> published;
  with_octree_on_strand([&](mapping::OctoMapModel&) {
    publish_octomap_here();
    published = octomap_.snapshot();
  });
  return published;
}

void World::insert_ptem_on_strand(mapping::PtemScan scan) {
  if (ptem_latest_stamp_s_) scan.stamp_s = std::max(scan.stamp_s, *ptem_latest_stamp_s_);
  ptem_.insert_scan(scan);
  ptem_latest_stamp_s_ = scan.stamp_s;
}

std::vector<control::TrackedObstacle> World::moving_clusters_on_strand(const std::string& sensor,
                                                                       const Eigen::Vector2d& p_WS, double max_range_m,
                                                                       const control::LaserArc& arc) {
  auto tracker = ptem_trackers_.find(sensor);
  if (tracker == ptem_trackers_.end()) tracker = ptem_trackers_.emplace(sensor, control::ClusterTracker()).first;
  const std::shared_ptr<const mapping::PtemSnapshot> snapshot = ptem_.snapshot();
  tracker->second.update(*snapshot, p_WS, max_range_m, arc);
  // The tracks seen in this scan come first, stamped with it; those coasting unseen are not this scan's returns.
  const double stamp_s = snapshot->latest_stamp_s().value_or(0.0);
  std::vector<control::TrackedObstacle> moving;
  for (const control::TrackedObstacle& track : tracker->second.tracks()) {
    if (track.moving && track.stamp_s == stamp_s) moving.push_back(track);
  }
  // Another laser's list is left out once it is older than this (a robot gone, a laser that stopped): its people
  // have walked on.
  constexpr double kMovingKept_s = 0.5;
  auto& mine = moving_by_sensor_[sensor];
  if (!(mine.empty() && moving.empty())) {
    mine = moving;
    auto all = std::make_shared<std::vector<control::TrackedObstacle>>();
    for (auto entry = moving_by_sensor_.begin(); entry != moving_by_sensor_.end();) {
      if (!entry->second.empty() && entry->second.front().stamp_s < stamp_s - kMovingKept_s) {
        entry = moving_by_sensor_.erase(entry);
        continue;
      }
      all->insert(all->end(), entry->second.begin(), entry->second.end());
      ++entry;
    }
    moving_now_ = std::move(all);
  }
  return moving;
}

// Per tracker: its key's length and bytes, its state's length and bytes; then the FNV-1a of all that, so that a damaged
// file is refused rather than read as other tracks.
std::string World::serialize_trackers_on_strand() const {
  std::string out;
  for (const auto& [sensor, tracker] : ptem_trackers_) {
    const std::string state = tracker.serialize();
    for (const std::string_view part : {std::string_view(sensor), std::string_view(state)}) {
      const std::uint64_t size = part.size();
      out.append(reinterpret_cast<const char*>(&size), sizeof(size));
      out.append(part);
    }
  }
  const std::uint64_t checksum = geometry::fnv1a(std::string_view(out));
  out.append(reinterpret_cast<const char*>(&checksum), sizeof(checksum));
  return out;
}

void World::restore_trackers_on_strand(std::string_view state) {
  std::uint64_t checksum = 0;
  if (state.size() < sizeof(checksum)) throw std::invalid_argument("tracker state: truncated");
  std::memcpy(&checksum, state.data() + state.size() - sizeof(checksum), sizeof(checksum));
  state.remove_suffix(sizeof(checksum));
  if (checksum != geometry::fnv1a(state)) {
    throw std::invalid_argument("tracker state is damaged: its checksum does not match");
  }
  std::map<std::string, control::ClusterTracker, std::less<>> trackers;
  const auto take = [&state]() {
    std::uint64_t size = 0;
    if (state.size() < sizeof(size)) throw std::invalid_argument("tracker state: truncated");
    std::memcpy(&size, state.data(), sizeof(size));
    state.remove_prefix(sizeof(size));
    if (size > state.size()) throw std::invalid_argument("tracker state: truncated");
    const std::string_view part = state.substr(0, size);
    state.remove_prefix(size);
    return part;
  };
  while (!state.empty()) {
    const std::string sensor(take());
    trackers[sensor].restore(take());
  }
  ptem_trackers_ = std::move(trackers);
}

bool World::restore_ptem_on_strand(std::string_view state) {
  if (!ptem_.restore(state)) return false;
  ptem_latest_stamp_s_ = ptem_.snapshot()->latest_stamp_s();
  return true;
}

std::shared_ptr<const mapping::GridSnapshot> World::snapshot() const {
  const std::lock_guard lock(snapshot_mutex_);
  return snapshot_.grid;
}

WorldMemory World::memory() const {
  const WorldSnapshot& models = snapshots_for_this_thread();
  WorldMemory memory;
  memory.grid_bytes = models.grid->memory_bytes();
  memory.distance_field_bytes = models.distance ? models.distance->memory_bytes() : 0;
  memory.octomap_bytes = models.octomap->memory_bytes();
  memory.ptem_bytes = models.ptem->memory_bytes();
  return memory;
}

void lower_this_threads_priority(int nice, const char* warning) {
  if (nice == 0) return;
  const auto thread = static_cast<id_t>(gettid());
  errno = 0;
  const int current = getpriority(PRIO_PROCESS, thread);
  if ((current == -1 && errno != 0) || setpriority(PRIO_PROCESS, thread, std::min(current + nice, 19)) != 0) {
    log::warn(warning, {{"nice", nice}, {"error", std::strerror(errno)}});
  }
}

void make_this_thread_realtime(int priority, const char* warning) {
  if (priority <= 0) return;
  sched_param param{};
  param.sched_priority = priority;
  if (const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param); error != 0) {
    log::warn(warning, {{"priority", priority}, {"error", std::strerror(error)}});
  }
}

std::optional<std::uint64_t> process_resident_bytes() {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t size_pages = 0;
  std::uint64_t resident_pages = 0;
  if (!(statm >> size_pages >> resident_pages)) return std::nullopt;
  return resident_pages * static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
}

WorldSnapshot World::snapshots() const {
  const std::lock_guard lock(snapshot_mutex_);
  return snapshot_;
}

const WorldSnapshot& World::snapshots_for_this_thread() const {
  struct Cached {
    const World* world = nullptr;
    std::uint64_t generation = 0;
    WorldSnapshot snapshot;
  };
  thread_local Cached cached;
  const std::uint64_t generation = snapshot_generation_.load(std::memory_order_acquire);
  if (cached.world != this || cached.generation != generation) {
    const std::lock_guard lock(snapshot_mutex_);
    cached.world = this;
    cached.snapshot = snapshot_;
    cached.generation = snapshot_generation_.load(std::memory_order_relaxed);
  }
  return cached.snapshot;
}

namespace {
template <typename SensorModel>
const SensorModel* find_by_name(const std::vector<SensorModel>& sensors, const std::string& name) {
  for (const auto& sensor : sensors) {
    if (sensor.name == name) return &sensor;
  }
  return nullptr;
}
}  // namespace

const LaserModel* RobotModel::find_laser(const std::string& name) const { return find_by_name(lasers, name); }

const RangeArrayModel* RobotModel::find_range_array(const std::string& name) const {
  return find_by_name(range_arrays, name);
}

const ServoRangeModel* RobotModel::find_servo_range(const std::string& name) const {
  return find_by_name(servo_ranges, name);
}

const PointCloudModel* RobotModel::find_point_cloud(const std::string& name) const {
  return find_by_name(point_clouds, name);
}

bool RobotModel::has_sensor(const std::string& name) const {
  return find_laser(name) != nullptr || find_range_array(name) != nullptr || find_servo_range(name) != nullptr ||
         find_point_cloud(name) != nullptr;
}

RobotCounters robot_counters(metrics::Registry& registry, const std::string& robot_id) {
  const metrics::Labels robot = {{"robot", robot_id}};
  return RobotCounters{registry.counter("occgeo_scans_rejected_total", robot),
                       registry.counter("occgeo_scans_duplicate_total", robot),
                       registry.counter("occgeo_guard_interventions_total", robot)};
}

metrics::Counter& Robot::ingested_counter_on_strand(metrics::Registry& registry, std::string_view kind) {
  constexpr std::array<std::string_view, 4> kKinds = {"laser_scan", "range_array", "servo_range", "point_cloud"};
  static_assert(kKinds.size() == std::tuple_size_v<decltype(ingested_counters_)>);
  const auto lookup = [&] {
    return &registry.counter("occgeo_scans_ingested_total",
                             {{"robot", model_->id}, {"world", world_->name()}, {"kind", std::string(kind)}});
  };
  const auto known = std::find(kKinds.begin(), kKinds.end(), kind);
  if (known == kKinds.end()) return *lookup();
  metrics::Counter*& counter = ingested_counters_[static_cast<std::size_t>(known - kKinds.begin())];
  if (counter == nullptr) counter = lookup();
  return *counter;
}

Robot::Robot(std::shared_ptr<const RobotModel> model, std::shared_ptr<World> world, control::BearcatParams bearcat,
             RobotCounters counters, std::shared_ptr<RobotControl> control)
    : model_(std::move(model)),
      world_(std::move(world)),
      counters_(counters),
      control_(control ? std::move(control) : std::make_shared<RobotControl>()),
      watchdog_(world_->strand()),
      behaviour_(bearcat) {
  if (model_->encoders) encoder_odometry_.emplace(*model_->encoders, model_->initial_pose);
}

RobotState Robot::state() const {
  const std::lock_guard lock(mutex_);
  return state_;
}

control::BearcatParams bearcat_params_for(const RobotModel& model, control::BearcatParams configured) {
  std::visit(
      [&](const auto& drive) {
        double separation_m = 0.0;
        if constexpr (requires { drive.wheel_separation_m; }) {
          separation_m = drive.wheel_separation_m;
        } else {
          separation_m = drive.track_separation_m;
        }
        if (separation_m > 0.0) configured.wheel_separation_m = separation_m;
      },
      model.drive);
  return configured;
}

namespace {

// Runs set_up once on each of a pool's `threads` threads and returns when all have. Each thread takes one of these
// tasks (they wait for each other), so every thread runs it. The latch is shared: a pool thread may still be inside
// arrive_and_wait after this function's wait has returned.
template <typename SetUp>
void on_each_pool_thread(asio::thread_pool& pool, std::size_t threads, SetUp set_up) {
  auto done = std::make_shared<std::latch>(static_cast<std::ptrdiff_t>(threads));
  for (std::size_t i = 0; i < threads; ++i) {
    asio::post(pool, [done, set_up] {
      set_up();
      done->arrive_and_wait();
    });
  }
  done->wait();
}

// Adds `nice` to the niceness of each of a pool's `threads` threads.
void lower_pool_priority(asio::thread_pool& pool, std::size_t threads, int nice, const char* warning) {
  if (nice <= 0) return;
  on_each_pool_thread(pool, threads, [nice, warning] { lower_this_threads_priority(nice, warning); });
}

std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

ServerCore::ServerCore(ServerConfig config)
    : config_(std::move(config)),
      robots_generation_(next_snapshot_generation()),
      resident_bytes_(process_resident_bytes().value_or(0)),
      resident_read_at_ns_(steady_now_ns()) {
  // The query pool runs at the network threads' lower priority (queries.network_nice): under a query flood the ingest
  // strand, which maps the scans and computes the robots' commands, gets the CPU first.
  lower_pool_priority(query_pool_, kQueryThreads, config_.queries.network_nice, "query_pool_nice_not_applied");
  // The octree lane's work (milliseconds per scan) waits for nobody: readers see the octree up to an interval stale.
  // Below the ingest strand, so that a scan's command does not share a core with the previous scan's octree work.
  lower_pool_priority(octree_pool_, 1, config_.octomap_lane_nice, "octree_lane_nice_not_applied");
  // The ingest strands turn a scan into its command: a woken strand takes a core at once rather than after the time
  // slice of whatever normal thread runs there (milliseconds on a busy 2-core machine).
  if (const int priority = config_.control.realtime_priority; priority > 0) {
    on_each_pool_thread(ingest_pool_, 1,
                        [priority] { make_this_thread_realtime(priority, "ingest_realtime_not_applied"); });
  }
}

ServerCore::~ServerCore() {
  drain();
  for (const auto& world : worlds()) {
    if (durability::WorldJournal* journal = world->journal()) journal->shut_down();
  }
}

void ServerCore::drain() {
  for (const auto& robot : robots()) {
    asio::post(robot->world().strand(), [robot] { robot->stop_watchdog_on_strand(); });
  }
  ingest_pool_.join();
  octree_pool_.join();   // after the ingest strands, which hand it work
  publish_pool_.join();  // likewise
  for (const auto& world : worlds()) world->retire_lanes();
  query_pool_.join();
}

std::shared_ptr<World> ServerCore::world(const std::string& name) {
  const std::lock_guard lock(registry_mutex_);
  auto& slot = worlds_[name];
  if (!slot) {
    slot = std::make_shared<World>(
        name, mapping::HimmGrid(config_.himm), world_params(name), asio::make_strand(ingest_pool_.get_executor()),
        asio::make_strand(octree_pool_.get_executor()), asio::make_strand(publish_pool_.get_executor()));
    slot->attach_journal(durability::make_world_journal(config_, metrics_, name));
  }
  return slot;
}

std::shared_ptr<World> ServerCore::find_world(const std::string& name) const {
  const std::lock_guard lock(registry_mutex_);
  const auto it = worlds_.find(name);
  return it == worlds_.end() ? nullptr : it->second;
}

std::vector<std::shared_ptr<World>> ServerCore::worlds() const {
  const std::lock_guard lock(registry_mutex_);
  std::vector<std::shared_ptr<World>> all;
  for (const auto& [name, world] : worlds_) all.push_back(world);
  return all;
}

std::shared_ptr<World> ServerCore::add_world(const std::string& name, mapping::HimmGrid grid) {
  const std::lock_guard lock(registry_mutex_);
  auto& slot = worlds_[name];
  if (!slot) {
    slot = std::make_shared<World>(
        name, std::move(grid), world_params(name), asio::make_strand(ingest_pool_.get_executor()),
        asio::make_strand(octree_pool_.get_executor()), asio::make_strand(publish_pool_.get_executor()));
  }
  return slot;
}

WorldParams ServerCore::world_params(const std::string& name) const {
  // The terrain rule travels with each world's octree (OctoMapParams::terrain): no setting is shared between servers.
  mapping::OctoMapParams octomap = config_.octomap;
  octomap.terrain = config_.terrain;
  return {config_.ptem.params_for(name), octomap, config_.distance_field, config_.octomap_publish_every_messages};
}

std::shared_ptr<Robot> ServerCore::find_robot(const std::string& id) const {
  const std::lock_guard lock(registry_mutex_);
  const auto it = robots_.find(id);
  return it == robots_.end() ? nullptr : it->second;
}

const RobotQueryView& ServerCore::robot_for_this_thread(const std::string& id) const {
  struct Cached {
    std::uint64_t generation = 0;
    std::string id;
    RobotQueryView view;
  };
  thread_local Cached cached;
  if (cached.generation != robots_generation_.load(std::memory_order_acquire) || cached.id != id) {
    const std::lock_guard lock(registry_mutex_);
    const auto it = robots_.find(id);
    cached.view =
        it == robots_.end() ? RobotQueryView{} : RobotQueryView{it->second->model_ptr(), &it->second->world()};
    cached.id = id;
    cached.generation = robots_generation_.load(std::memory_order_relaxed);
  }
  return cached.view;
}

std::vector<std::shared_ptr<Robot>> ServerCore::robots() const {
  const std::lock_guard lock(registry_mutex_);
  std::vector<std::shared_ptr<Robot>> all;
  for (const auto& [id, robot] : robots_) all.push_back(robot);
  return all;
}

std::shared_ptr<Robot> ServerCore::register_robot(const std::shared_ptr<const RobotModel>& model,
                                                  const std::string& world_name, std::string& error) {
  auto target_world = world(world_name);
  const std::lock_guard lock(registry_mutex_);
  if (const auto it = robots_.find(model->id); it != robots_.end() && it->second->state().connected) {
    error = "robot '" + model->id + "' already has a driver connected";
    return nullptr;
  }
  if (!robots_.contains(model->id) && robots_.size() >= config_.limits.max_robots) {
    error = "the server already has its limit of " + std::to_string(config_.limits.max_robots) + " robots";
    return nullptr;
  }
  // A reconnecting driver's robot keeps its control (lease, behaviour, latched e-stop).
  std::shared_ptr<RobotControl> control;
  if (const auto it = robots_.find(model->id); it != robots_.end()) control = it->second->control_ptr();
  if (!control) {
    control = std::make_shared<RobotControl>();
    // The robot's own default (a sonar robot wanders) stands in for the Bearcat, never for an initial stop.
    const v1::Behaviour own_default = model->spec.default_behaviour();
    const v1::Behaviour initial =
        config_.control.initial_behaviour == "bearcat" && own_default != v1::BEHAVIOUR_UNSPECIFIED
            ? own_default
            : proto::behaviour_from_label(config_.control.initial_behaviour).value();
    control->update([&](ControlState& c) { c.behaviour = initial; });
  }
  auto robot = std::make_shared<Robot>(model, std::move(target_world), bearcat_params_for(*model, config_.bearcat),
                                       robot_counters(metrics_, model->id), std::move(control));
  robots_[model->id] = robot;
  robots_generation_.store(next_snapshot_generation(), std::memory_order_release);
  return robot;
}

double ServerCore::uptime_s() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
}

std::uint64_t ServerCore::recent_resident_bytes() const {
  const std::int64_t now_ns = steady_now_ns();
  std::int64_t read_at_ns = resident_read_at_ns_.load(std::memory_order_acquire);
  // One caller refreshes the value; the others meanwhile answer with the previous one.
  if (now_ns - read_at_ns >= std::chrono::nanoseconds(kResidentRefreshInterval).count() &&
      resident_read_at_ns_.compare_exchange_strong(read_at_ns, now_ns, std::memory_order_acq_rel)) {
    resident_bytes_.store(process_resident_bytes().value_or(0), std::memory_order_release);
  }
  return resident_bytes_.load(std::memory_order_acquire);
}

}  // namespace occgeo::service
