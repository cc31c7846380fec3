#pragma once
// The write-ahead journal of one world: every sensor message that changes the world's maps, appended before it is
// applied, with the robot pose ingest placed it at, so that a snapshot plus a replay of the journal rebuilds the maps
// cell for cell after a crash. Files with a length and a CRC-32 per record rather than SQLite: the journal is only ever
// appended to, read whole at start and truncated after a snapshot, so a database buys nothing but a second copy of
// each record (its own WAL) and a dependency in the ingest path.
//
// File layout: the 8-byte magic "OCCGEOJ1", then records, each
//   u32 payload length (little-endian) | u32 CRC-32 of the payload | u32 CRC-32 of those 8 bytes | payload
// (the header's own CRC tells a damaged length in the middle of the file from a record a crash cut short at its end)
// and the payload is
//   u64 lsn | u8 type | u16 robot id length | robot id | type-specific body
// type 1 (robot): the body is the robot's RobotSpec (protobuf); it precedes the robot's first sensor record in a file.
// type 2 (sensor): f64 x, y, theta of X_WB (the pose the message was placed at) | u8 kind length | kind (the
// ClientMessage field, e.g. "laser_scan") | the sensor message (protobuf).
// lsn numbers the world's records from 1 and never restarts; a snapshot records the last lsn it holds, so records that
// a crash left in the journal after the snapshot was written are skipped on replay.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "occgeo/geometry/pose.h"

namespace google::protobuf {
class MessageLite;
}

namespace occgeo::service::metrics {
class Gauge;
class Histogram;
class Registry;
}  // namespace occgeo::service::metrics

namespace occgeo::service::durability {

// When an accepted message counts as durable, hence may be acknowledged.
enum class SyncPolicy {
  kEvery,  // fdatasync of each record before its ack, by the journal's sync thread as soon as the record is written
  kBatch,  // group commit: acks wait for the fsync that ends the batch window
  kNone,   // acknowledged once written to the OS; a power loss may lose what the OS had not written
};

// A stable 64-bit FNV-1a hash of a sensor message's kind and serialized bytes: equal for a resent copy of the same
// message, across restarts and builds.
[[nodiscard]] std::uint64_t message_fingerprint(std::string_view kind, std::string_view serialized);

// "every" / "batch" / "none"; nullopt for anything else.
[[nodiscard]] std::optional<SyncPolicy> parse_sync_policy(const std::string& name);

enum class RecordType : std::uint8_t { kRobot = 1, kSensor = 2 };

struct JournalRecord {
  std::uint64_t lsn = 0;
  RecordType type = RecordType::kSensor;
  std::string robot_id;
  geometry::Pose2 X_WB;  // sensor records only
  std::string kind;      // sensor records only: "laser_scan", "range_array", "servo_range", "point_cloud"
  std::string body;      // RobotSpec or the sensor message, serialized
};

// A journal whose middle is damaged: records after the damage cannot be trusted to follow the lost ones.
class JournalCorrupt : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct JournalContents {
  std::vector<JournalRecord> records;
  std::uint64_t valid_bytes = 0;  // the file's length up to the end of the last good record
  bool torn_tail = false;         // bytes after valid_bytes form an incomplete or damaged last record
};

// Reads a journal file. A damaged last record (shorter than its length says, or failing its CRC with nothing but
// zeros after it) is a torn write: it is reported in torn_tail and left out. Damage followed by more data throws
// JournalCorrupt naming the file and the byte offset.
[[nodiscard]] JournalContents read_journal(const std::filesystem::path& file);

// Appends records to one world's journal file and tells when they are durable. append_* are called from the world's
// ingest strand only; the batch policy's fsyncs run on a thread of their own.
class WorldJournal {
 public:
  // `next_lsn` continues the numbering of what the file (or the snapshot) already holds; `snapshot_lsn` is the last
  // record the world's snapshot holds. The file is opened on the first append, so a world that never ingests never
  // creates one.
  // Its gauges and the fsync histogram go to `metrics`, which must outlive it.
  WorldJournal(std::filesystem::path file, SyncPolicy policy, std::chrono::microseconds batch_interval,
               std::uint64_t next_lsn, std::uint64_t snapshot_lsn, metrics::Registry& metrics);
  ~WorldJournal();
  // Stops the sync thread (after it has synced what was written and answered those waiting) and drops every callback
  // it still holds, uncalled: one may hold the last reference to what owns this journal (a driver's session, its
  // robot, their world), and kept here it would keep all of them, and this journal, alive for good (their strands
  // and timers then outlive the server's thread pools). For a server shutting down, after its last snapshot.
  void shut_down();
  WorldJournal(const WorldJournal&) = delete;
  WorldJournal& operator=(const WorldJournal&) = delete;

