#include "journal.h"

#include <fcntl.h>
#include <google/protobuf/message_lite.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>

#include "../metrics.h"
#include "occgeo/geometry/fnv1a.h"

namespace occgeo::service::durability {

namespace {

constexpr std::string_view kMagic = "OCCGEOJ1";
constexpr std::size_t kFrameHeaderBytes = 12;  // length, payload CRC, CRC of those two
// A record longer than this is damage, not data: frames are bounded far below by limits.max_frame_bytes.
constexpr std::uint32_t kMaxPayloadBytes = 1U << 30;

static_assert(std::endian::native == std::endian::little, "the journal is written in the host's byte order");

template <typename T>
void put(std::string& out, T value) {
  std::array<char, sizeof(T)> bytes{};
  std::memcpy(bytes.data(), &value, sizeof(T));
  out.append(bytes.data(), bytes.size());
}

template <typename T>
bool get(std::string_view& in, T& value) {
  if (in.size() < sizeof(T)) return false;
  std::memcpy(&value, in.data(), sizeof(T));
  in.remove_prefix(sizeof(T));
  return true;
}

std::uint32_t crc_of(std::string_view bytes) {
  return static_cast<std::uint32_t>(
      crc32(0L, reinterpret_cast<const Bytef*>(bytes.data()), static_cast<uInt>(bytes.size())));
}

std::string frame_of(const std::string& payload) {
  std::string frame;
  frame.reserve(kFrameHeaderBytes + payload.size());
  put(frame, static_cast<std::uint32_t>(payload.size()));
  put(frame, crc_of(payload));
  put(frame, crc_of(frame));
  frame += payload;
  return frame;
}

std::string errno_text(const std::string& what, int error) { return what + ": " + std::strerror(error); }

metrics::Labels world_label(const std::filesystem::path& file) { return {{"world", file.stem().string()}}; }

// Decodes one payload whose CRC matched; false when its structure is wrong (which a CRC match makes a bug or
// deliberate damage, treated as corruption).
bool decode_payload(std::string_view in, JournalRecord& record) {
  std::uint8_t type = 0;
  std::uint16_t id_length = 0;
  if (!get(in, record.lsn) || !get(in, type) || !get(in, id_length) || in.size() < id_length) return false;
  record.robot_id.assign(in.substr(0, id_length));
  in.remove_prefix(id_length);
  if (type == static_cast<std::uint8_t>(RecordType::kRobot)) {
    record.type = RecordType::kRobot;
  } else if (type == static_cast<std::uint8_t>(RecordType::kSensor)) {
    record.type = RecordType::kSensor;
    std::uint8_t kind_length = 0;
    if (!get(in, record.X_WB.x) || !get(in, record.X_WB.y) || !get(in, record.X_WB.theta) || !get(in, kind_length) ||
        in.size() < kind_length) {
      return false;
    }
    record.kind.assign(in.substr(0, kind_length));
    in.remove_prefix(kind_length);
  } else {
    return false;
  }
  record.body.assign(in);
  return true;
}

}  // namespace

std::uint64_t message_fingerprint(std::string_view kind, std::string_view serialized) {
  return geometry::fnv1a(serialized, geometry::fnv1a(std::string_view("\0", 1), geometry::fnv1a(kind)));
}

std::optional<SyncPolicy> parse_sync_policy(const std::string& name) {
  if (name == "every") return SyncPolicy::kEvery;
  if (name == "batch") return SyncPolicy::kBatch;
  if (name == "none") return SyncPolicy::kNone;
  return std::nullopt;
}

JournalContents read_journal(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read journal " + file.string());
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  JournalContents contents;
  if (data.size() < kMagic.size()) {
    // A crash while the file was being created: nothing in it was ever acknowledged.
    contents.torn_tail = !data.empty();
    return contents;
  }
  if (std::string_view(data).substr(0, kMagic.size()) != kMagic) {
    throw JournalCorrupt("journal " + file.string() + " is corrupt at byte 0: not an occgeo journal (bad magic)");
  }
  std::size_t offset = kMagic.size();
  contents.valid_bytes = offset;
  // A torn write leaves the last record short, or zeros where the file was extended but not yet written; anything
  // else after a bad record means the damage is in the middle.
  const auto only_zeros_from = [&](std::size_t from) {
    return from >= data.size() ||
           std::all_of(data.begin() + static_cast<std::ptrdiff_t>(from), data.end(), [](char c) { return c == 0; });
  };
  const auto corrupt = [&](const std::string& what) {
    return JournalCorrupt("journal " + file.string() + " is corrupt at byte " + std::to_string(offset) + ": " + what +
                          " and more data follows, so the records after it cannot be trusted (restore the data "
                          "directory from a backup, or move the journal away to start without what it holds)");
  };
  while (offset < data.size()) {
    std::string_view rest = std::string_view(data).substr(offset);
    if (rest.size() < kFrameHeaderBytes) {
      contents.torn_tail = true;  // the crash cut the last record's header
      return contents;
    }
    const std::string_view header = rest.substr(0, kFrameHeaderBytes - 4);
    std::uint32_t length = 0;
    std::uint32_t payload_crc = 0;
    std::uint32_t header_crc = 0;
    get(rest, length);
    get(rest, payload_crc);
    get(rest, header_crc);
    if (crc_of(header) != header_crc || length > kMaxPayloadBytes) {
      if (only_zeros_from(offset)) {
        contents.torn_tail = true;
        return contents;
      }
      throw corrupt("a record header fails its checksum");
    }
    if (rest.size() < length) {
      contents.torn_tail = true;  // the crash cut the last record short
      return contents;
    }
    const std::string_view payload = rest.substr(0, length);
    const std::size_t record_end = offset + kFrameHeaderBytes + length;
    JournalRecord record;
    if (crc_of(payload) != payload_crc || !decode_payload(payload, record)) {
      if (only_zeros_from(record_end)) {
        contents.torn_tail = true;
        return contents;
      }
      throw corrupt("a record fails its checksum");
    }
    contents.records.push_back(std::move(record));
    offset = record_end;
    contents.valid_bytes = offset;
  }
  return contents;
}

WorldJournal::WorldJournal(std::filesystem::path file, SyncPolicy policy, std::chrono::microseconds batch_interval,
                           std::uint64_t next_lsn, std::uint64_t snapshot_lsn, metrics::Registry& metrics)
    : file_(std::move(file)),
      policy_(policy),
      batch_interval_(batch_interval),
      next_lsn_(next_lsn),
      written_lsn_(next_lsn - 1),
      durable_lsn_(next_lsn - 1),
      synced_lsn_(next_lsn - 1),
      snapshot_lsn_(snapshot_lsn),
      unsynced_records_(metrics.gauge("occgeo_journal_unsynced_records", world_label(file_),
                                      "Journal records written to the file that no fsync has covered yet")),
      unsynced_bytes_(metrics.gauge("occgeo_journal_unsynced_bytes", world_label(file_),
                                    "Journal bytes written to the file that no fsync has covered yet")),
      journal_bytes_(metrics.gauge("occgeo_journal_bytes", world_label(file_),
                                   "Size of the world's journal file (emptied by each snapshot)")),
      sync_seconds_(metrics.histogram("occgeo_journal_sync_seconds", world_label(file_),
                                      "Time one fdatasync of the world's journal took")) {
  // The fsyncs run on a thread of their own: the world's strand, which appends, also computes the robots' commands, and
  // must not wait for the disk (an fdatasync takes from a few hundred microseconds to tens of milliseconds).
  if (policy_ != SyncPolicy::kNone) sync_thread_ = std::thread([this] { sync_loop(); });
}

void WorldJournal::shut_down() {
  {
    const std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (sync_thread_.joinable()) sync_thread_.join();
  // Destroyed outside the lock: a callback's captures may own objects whose destructors come back here.
  std::vector<std::function<void(const std::string*)>> finished;
  std::vector<std::pair<std::uint64_t, std::function<void(const std::string*)>>> waiting;
  {
    const std::lock_guard lock(mutex_);
    finished.swap(finished_callbacks_);
    waiting.swap(waiting_);
  }
}

WorldJournal::~WorldJournal() {
  shut_down();
  if (fd_ >= 0) ::close(fd_);
}

std::string WorldJournal::open_locked() {
  std::error_code error;
  std::filesystem::create_directories(file_.parent_path(), error);
  if (error) return "cannot create the journal folder " + file_.parent_path().string() + ": " + error.message();
  const int fd = ::open(file_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return errno_text("cannot open the journal " + file_.string(), errno);
  const off_t size = ::lseek(fd, 0, SEEK_END);
  if (size < 0) {
    const int saved = errno;
    ::close(fd);
    return errno_text("cannot read the size of the journal " + file_.string(), saved);
  }
  fd_ = fd;
  end_ = static_cast<std::uint64_t>(size);
  synced_end_ = end_;  // what a previous run left is as durable as it will get
  if (end_ < kMagic.size()) {
    end_ = 0;
    if (::ftruncate(fd_, 0) != 0) return errno_text("cannot reset the journal " + file_.string(), errno);
    if (auto failure = write_locked(std::string(kMagic)); !failure.empty()) return failure;
    // The new file's directory entry must survive a crash too.
    if (const int dir = ::open(file_.parent_path().c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dir >= 0) {
      ::fsync(dir);
      ::close(dir);
    }
  }
  return {};
}

std::string WorldJournal::write_locked(const std::string& frame) {
  std::size_t done = 0;
  while (done < frame.size()) {
    const ssize_t n = ::pwrite(fd_, frame.data() + done, frame.size() - done, static_cast<off_t>(end_ + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int saved = n < 0 ? errno : ENOSPC;
      // Leave no partial record behind, or the next good one would sit after damage.
      if (::ftruncate(fd_, static_cast<off_t>(end_)) != 0) {
        failed_ = errno_text("the journal " + file_.string() + " could not be cut back after a failed write", errno);
      }
      return errno_text("cannot write the journal " + file_.string(), saved);
    }
    done += static_cast<std::size_t>(n);
  }
  end_ += frame.size();
  return {};
}

std::string WorldJournal::sync_locked_fd(int fd) const {
  const auto started = std::chrono::steady_clock::now();
  const int result = ::fdatasync(fd);
  const int saved = errno;
  sync_seconds_.observe(std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count());
  if (result != 0) return errno_text("cannot sync the journal " + file_.string(), saved);
  return {};
}

void WorldJournal::note_synced_locked(std::uint64_t lsn, std::uint64_t end) {
  synced_lsn_ = std::max(synced_lsn_, lsn);
  synced_end_ = std::max(synced_end_, end);
  update_lag_metrics_locked();
}

void WorldJournal::update_lag_metrics_locked() {
  unsynced_records_.set(static_cast<std::int64_t>(written_lsn_ - std::min(synced_lsn_, written_lsn_)));
  unsynced_bytes_.set(static_cast<std::int64_t>(end_ - std::min(synced_end_, end_)));
  journal_bytes_.set(static_cast<std::int64_t>(end_));
}

WorldJournal::AppendResult WorldJournal::append_sensor(const std::string& robot_id,
                                                       const std::shared_ptr<const void>& robot_spec_identity,
                                                       const google::protobuf::MessageLite& robot_spec,
                                                       const geometry::Pose2& X_WB, const std::string& kind,
                                                       const google::protobuf::MessageLite& message) {
  // Declared before the lock, so destroyed after it is released: on the appending thread, outside the lock.
  std::vector<std::function<void(const std::string*)>> finished;
  const std::lock_guard lock(mutex_);
  finished.swap(finished_callbacks_);
  if (!failed_.empty()) return {0, failed_};
  if (fd_ < 0) {
    if (auto failure = open_locked(); !failure.empty()) return {0, failure};
  }
  std::string frames;
  std::uint64_t lsn = next_lsn_;
  const auto spec_it = robots_in_file_.find(robot_id);
  const bool write_spec = spec_it == robots_in_file_.end() || spec_it->second != robot_spec_identity;
  if (write_spec) {
    std::string payload;
    put(payload, lsn++);
    put(payload, static_cast<std::uint8_t>(RecordType::kRobot));
    put(payload, static_cast<std::uint16_t>(robot_id.size()));
    payload += robot_id;
    payload += robot_spec.SerializeAsString();
    frames += frame_of(payload);
  }
  std::string payload;
  put(payload, lsn);
  put(payload, static_cast<std::uint8_t>(RecordType::kSensor));
  put(payload, static_cast<std::uint16_t>(robot_id.size()));
  payload += robot_id;
  put(payload, X_WB.x);
  put(payload, X_WB.y);
  put(payload, X_WB.theta);
  put(payload, static_cast<std::uint8_t>(kind.size()));
  payload += kind;
  const std::size_t message_offset = payload.size();
  payload += message.SerializeAsString();
  const std::uint64_t fingerprint = message_fingerprint(kind, std::string_view(payload).substr(message_offset));
  frames += frame_of(payload);

  if (auto failure = write_locked(frames); !failure.empty()) return {0, failure};
  if (write_spec) robots_in_file_[robot_id] = robot_spec_identity;
  next_lsn_ = lsn + 1;
  written_lsn_ = lsn;
  if (policy_ == SyncPolicy::kNone) durable_lsn_ = lsn;
  update_lag_metrics_locked();
  if (policy_ == SyncPolicy::kEvery) wake_.notify_all();
  return {lsn, {}, fingerprint};
}

void WorldJournal::when_durable(std::uint64_t lsn, std::function<void(const std::string* error)> done) {
  // Before anything else: when this record is already durable, the batch thread may still be calling back for
  // earlier ones (it found them durable in the same fsync); this callback waits its turn.
  const std::lock_guard in_order(completion_mutex_);
  {
    const std::lock_guard lock(mutex_);
    if (lsn > durable_lsn_) {
      waiting_.emplace_back(lsn, std::move(done));
      wake_.notify_all();
      return;
    }
  }
  done(nullptr);
}

void WorldJournal::complete(std::uint64_t up_to_lsn, const std::string* error) {
  const std::lock_guard in_order(completion_mutex_);
  std::vector<std::function<void(const std::string*)>> ready;
  {
    const std::lock_guard lock(mutex_);
    if (!error) durable_lsn_ = std::max(durable_lsn_, up_to_lsn);
    auto it = std::stable_partition(waiting_.begin(), waiting_.end(),
                                    [&](const auto& waiter) { return waiter.first > up_to_lsn; });
    for (auto moved = it; moved != waiting_.end(); ++moved) ready.push_back(std::move(moved->second));
    waiting_.erase(it, waiting_.end());
  }
  if (ready.empty()) return;
  for (auto& done : ready) done(error);
  const std::lock_guard lock(mutex_);
  std::move(ready.begin(), ready.end(), std::back_inserter(finished_callbacks_));
}

void WorldJournal::sync_loop() {
  std::unique_lock lock(mutex_);
  const bool every = policy_ == SyncPolicy::kEvery;
  while (true) {
    // `every` syncs whatever was written as soon as it was (records written during one fsync share the next);
    // `batch` waits for a record someone awaits, then lets the batch window gather more.
    // After a failed fsync nothing more is synced (every waiter is answered with the failure at once).
    const auto unsynced = [&] { return every && failed_.empty() && written_lsn_ > synced_lsn_; };
    wake_.wait(lock, [&] { return stopping_ || !waiting_.empty() || unsynced(); });
    if (stopping_ && waiting_.empty() && !unsynced()) return;
    if (!every && !stopping_) wake_.wait_for(lock, batch_interval_, [&] { return stopping_; });
    const std::uint64_t target = written_lsn_;
    const std::uint64_t target_end = end_;
    const int fd = fd_;
    std::string failure = failed_;
    lock.unlock();
    if (failure.empty() && fd >= 0) failure = sync_locked_fd(fd);
    if (!failure.empty()) {
      lock.lock();
      if (failed_.empty()) failed_ = failure + "; no further data is acknowledged until the server restarts";
      lock.unlock();
      complete(~std::uint64_t{0}, &failure);
    } else {
      complete(target, nullptr);
    }
    lock.lock();
    if (failure.empty()) note_synced_locked(target, target_end);
  }
}

void WorldJournal::compact() {
  std::uint64_t up_to = 0;
  {
    const std::lock_guard lock(mutex_);
    up_to = written_lsn_;
    snapshot_lsn_ = written_lsn_;
    robots_in_file_.clear();
    if (fd_ >= 0 && end_ > kMagic.size()) {
      if (::ftruncate(fd_, static_cast<off_t>(kMagic.size())) == 0) {
        end_ = kMagic.size();
        ::fdatasync(fd_);
      }
    }
    // The snapshot holds every record written so far, durably.
    synced_lsn_ = written_lsn_;
    synced_end_ = end_;
    update_lag_metrics_locked();
  }
  complete(up_to, nullptr);
}

static void add_delivered(WorldJournal::Delivered& delivered, const std::string& robot_id, std::uint64_t seq,
                          std::uint64_t fingerprint) {
  auto& seqs = delivered[robot_id];
  seqs[seq] = fingerprint;
  while (seqs.size() > WorldJournal::kDeliveredWindow) seqs.erase(seqs.begin());
}

void WorldJournal::note_delivered(const std::string& robot_id, std::uint64_t seq, std::uint64_t fingerprint) {
  const std::lock_guard lock(mutex_);
  add_delivered(delivered_, robot_id, seq, fingerprint);
}

bool WorldJournal::already_delivered(const std::string& robot_id, std::uint64_t seq, std::string_view kind,
                                     const google::protobuf::MessageLite& message) const {
  std::uint64_t remembered = 0;
  {
    const std::lock_guard lock(mutex_);
    const auto robot = delivered_.find(robot_id);
    if (robot == delivered_.end()) return false;
    const auto it = robot->second.find(seq);
    if (it == robot->second.end()) return false;
    remembered = it->second;
  }
  return remembered == message_fingerprint(kind, message.SerializeAsString());
}

WorldJournal::Delivered WorldJournal::delivered() const {
  const std::lock_guard lock(mutex_);
  return delivered_;
}

void WorldJournal::restore_delivered(Delivered delivered) {
  const std::lock_guard lock(mutex_);
  delivered_ = std::move(delivered);
}

std::uint64_t WorldJournal::last_lsn() const {
  const std::lock_guard lock(mutex_);
  return written_lsn_;
}

bool WorldJournal::changed_since_snapshot() const {
  const std::lock_guard lock(mutex_);
  return written_lsn_ > snapshot_lsn_;
}

std::uint64_t WorldJournal::size_bytes() const {
  const std::lock_guard lock(mutex_);
  return end_;
}

}  // namespace occgeo::service::durability
