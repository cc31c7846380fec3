// The world journal on its own: acknowledgements leave in record order under group commit, and the lag metrics.
#include "../../service/src/durability/journal.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

#include "../../service/src/metrics.h"
#include "../support/temp_dir.h"
#include "occgeo/v1/robot.pb.h"
#include "occgeo/v1/sensors.pb.h"

namespace occgeo::testing {
namespace {

using service::durability::SyncPolicy;
using service::durability::WorldJournal;

// Appends one small sensor record of robot "alpha"; returns its lsn.
std::uint64_t append_one(WorldJournal& journal, const std::shared_ptr<const void>& spec_identity, std::uint64_t seq) {
  v1::RobotSpec spec;
  v1::LaserScan scan;
  scan.set_seq(seq);
  scan.add_ranges(1.0F);
  const auto result = journal.append_sensor("alpha", spec_identity, spec, {0.0, 0.0, 0.0}, "laser_scan", scan);
  EXPECT_TRUE(result.error.empty()) << result.error;
  return result.lsn;
}

// A driver pipelines scans under `batch`: record 1 waits for the group commit, record 2 is appended before it ends.
// The batch thread's fsync covers both and it calls back for record 1 (slowly, as a thread preempted under load
// does); record 2 registers its callback only then, already durable. Its ack must still leave after record 1's: a
// driver waiting for each ack in turn skipped an overtaken one and waited forever.
TEST(JournalTest, BatchCallbacksRunInRecordOrderEvenWhenALaterRecordIsAlreadyDurable) {
  TempDir dir;
  service::metrics::Registry metrics;
  WorldJournal journal(dir.path() / "journal" / "ordering.journal", SyncPolicy::kBatch, std::chrono::milliseconds(2), 1,
                       0, metrics);
  const auto spec_identity = std::make_shared<int>(0);
  std::mutex order_mutex;
  std::vector<std::uint64_t> order;
  std::atomic<bool> first_callback_started{false};
  const auto record = [&](std::uint64_t lsn) {
    const std::lock_guard lock(order_mutex);
    order.push_back(lsn);
  };

  const std::uint64_t first = append_one(journal, spec_identity, 1);
  journal.when_durable(first, [&](const std::string* error) {
    EXPECT_EQ(error, nullptr);
    first_callback_started = true;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    record(first);
  });
  const std::uint64_t second = append_one(journal, spec_identity, 2);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (!first_callback_started && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_TRUE(first_callback_started) << "the group commit never called back";
  journal.when_durable(second, [&](const std::string* error) {
    EXPECT_EQ(error, nullptr);
    record(second);
  });
  const std::lock_guard lock(order_mutex);
  EXPECT_EQ(order, (std::vector<std::uint64_t>{first, second}));
}

// Many records pipelined from one thread while the batch thread commits: every callback runs once, in lsn order.
TEST(JournalTest, PipelinedBatchCallbacksAllRunInOrder) {
  TempDir dir;
  service::metrics::Registry metrics;
  WorldJournal journal(dir.path() / "journal" / "pipelined.journal", SyncPolicy::kBatch, std::chrono::microseconds(200),
                       1, 0, metrics);
  const auto spec_identity = std::make_shared<int>(0);
  std::mutex order_mutex;
  std::vector<std::uint64_t> order;
  std::vector<std::uint64_t> appended;
  for (std::uint64_t seq = 1; seq <= 300; ++seq) {
    const std::uint64_t lsn = append_one(journal, spec_identity, seq);
    appended.push_back(lsn);
    journal.when_durable(lsn, [&, lsn](const std::string* error) {
      EXPECT_EQ(error, nullptr);
      if (lsn % 7 == 0) std::this_thread::sleep_for(std::chrono::microseconds(300));
      const std::lock_guard lock(order_mutex);
      order.push_back(lsn);
    });
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (std::chrono::steady_clock::now() < deadline) {
    {
      const std::lock_guard lock(order_mutex);
      if (order.size() == appended.size()) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const std::lock_guard lock(order_mutex);
  EXPECT_EQ(order, appended);
}

// The lag metrics follow the file: under `none` nothing is synced until a snapshot compacts the journal; under `every`
// the sync thread leaves nothing unsynced once the acks are out, and each fsync is timed.
TEST(JournalTest, LagMetricsCountWhatNoFsyncCoveredYet) {
  TempDir dir;
  service::metrics::Registry metrics;
  {
    WorldJournal journal(dir.path() / "journal" / "lagnone.journal", SyncPolicy::kNone, std::chrono::milliseconds(5), 1,
                         0, metrics);
    const auto spec_identity = std::make_shared<int>(0);
    for (std::uint64_t seq = 1; seq <= 5; ++seq) append_one(journal, spec_identity, seq);
    // Five sensor records and the robot record before the first.
    EXPECT_EQ(metrics.gauge("occgeo_journal_unsynced_records", {{"world", "lagnone"}}).value(), 6);
    EXPECT_GT(metrics.gauge("occgeo_journal_unsynced_bytes", {{"world", "lagnone"}}).value(), 5 * 20);
    EXPECT_EQ(metrics.gauge("occgeo_journal_bytes", {{"world", "lagnone"}}).value(),
              static_cast<std::int64_t>(journal.size_bytes()));
    journal.compact();
    EXPECT_EQ(metrics.gauge("occgeo_journal_unsynced_records", {{"world", "lagnone"}}).value(), 0);
    EXPECT_EQ(metrics.gauge("occgeo_journal_unsynced_bytes", {{"world", "lagnone"}}).value(), 0);
  }
  {
    WorldJournal journal(dir.path() / "journal" / "lagevery.journal", SyncPolicy::kEvery, std::chrono::milliseconds(5),
                         1, 0, metrics);
    const auto spec_identity = std::make_shared<int>(0);
    auto& syncs = metrics.histogram("occgeo_journal_sync_seconds", {{"world", "lagevery"}});
    std::atomic<int> acked{0};
    std::atomic<bool> synced_before_every_ack{true};
    for (std::uint64_t seq = 1; seq <= 5; ++seq) {
      const std::uint64_t lsn = append_one(journal, spec_identity, seq);
      // The append returns without waiting for the disk (the sync thread does); the ack waits for an fsync.
      journal.when_durable(lsn, [&](const std::string* error) {
        EXPECT_EQ(error, nullptr);
        if (syncs.count() == 0) synced_before_every_ack = false;
        ++acked;
      });
    }
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (std::chrono::steady_clock::now() < deadline &&
           (acked < 5 || metrics.gauge("occgeo_journal_unsynced_records", {{"world", "lagevery"}}).value() != 0)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    EXPECT_EQ(acked, 5);
    EXPECT_TRUE(synced_before_every_ack);
    EXPECT_EQ(metrics.gauge("occgeo_journal_unsynced_records", {{"world", "lagevery"}}).value(), 0);
    EXPECT_EQ(metrics.gauge("occgeo_journal_unsynced_bytes", {{"world", "lagevery"}}).value(), 0);
    // Records written during one fsync share the next: at least one, at most one per record (and the robot record's).
    EXPECT_GE(syncs.count(), 1U);
    EXPECT_LE(syncs.count(), 6U);
  }
}

}  // namespace
}  // namespace occgeo::testing