  // Appends a sensor message placed at X_WB, preceded by the robot's spec when this file does not hold it yet (a
  // driver that reconnects with another spec gets a new record: `robot_spec_identity` tells specs apart). Under the
  // `every` policy the record is on disk when this returns. Returns the record's lsn, or the reason it could not be
  // written (disk full, I/O error): the file is then left as it was before the call and the message must not be
  // applied.
  struct AppendResult {
    std::uint64_t lsn = 0;
    std::string error;              // empty on success
    std::uint64_t fingerprint = 0;  // message_fingerprint of the message, for note_delivered
  };
  AppendResult append_sensor(const std::string& robot_id, const std::shared_ptr<const void>& robot_spec_identity,
                             const google::protobuf::MessageLite& robot_spec, const geometry::Pose2& X_WB,
                             const std::string& kind, const google::protobuf::MessageLite& message);

  // Calls done(nullptr) once record `lsn` is durable under the policy (at once for `every` and `none`), or
  // done(&reason) if syncing it failed. From the batch thread for `batch`. Callbacks run one at a time and in the
  // order of their lsns, whichever thread runs them: a driver's acks leave in the order of its messages, so a driver
  // that pipelines and waits for each ack in turn never misses one that overtook another.
  void when_durable(std::uint64_t lsn, std::function<void(const std::string* error)> done);

  // After a snapshot holding every record up to last_lsn() is safely on disk: empties the file (keeping the
  // numbering) and completes waiting acks, which the snapshot made durable. Call from the world's strand.
  void compact();

  // What each robot's last sensor messages were (seq and a fingerprint of the message), kept for the last
  // kDeliveredWindow messages per robot so that a driver resending one whose ack it lost (a dropped connection, a
  // server crash) is told it is already durable instead of having it applied twice. Restored from the snapshot and the
  // journal at start.
  static constexpr std::size_t kDeliveredWindow = 512;
  using Delivered = std::map<std::string, std::map<std::uint64_t, std::uint64_t>>;  // robot -> seq -> fingerprint
  // Records one accepted (journalled) sensor message.
  void note_delivered(const std::string& robot_id, std::uint64_t seq, std::uint64_t fingerprint);
  // True when the robot's message with this seq and exactly this content (`kind`, `message`) is already in the journal
  // or the snapshot. Serializes the message only when the seq is one of the remembered ones.
  [[nodiscard]] bool already_delivered(const std::string& robot_id, std::uint64_t seq, std::string_view kind,
                                       const google::protobuf::MessageLite& message) const;
  [[nodiscard]] Delivered delivered() const;
  void restore_delivered(Delivered delivered);

  // The lsn of the last record appended (0 when none ever was).
  [[nodiscard]] std::uint64_t last_lsn() const;
  // True when records were appended (or replayed at start) since the last snapshot.
  [[nodiscard]] bool changed_since_snapshot() const;
  // Bytes in the file now (0 before the first append).
  [[nodiscard]] std::uint64_t size_bytes() const;
  [[nodiscard]] const std::filesystem::path& file() const { return file_; }

 private:
  std::string open_locked();
  std::string write_locked(const std::string& frame);
  std::string sync_locked_fd(int fd) const;
  // After an fsync that covered the file up to `end` and record `lsn`: the journal lag metrics.
  void note_synced_locked(std::uint64_t lsn, std::uint64_t end);
  void update_lag_metrics_locked();
  void sync_loop();
  void complete(std::uint64_t up_to_lsn, const std::string* error);

  std::filesystem::path file_;
  SyncPolicy policy_;
  std::chrono::microseconds batch_interval_;
  mutable std::mutex mutex_;
  // Held while callbacks of when_durable run (taken before mutex_, never after it): a record found durable at
  // registration must not call back while the batch thread is still calling back for earlier records.
  std::mutex completion_mutex_;
  std::condition_variable wake_;
  int fd_ = -1;
  std::uint64_t end_ = 0;         // bytes written to the file
  std::uint64_t next_lsn_;        // of the next record
  std::uint64_t written_lsn_;     // last record written
  std::uint64_t durable_lsn_;     // last record known durable
  std::uint64_t synced_lsn_;      // last record an fsync covered (durable_lsn_ runs ahead of it under `none`)
  std::uint64_t synced_end_ = 0;  // bytes of the file an fsync covered
  std::uint64_t snapshot_lsn_;    // last record the world's snapshot holds
  std::string failed_;            // set after an fsync failure: nothing more is acknowledged until a restart
  // The spec each robot's records in this file refer to (held, so that its address is not reused for another).
  std::map<std::string, std::shared_ptr<const void>> robots_in_file_;
  Delivered delivered_;
  std::vector<std::pair<std::uint64_t, std::function<void(const std::string*)>>> waiting_;
  // Callbacks the sync thread has run, destroyed by the next append (or with the journal) rather than on that thread:
  // one may hold the last reference to what owns this journal, whose destructor joins that thread.
  std::vector<std::function<void(const std::string*)>> finished_callbacks_;
  bool stopping_ = false;
  // /metrics, labelled with the world: how far the file runs ahead of what an fsync made durable, and fsync times.
  metrics::Gauge& unsynced_records_;
  metrics::Gauge& unsynced_bytes_;
  metrics::Gauge& journal_bytes_;
  metrics::Histogram& sync_seconds_;
  std::thread sync_thread_;
};

}  // namespace occgeo::service::durability
