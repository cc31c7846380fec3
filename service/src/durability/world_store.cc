#include "world_store.h"

#include <fcntl.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <array>
#include <boost/asio/post.hpp>
#include <charconv>
#include <chrono>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <stdexcept>

#include "../core.h"
#include "../ingest/model_ingest.h"
#include "../validation.h"
#include "occgeo/mapfile/map_file.h"
#include "occgeo/service/log.h"

namespace occgeo::service::durability {

namespace {

constexpr const char* kSnapshotInfo = "snapshot.yaml";
constexpr const char* kPtemState = "ptem.bin";
constexpr const char* kTrackerState = "trackers.bin";  // which laser returns ingest takes for walkers (see core.h)

std::string read_whole_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + file.string());
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Brings back the world's PTEM from its snapshot. State written under other PTEM parameters is set aside with a
// warning (the journal tail alone then rebuilds it); a damaged file throws, as a damaged grid does.
void restore_ptem(World& world, const std::filesystem::path& file) {
  try {
    if (!world.restore_ptem_on_strand(read_whole_file(file))) {
      log::warn("ptem_snapshot_skipped",
                {{"world", world.name()},
                 {"file", file.string()},
                 {"reason", "written under other ptem parameters; the PTEM restarts from the journal"}});
    }
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error("snapshot " + file.string() + " is damaged: " + e.what());
  }
}

// Flushes a file or folder to disk; a snapshot is only renamed into place once all of it is durable.
void sync_path(const std::filesystem::path& path, bool directory) {
  const int fd = ::open(path.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
  if (fd < 0) throw std::runtime_error("cannot open " + path.string() + " to sync it");
  const int result = ::fsync(fd);
  ::close(fd);
  if (result != 0) throw std::runtime_error("cannot sync " + path.string());
}

// The last journal lsn a snapshot folder holds (0 for a folder written before journals existed).
std::uint64_t snapshot_lsn(const std::filesystem::path& dir) {
  const auto info = dir / kSnapshotInfo;
  if (!std::filesystem::exists(info)) return 0;
  try {
    return YAML::LoadFile(info.string())["journal_lsn"].as<std::uint64_t>();
  } catch (const YAML::Exception& e) {
    throw std::runtime_error("snapshot " + info.string() + " is damaged: " + e.what());
  }
}

// A crash while a snapshot was being swapped in leaves "<name>.old" (the previous snapshot) or "<name>.saving" (an
// incomplete new one) beside it: the previous snapshot is the one the journal continues.
void finish_interrupted_swaps(const std::filesystem::path& worlds_dir) {
  if (!std::filesystem::is_directory(worlds_dir)) return;
  std::vector<std::filesystem::path> leftovers;
  for (const auto& entry : std::filesystem::directory_iterator(worlds_dir)) {
    const auto ext = entry.path().extension();
    if (ext == ".old" || ext == ".saving") leftovers.push_back(entry.path());
  }
  for (const auto& path : leftovers) {
    auto base = path;
    base.replace_extension();
    if (path.extension() == ".old" && !std::filesystem::exists(base)) {
      log::warn("snapshot_swap_finished", {{"from", path.string()}, {"to", base.string()}});
      std::filesystem::rename(path, base);
    } else {
      std::filesystem::remove_all(path);
    }
  }
}

// The robots' last delivered messages a snapshot folder holds (see WorldJournal::delivered).
WorldJournal::Delivered snapshot_delivered(const std::filesystem::path& dir) {
  WorldJournal::Delivered delivered;
  const auto info = dir / kSnapshotInfo;
  if (!std::filesystem::exists(info)) return delivered;
  try {
    const YAML::Node robots = YAML::LoadFile(info.string())["delivered"];
    if (!robots) return delivered;
    for (const auto& robot : robots) {
      auto& seqs = delivered[robot.first.as<std::string>()];
      for (const auto& pair : robot.second) seqs[pair[0].as<std::uint64_t>()] = pair[1].as<std::uint64_t>();
    }
  } catch (const YAML::Exception& e) {
    throw std::runtime_error("snapshot " + info.string() + " is damaged: " + e.what());
  }
  return delivered;
}

// The seq every sensor message carries.
struct SensorOrder {
  std::uint64_t seq = 0;
};

// Applies one journalled sensor message as ingest did: at the pose it recorded, through the same insertion code.
SensorOrder replay_sensor(World& world, IngestTarget& target, const RobotModel& model, const JournalRecord& record,
                          const std::filesystem::path& file) {
  const auto damaged = [&](const std::string& what) {
    return std::runtime_error("journal " + file.string() + " record " + std::to_string(record.lsn) + ": " + what);
  };
  if (record.kind == "laser_scan") {
    v1::LaserScan message;
    if (!message.ParseFromString(record.body)) throw damaged("undecodable laser_scan");
    const LaserModel* laser = model.find_laser(message.sensor());
    if (!laser) throw damaged("robot '" + model.id + "' has no laser '" + message.sensor() + "'");
    insert_laser_scan(world, target, model.id, record.X_WB, *laser, message);
    return {message.seq()};
  }
  if (record.kind == "range_array") {
    v1::RangeArray message;
    if (!message.ParseFromString(record.body)) throw damaged("undecodable range_array");
    const RangeArrayModel* array = model.find_range_array(message.sensor());
    if (!array) throw damaged("robot '" + model.id + "' has no range array '" + message.sensor() + "'");
    insert_range_array(target, record.X_WB, *array, message);
    return {message.seq()};
  }
  if (record.kind == "servo_range") {
    v1::ServoRange message;
    if (!message.ParseFromString(record.body)) throw damaged("undecodable servo_range");
    const ServoRangeModel* servo = model.find_servo_range(message.sensor());
    if (!servo) throw damaged("robot '" + model.id + "' has no servo range '" + message.sensor() + "'");
    insert_servo_range(target, record.X_WB, *servo, message);
    return {message.seq()};
  }
  if (record.kind == "point_cloud") {
    v1::PointCloud message;
    if (!message.ParseFromString(record.body)) throw damaged("undecodable point_cloud");
    const PointCloudModel* cloud = model.find_point_cloud(message.sensor());
    if (!cloud) throw damaged("robot '" + model.id + "' has no point cloud '" + message.sensor() + "'");
    insert_point_cloud(target, record.X_WB, model, *cloud, message);
    return {message.seq()};
  }
  throw damaged("unknown sensor kind '" + record.kind + "'");
}

struct ReplayResult {
  std::uint64_t last_lsn = 0;
  std::uint64_t replayed = 0;
};

ReplayResult replay_journal(ServerCore& core, World& world, const std::filesystem::path& file, std::uint64_t after_lsn,
                            WorldJournal::Delivered& delivered) {
  ReplayResult result{after_lsn, 0};
  const JournalContents contents = read_journal(file);
  if (contents.torn_tail) {
    log::warn("journal_torn_tail_truncated",
              {{"file", file.string()},
               {"offset", contents.valid_bytes},
               {"reason", "the last record was cut short by a crash; it was never acknowledged"}});
    std::filesystem::resize_file(file, contents.valid_bytes);
  }
  std::map<std::string, std::shared_ptr<const RobotModel>> robots;
  for (const auto& record : contents.records) {
    result.last_lsn = std::max(result.last_lsn, record.lsn);
    if (record.type == RecordType::kRobot) {
      v1::RobotSpec spec;
      if (!spec.ParseFromString(record.body)) {
        throw std::runtime_error("journal " + file.string() + " record " + std::to_string(record.lsn) +
                                 ": undecodable robot_spec");
      }
      FieldError error;
      auto model = robot_model_from_spec(record.robot_id, spec, core.config().limits, error, core.config().sensors);
      if (!model) {
        throw std::runtime_error("journal " + file.string() + " record " + std::to_string(record.lsn) +
                                 ": the robot_spec of '" + record.robot_id + "' is refused by this configuration (" +
                                 error.field + ": " + error.message + ")");
      }
      robots[record.robot_id] = std::move(model);
      continue;
    }
    if (record.lsn <= after_lsn) continue;  // the snapshot already holds it
    const auto robot = robots.find(record.robot_id);
    if (robot == robots.end()) {
      throw std::runtime_error("journal " + file.string() + " record " + std::to_string(record.lsn) +
                               ": no robot_spec precedes the data of robot '" + record.robot_id + "'");
    }
    IngestTarget target{world.grid_on_strand(), world.octomap_params(), std::nullopt, {}};
    const SensorOrder order = replay_sensor(world, target, *robot->second, record, file);
    world.apply_octree_work_on_strand(std::move(target.octree_work));
    auto& seqs = delivered[record.robot_id];
    seqs[order.seq] = message_fingerprint(record.kind, record.body);
    while (seqs.size() > WorldJournal::kDeliveredWindow) seqs.erase(seqs.begin());
    ++result.replayed;
  }
  return result;
}

}  // namespace

std::filesystem::path world_snapshot_dir(const std::filesystem::path& data_dir, const std::string& world) {
  return data_dir / "worlds" / world;
}

std::filesystem::path world_journal_file(const std::filesystem::path& data_dir, const std::string& world) {
  return data_dir / "journal" / (world + ".journal");
}

std::shared_ptr<WorldJournal> make_world_journal(const ServerConfig& config, metrics::Registry& metrics,
                                                 const std::string& world, std::uint64_t next_lsn,
                                                 std::uint64_t snapshot_lsn) {
  const auto policy = parse_sync_policy(config.durability.policy).value_or(SyncPolicy::kEvery);
  const auto interval = std::chrono::microseconds(static_cast<std::int64_t>(config.durability.batch_interval_s * 1e6));
  return std::make_shared<WorldJournal>(world_journal_file(config.data_dir, world), policy, interval, next_lsn,
                                        snapshot_lsn, metrics);
}

void restore_worlds(ServerCore& core) {
  const auto& config = core.config();
  const auto worlds_dir = config.data_dir / "worlds";
  const auto journal_dir = config.data_dir / "journal";
  finish_interrupted_swaps(worlds_dir);
  std::set<std::string> names;
  const auto consider = [&](const std::filesystem::path& path, const std::string& name) {
    if (valid_name(name)) {
      names.insert(name);
    } else {
      log::warn("restore_skipped", {{"path", path.string()}, {"reason", "not a valid world name"}});
    }
  };
  if (std::filesystem::is_directory(worlds_dir)) {
    for (const auto& entry : std::filesystem::directory_iterator(worlds_dir)) {
      if (entry.is_directory()) consider(entry.path(), entry.path().filename().string());
    }
  }
  if (std::filesystem::is_directory(journal_dir)) {
    for (const auto& entry : std::filesystem::directory_iterator(journal_dir)) {
      if (entry.is_regular_file() && entry.path().extension() == ".journal") {
        consider(entry.path(), entry.path().stem().string());
      }
    }
  }
  for (const auto& name : names) {
    const auto started = std::chrono::steady_clock::now();
    const auto dir = world_snapshot_dir(config.data_dir, name);
    const auto yaml = dir / "grid.yaml";
    const bool has_grid = std::filesystem::exists(yaml);
    mapping::HimmGrid grid = has_grid ? mapping::HimmGrid::from_image(mapfile::read_map_yaml(yaml), config.himm)
                                      : mapping::HimmGrid(config.himm);
    const std::uint64_t base_lsn = snapshot_lsn(dir);
    auto world = core.add_world(name, std::move(grid));
    // No strand work exists yet, so this thread is the worlds' only writer.
    if (const auto bt = dir / "octomap.bt"; std::filesystem::exists(bt)) {
      world->with_octree_on_strand([&](mapping::OctoMapModel& octomap) { octomap.load_bt(bt); });
    }
    if (const auto ptem = dir / kPtemState; std::filesystem::exists(ptem)) restore_ptem(*world, ptem);
    if (const auto trackers = dir / kTrackerState; std::filesystem::exists(trackers)) {
      try {
        world->restore_trackers_on_strand(read_whole_file(trackers));
      } catch (const std::invalid_argument& e) {
        throw std::runtime_error("snapshot " + trackers.string() + " is damaged: " + e.what());
      }
    }
    ReplayResult replay{base_lsn, 0};
    WorldJournal::Delivered delivered = snapshot_delivered(dir);
    if (const auto journal = world_journal_file(config.data_dir, name); std::filesystem::exists(journal)) {
      replay = replay_journal(core, *world, journal, base_lsn, delivered);
    }
    auto journal = make_world_journal(config, core.metrics(), name, replay.last_lsn + 1, base_lsn);
    journal->restore_delivered(std::move(delivered));
    world->attach_journal(std::move(journal));
    world->publish_on_strand();
    world->wait_for_publications_on_strand();  // readers see the restored world from the first connection on
    world->publish_octomap_on_strand();
    log::info(
        "world_restored",
        {{"world", name},
         {"snapshot", has_grid || std::filesystem::exists(dir / "octomap.bt") ? dir.string() : std::string("none")},
         {"journal_records_replayed", replay.replayed},
         {"occupied_cells", world->grid_on_strand().occupied_cell_count()},
         {"octomap_leaves", static_cast<std::uint64_t>(world->snapshots().octomap->leaf_count())},
         {"ptem_clusters", static_cast<std::uint64_t>(world->snapshots().ptem->clusters().size())},
         {"restore_s", std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count()}});
  }
}

bool snapshot_world(ServerCore& core, World& world) {
  WorldJournal* journal = world.journal();
  const std::uint64_t lsn = journal ? journal->last_lsn() : 0;
  const bool has_grid = world.grid_on_strand().tile_count() > 0;
  bool has_octomap = false;
  world.with_octree_on_strand([&](mapping::OctoMapModel& octomap) { has_octomap = octomap.leaf_count() > 0; });
  const bool has_ptem = world.ptem_scan_count_on_strand() > 0;
  if (!has_grid && !has_octomap && !has_ptem && lsn == 0) return true;  // nothing observed, nothing to keep
  const auto final_dir = world_snapshot_dir(core.config().data_dir, world.name());
  const auto temp_dir = std::filesystem::path(final_dir.string() + ".saving");
  const auto old_dir = std::filesystem::path(final_dir.string() + ".old");
  try {
    std::filesystem::remove_all(temp_dir);
    std::filesystem::create_directories(temp_dir);
    if (has_grid) {
      mapfile::write_map(temp_dir / "grid", world.grid_on_strand().to_image());
      sync_path(temp_dir / "grid.pgm", false);
      sync_path(temp_dir / "grid.yaml", false);
    }
    if (has_octomap) {
      world.with_octree_on_strand([&](mapping::OctoMapModel& octomap) { octomap.save_bt(temp_dir / "octomap.bt"); });
      sync_path(temp_dir / "octomap.bt", false);
    }
    const auto write_bytes = [&](const char* file, const std::string& state) {
      std::ofstream out(temp_dir / file, std::ios::binary);
      out.write(state.data(), static_cast<std::streamsize>(state.size()));
      if (!out.flush()) throw std::runtime_error("cannot write " + (temp_dir / file).string());
      out.close();
      sync_path(temp_dir / file, false);
    };
    if (has_ptem) {
      write_bytes(kPtemState, world.serialize_ptem_on_strand());
      write_bytes(kTrackerState, world.serialize_trackers_on_strand());
    }
    {
      std::ofstream info(temp_dir / kSnapshotInfo);
      info << "# the last journal record this snapshot holds; later records are replayed over it\n"
           << "journal_lsn: " << lsn << "\n";
      if (journal) {
        // Each robot's last sensor messages, [seq, fingerprint], so that one resent after a restart is known.
        info << "delivered:\n";
        for (const auto& [robot_id, seqs] : journal->delivered()) {
          info << "  \"" << robot_id << "\":\n";
          for (const auto& [seq, fingerprint] : seqs) info << "    - [" << seq << ", " << fingerprint << "]\n";
        }
      }
      if (!info.flush()) throw std::runtime_error("cannot write " + (temp_dir / kSnapshotInfo).string());
    }
    sync_path(temp_dir / kSnapshotInfo, false);
    sync_path(temp_dir, true);
    // The previous snapshot stays whole (as <name>.old) until the new one is in place.
    std::filesystem::remove_all(old_dir);
    if (std::filesystem::exists(final_dir)) std::filesystem::rename(final_dir, old_dir);
    std::filesystem::rename(temp_dir, final_dir);
    sync_path(final_dir.parent_path(), true);
    std::filesystem::remove_all(old_dir);
  } catch (const std::exception& e) {
    log::error("world_save_failed", {{"world", world.name()}, {"error", e.what()}});
    return false;
  }
  if (journal) journal->compact();
  log::info("world_saved", {{"world", world.name()}, {"dir", final_dir.string()}, {"journal_lsn", lsn}});
  return true;
}

void snapshot_world_if_changed(ServerCore& core, const std::shared_ptr<World>& world) {
  boost::asio::post(world->strand(), [&core, world] {
    if (WorldJournal* journal = world->journal(); journal && journal->changed_since_snapshot())
      snapshot_world(core, *world);
  });
}

}  // namespace occgeo::service::durability
