// Nothing acknowledged is lost: the real occgeod killed with SIGKILL in the middle of ingest from two robots, a driver
// that vanishes in the middle of a frame, a journal that hits a file-size limit, and damaged journals. After each, the
// restarted server's grid is compared cell for cell with the grid a fresh server builds from exactly the scans that
// were acknowledged.
#include <gtest/gtest.h>

#include <zlib.h>

#include <array>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include "fault_support.h"

namespace occgeo::testing {
namespace {

// How many kill -9 repetitions to run: OCCGEO_KILL_REPETITIONS (the acceptance run uses 20), else a short CI form.
int kill_repetitions() {
  if (const char* text = std::getenv("OCCGEO_KILL_REPETITIONS")) return std::max(1, std::atoi(text));
  return 4;
}

// The scans a restarted server holds must be exactly the acknowledged ones, plus at most the one scan that was in
// flight when the server died (it may have become durable before its ack could be sent: the driver, not having the
// ack, resends it — at-least-once).
void expect_restored_equals_acknowledged(const std::filesystem::path& work, const ObservedCells& restored,
                                         std::vector<Step> acknowledged, const std::optional<Step>& in_flight,
                                         const std::string& context) {
  const ObservedCells expected = reference_cells(work / "reference-acked", acknowledged);
  const std::size_t differing = differing_cells(restored, expected);
  if (differing == 0) {
    std::cout << "[ kill -9 ] " << context << ": restored grid == grid of the acknowledged scans\n";
    return;
  }
  if (in_flight) {
    acknowledged.push_back(*in_flight);
    const ObservedCells with_in_flight = reference_cells(work / "reference-in-flight", acknowledged);
    const std::size_t differing_with = differing_cells(restored, with_in_flight);
    if (differing_with == 0) {
      std::cout << "[ kill -9 ] " << context
                << ": restored grid == grid of the acknowledged scans + the one in flight\n";
    }
    EXPECT_EQ(differing_with, 0U) << context << ": the restored grid matches neither the acknowledged scans ("
                                  << differing << " cells differ) nor them plus the scan in flight (" << differing_with
                                  << " cells differ)";
    return;
  }
  ADD_FAILURE() << context << ": " << differing << " cells of the restored grid differ from the grid of the "
                << acknowledged.size() << " acknowledged scans";
}

// The program's path, searched in PATH.
std::optional<std::string> find_program(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::string_view dirs = path ? path : "/usr/bin:/bin";
  while (!dirs.empty()) {
    const auto colon = dirs.find(':');
    const auto candidate = std::filesystem::path(dirs.substr(0, colon)) / name;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    dirs = colon == std::string_view::npos ? std::string_view{} : dirs.substr(colon + 1);
  }
  return std::nullopt;
}

TEST(KillDuringIngest, EveryAcknowledgedScanSurvivesAndNothingElse) {
  const int repetitions = kill_repetitions();
  for (int repetition = 0; repetition < repetitions; ++repetition) {
    SCOPED_TRACE("repetition " + std::to_string(repetition));
    TempDir dir;
    const auto data = dir.path() / "data";
    std::filesystem::create_directories(data);
    // Every other repetition also snapshots (and empties the journal) while the robots stream, so restores from a
    // snapshot plus a journal tail are killed in the middle too.
    const double snapshot_interval_s = repetition % 2 == 1 ? 0.2 : 0.0;
    const auto config = write_durability_config(dir.path(), "every", snapshot_interval_s);
    std::mt19937 random(static_cast<unsigned>(1000 + repetition));
    std::uniform_int_distribution<int> kill_after_ms(150, 900);

    std::vector<Step> acknowledged;
    std::optional<Step> in_flight;
    {
      FaultServer server(data, config);
      Drivers drivers(server.address());
      // The delay counts from the first ack: on a loaded machine starting up may take longer than the whole delay.
      std::atomic<bool> first_ack{false};
      std::thread killer([&server, &first_ack, delay = kill_after_ms(random)] {
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
        while (!first_ack && std::chrono::steady_clock::now() < deadline) {
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(delay));
        server.kill9();
      });
      bool alive = true;
      for (std::uint64_t i = 1; alive && i <= 5000; ++i) {
        for (int robot = 0; robot < 2 && alive; ++robot) {
          Step step = make_step(robot, i, random);
          const auto reply = drivers.send(step);
          if (!reply) {
            in_flight = std::move(step);
            alive = false;
            break;
          }
          if (!reply->has_scan_ack()) {
            server.kill9();
            killer.join();
            FAIL() << reply->DebugString();
          }
          acknowledged.push_back(std::move(step));
          first_ack = true;
        }
      }
      killer.join();
      ASSERT_FALSE(alive) << "the server was not killed";
    }
    ASSERT_GT(acknowledged.size(), 0U) << "the kill came before the first ack; the repetition proves nothing";

    const auto restart_started = std::chrono::steady_clock::now();
    FaultServer restarted(data, config, {}, "restarted");
    const double restart_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - restart_started).count();
    const ObservedCells restored = observed_cells(restarted.address());
    std::cout << "[ kill -9 ] repetition " << repetition << ": " << acknowledged.size() << " scans acknowledged, "
              << (in_flight ? 1 : 0) << " in flight, snapshot_interval_s " << snapshot_interval_s << ", restart "
              << restart_s * 1e3 << " ms, " << restored.size() << " observed cells\n";
    expect_restored_equals_acknowledged(dir.path(), restored, acknowledged, in_flight,
                                        "repetition " + std::to_string(repetition));
    restarted.terminate();
    if (::testing::Test::HasFailure()) {
      std::cout << restarted.log();
      return;
    }
  }
}

TEST(DriverDisconnect, MidFrameAppliesNothingOfThePartialFrameAndKeepsTheRest) {
  TempDir dir;
  const auto data = dir.path() / "data";
  std::filesystem::create_directories(data);
  const auto config = write_durability_config(dir.path(), "every", 0);
  std::mt19937 random(7);
  std::vector<Step> steps;
  for (std::uint64_t i = 1; i <= 4; ++i) steps.push_back(make_step(0, i, random));
  // The last scan is taken far from the others, so applying it would show.
  steps.back().odometry.mutable_odometry()->mutable_pose()->set_x(40.0);
  const std::vector<Step> acknowledged(steps.begin(), steps.end() - 1);

  FaultServer server(data, config);
  {
    RawDriver driver(server.port(), "alpha");
    for (const Step& step : acknowledged) {
      driver.send_bytes(proto::encode_frame(step.odometry));
      driver.send_bytes(proto::encode_frame(step.scan));
      const auto reply = driver.await_reply(step.scan.laser_scan().seq());
      ASSERT_TRUE(reply && reply->has_scan_ack()) << (reply ? reply->DebugString() : "no reply") << server.log();
    }
    driver.send_bytes(proto::encode_frame(steps.back().odometry));
    const std::string frame = proto::encode_frame(steps.back().scan);
    driver.send_bytes(frame.substr(0, frame.size() / 2));
    driver.close();
  }
  // A query after the disconnect is served after the partial frame was dropped (the session is gone).
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  ASSERT_TRUE(server.running()) << server.log();
  const ObservedCells expected = reference_cells(dir.path() / "reference-acked", acknowledged);
  EXPECT_EQ(differing_cells(observed_cells(server.address()), expected), 0U) << "the live grid changed";
  const ObservedCells with_partial = reference_cells(dir.path() / "reference-all", steps);
  ASSERT_GT(differing_cells(with_partial, expected), 0U) << "the partial scan would not have shown; test is void";

  // The robot is not left stuck: a new driver for it is accepted and acknowledged once the old one is gone.
  std::mt19937 other(8);
  const Step after_reconnect = make_step(0, 10, other);
  {
    Drivers drivers(server.address());
    const auto reply = drivers.send(after_reconnect);
    EXPECT_TRUE(reply && reply->has_scan_ack()) << server.log();
  }

  server.kill9();
  FaultServer restarted(data, config, {}, "restarted");
  const ObservedCells restored = observed_cells(restarted.address());
  std::vector<Step> all_acknowledged = acknowledged;
  all_acknowledged.push_back(after_reconnect);
  EXPECT_EQ(differing_cells(restored, reference_cells(dir.path() / "reference-restart", all_acknowledged)), 0U)
      << restarted.log();
}

TEST(DiskFull, TheServerReportsItAndAcknowledgesNothingItCouldNotWrite) {
  TempDir dir;
  const auto data = dir.path() / "data";
  std::filesystem::create_directories(data);
  const auto config = write_durability_config(dir.path(), "every", 0);
  // RLIMIT_FSIZE makes every write beyond 48 KiB fail with EFBIG, as a full disk fails with ENOSPC, without needing a
  // mount (the journal grows by about 1 KiB per scan).
  const std::optional<std::string> prlimit = find_program("prlimit");
  if (!prlimit) GTEST_SKIP() << "prlimit (util-linux) is not installed";
  const std::vector<std::string> limit = {*prlimit, "--fsize=49152", "--"};
  std::mt19937 random(11);
  std::vector<Step> acknowledged;
  {
    FaultServer server(data, config, limit);
    Drivers drivers(server.address());
    std::optional<v1::Error> first_error;
    std::uint64_t i = 1;
    for (; i <= 400 && !first_error; ++i) {
      Step step = make_step(0, i, random);
      const auto reply = drivers.send(step);
      ASSERT_TRUE(reply) << server.log();
      if (reply->has_error()) {
        first_error = reply->error();
      } else {
        acknowledged.push_back(std::move(step));
      }
    }
    ASSERT_TRUE(first_error) << "400 scans fitted under the limit; test is void";
    EXPECT_EQ(first_error->code(), v1::ERROR_INTERNAL);
    EXPECT_EQ(first_error->field(), "durability");
    EXPECT_NE(first_error->message().find("File too large"), std::string::npos) << first_error->message();
    EXPECT_NE(first_error->message().find("not acknowledged"), std::string::npos) << first_error->message();
    EXPECT_GT(acknowledged.size(), 10U);
    // While the disk stays full nothing more is acknowledged, and the server keeps serving.
    for (int more = 0; more < 3; ++more, ++i) {
      const auto reply = drivers.send(make_step(0, i, random));
      ASSERT_TRUE(reply) << server.log();
      EXPECT_TRUE(reply->has_error()) << reply->DebugString();
    }
    EXPECT_TRUE(server.running());
    EXPECT_NE(server.log().find("journal_write_failed"), std::string::npos);
    server.kill9();
  }
  FaultServer restarted(data, config, {}, "restarted");
  EXPECT_EQ(differing_cells(observed_cells(restarted.address()), reference_cells(dir.path() / "ref", acknowledged)), 0U)
      << restarted.log();
}

// Streams `count` steps of robot alpha and kills the server; returns the steps, all acknowledged.
std::vector<Step> stream_then_kill(const std::filesystem::path& data, const std::filesystem::path& config, int count) {
  std::vector<Step> steps;
  FaultServer server(data, config);
  Drivers drivers(server.address());
  std::mt19937 random(21);
  for (int i = 1; i <= count; ++i) {
    Step step = make_step(0, static_cast<std::uint64_t>(i), random);
    const auto reply = drivers.send(step);
    if (!reply || !reply->has_scan_ack()) throw std::runtime_error("a scan was not acknowledged: " + server.log());
    steps.push_back(std::move(step));
  }
  server.kill9();
  return steps;
}

TEST(DamagedJournal, ATornLastRecordIsCutOffWithAWarning) {
  TempDir dir;
  const auto data = dir.path() / "data";
  std::filesystem::create_directories(data);
  const auto config = write_durability_config(dir.path(), "every", 0);
  const auto steps = stream_then_kill(data, config, 6);
  const auto journal = data / "journal" / "default.journal";
  ASSERT_TRUE(std::filesystem::exists(journal));
  const auto good_size = std::filesystem::file_size(journal);
  {
    // What a crash in the middle of an append leaves: a whole record header (length, payload CRC, header CRC)
    // promising 800 payload bytes, of which only 100 made it.
    std::string torn(12, '\0');
    const std::uint32_t length = 800;
    const std::uint32_t payload_crc = 0x12345678;
    std::memcpy(torn.data(), &length, 4);
    std::memcpy(torn.data() + 4, &payload_crc, 4);
    const auto header_crc = static_cast<std::uint32_t>(crc32(0L, reinterpret_cast<const Bytef*>(torn.data()), 8));
    std::memcpy(torn.data() + 8, &header_crc, 4);
    torn += std::string(100, '\x42');
    std::ofstream out(journal, std::ios::binary | std::ios::app);
    out.write(torn.data(), static_cast<std::streamsize>(torn.size()));
  }
  FaultServer restarted(data, config, {}, "restarted");
  EXPECT_NE(restarted.log().find("journal_torn_tail_truncated"), std::string::npos) << restarted.log();
  EXPECT_EQ(std::filesystem::file_size(journal), good_size);
  EXPECT_EQ(differing_cells(observed_cells(restarted.address()), reference_cells(dir.path() / "ref", steps)), 0U);
}

TEST(DamagedJournal, DamageInTheMiddleStopsTheStartNamingTheFileAndOffset) {
  TempDir dir;
  const auto data = dir.path() / "data";
  std::filesystem::create_directories(data);
  const auto config = write_durability_config(dir.path(), "every", 0);
  stream_then_kill(data, config, 8);
  const auto journal = data / "journal" / "default.journal";
  {
    std::fstream file(journal, std::ios::binary | std::ios::in | std::ios::out);
    const auto middle = static_cast<std::streamoff>(std::filesystem::file_size(journal) / 2);
    file.seekg(middle);
    const char byte = static_cast<char>(file.get());
    file.seekp(middle);
    file.put(static_cast<char>(~byte));
  }
  try {
    FaultServer restarted(data, config, {}, "restarted");
    ADD_FAILURE() << "the server started on a journal damaged in its middle:\n" << restarted.log();
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(journal.string()), std::string::npos) << message;
    EXPECT_NE(message.find("corrupt at byte"), std::string::npos) << message;
  }
}

TEST(CleanShutdown, SnapshotsAndEmptiesTheJournal) {
  TempDir dir;
  const auto data = dir.path() / "data";
  std::filesystem::create_directories(data);
  const auto config = write_durability_config(dir.path(), "every", 0);
  std::mt19937 random(31);
  std::vector<Step> steps;
  {
    FaultServer server(data, config);
    Drivers drivers(server.address());
    for (std::uint64_t i = 1; i <= 10; ++i) {
      for (int robot = 0; robot < 2; ++robot) {
        steps.push_back(make_step(robot, i, random));
        const auto reply = drivers.send(steps.back());
        ASSERT_TRUE(reply && reply->has_scan_ack());
      }
    }
    EXPECT_EQ(server.terminate(), 0);
  }
  EXPECT_EQ(std::filesystem::file_size(data / "journal" / "default.journal"), 8U);  // the magic only
  EXPECT_TRUE(std::filesystem::exists(data / "worlds" / "default" / "snapshot.yaml"));
  FaultServer restarted(data, config, {}, "restarted");
  EXPECT_EQ(differing_cells(observed_cells(restarted.address()), reference_cells(dir.path() / "ref", steps)), 0U);
}

// The default world's PTEM clusters, bit for bit, with the scan count and the latest stamp.
struct PtemState {
  std::uint64_t scans = 0;
  double latest_stamp_s = 0.0;
  std::vector<std::array<double, 4>> clusters;  // centre x, y, radius, sigma
  std::vector<std::uint64_t> ages;
  bool operator==(const PtemState&) const = default;
};

PtemState ptem_state(const std::string& address) {
  auto query = open_query_session(address);
  v1::ClientMessage request;
  request.set_request_id(1);
  request.mutable_ptem()->set_include_clusters(true);
  const v1::PtemReply reply = query.call(request, 1).ptem();
  PtemState state{reply.scans(), reply.latest_stamp_s(), {}, {}};
  for (const auto& cluster : reply.clusters()) {
    state.clusters.push_back({cluster.center().x(), cluster.center().y(), cluster.radius_m(), cluster.sigma_m()});
    state.ages.push_back(cluster.age_scans());
  }
  return state;
}

// The PTEM is part of the snapshot: after a snapshot emptied the journal, a restart (kill -9, then a clean one) brings
// back exactly the clusters the server had, not only those the journal tail rebuilds.
TEST(PtemSnapshot, ClustersAfterRestartEqualThoseBefore) {
  TempDir dir;
  const auto data = dir.path() / "data";
  std::filesystem::create_directories(data);
  const auto config = write_durability_config(dir.path(), "every", 0.2);
  std::mt19937 random(11);
  PtemState before;
  {
    FaultServer server(data, config);
    Drivers drivers(server.address());
    std::uint64_t i = 1;
    const auto send_steps = [&](int count) {
      for (int k = 0; k < count; ++k, ++i) {
        for (int robot = 0; robot < 2; ++robot) {
          const auto reply = drivers.send(make_step(robot, i, random));
          ASSERT_TRUE(reply && reply->has_scan_ack()) << (reply ? reply->DebugString() : "no reply");
        }
      }
    };
    send_steps(30);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (server.log().find("\"world_saved\"") == std::string::npos && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ASSERT_NE(server.log().find("\"world_saved\""), std::string::npos) << "no snapshot was taken";
    send_steps(10);
    before = ptem_state(server.address());
    ASSERT_EQ(before.scans, 80U);
    ASSERT_FALSE(before.clusters.empty());
    server.kill9();
  }
  EXPECT_TRUE(std::filesystem::exists(data / "worlds" / "default" / "ptem.bin"));
  {
    FaultServer restarted(data, config, {}, "after-kill");
    EXPECT_TRUE(ptem_state(restarted.address()) == before) << "the PTEM after kill -9 differs";
    EXPECT_EQ(restarted.terminate(), 0);
  }
  FaultServer again(data, config, {}, "after-clean-stop");
  EXPECT_TRUE(ptem_state(again.address()) == before) << "the PTEM after a clean shutdown differs";
  EXPECT_NE(again.log().find("\"journal_records_replayed\":0"), std::string::npos)
      << "the clean shutdown should have left everything in the snapshot";
}

// A driver that lost its acks in a crash resends what it had not seen acknowledged: messages the journal (after
// kill -9) or the snapshot (after a clean stop) already holds are acknowledged again and not applied twice, so the
// map equals the one built from each scan once.
TEST(ResendAfterRestart, JournalledScansAreAcknowledgedAsDurableAndAppliedOnce) {
  TempDir dir;
  const auto data = dir.path() / "data";
  std::filesystem::create_directories(data);
  const auto config = write_durability_config(dir.path(), "every", 0);
  std::mt19937 random(21);
  std::vector<Step> steps;
  for (std::uint64_t i = 1; i <= 8; ++i) steps.push_back(make_step(0, i, random));
  // A resent scan's ack says it was a duplicate (durable, not applied again, answered by no command).
  const auto expect_ack = [](const std::optional<v1::ServerMessage>& reply, std::uint64_t seq, bool duplicate) {
    ASSERT_TRUE(reply) << "no reply to seq " << seq;
    ASSERT_TRUE(reply->has_scan_ack()) << reply->DebugString();
    EXPECT_EQ(reply->scan_ack().seq(), seq);
    EXPECT_EQ(reply->scan_ack().duplicate(), duplicate) << "seq " << seq;
  };
  {
    FaultServer server(data, config);
    Drivers drivers(server.address());
    for (std::size_t k = 0; k < 5; ++k) expect_ack(drivers.send(steps[k]), k + 1, false);
    server.kill9();
  }
  {
    FaultServer restarted(data, config, {}, "after-kill");
    Drivers drivers(restarted.address());
    // Scans 3-5 again (their acks "lost"), then the new scan 6.
    for (std::size_t k = 2; k < 6; ++k) expect_ack(drivers.send(steps[k]), k + 1, k < 5);
    EXPECT_EQ(differing_cells(observed_cells(restarted.address()),
                              reference_cells(dir.path() / "reference-6", {steps.begin(), steps.begin() + 6})),
              0U)
        << "a resent scan was applied twice (or a new one not at all)";
    EXPECT_EQ(restarted.terminate(), 0);
  }
  FaultServer again(data, config, {}, "after-clean-stop");
  Drivers drivers(again.address());
  // Now from the snapshot the clean stop wrote: scan 6 again, then 7 and 8.
  for (std::size_t k = 5; k < 8; ++k) expect_ack(drivers.send(steps[k]), k + 1, k == 5);
  EXPECT_EQ(differing_cells(observed_cells(again.address()), reference_cells(dir.path() / "reference-8", steps)), 0U)
      << "a resent scan was applied twice after the snapshot";
  // A scan with a journalled seq but other content is not the same message: it is refused as out of order.
  Step stale = make_step(0, 8, random);
  stale.scan.mutable_laser_scan()->set_stamp_s(stale.scan.laser_scan().stamp_s() + 0.01);
  stale.odometry.mutable_odometry()->set_stamp_s(stale.odometry.odometry().stamp_s() + 0.01);
  const auto refused = drivers.send(stale);
  ASSERT_TRUE(refused && refused->has_error()) << (refused ? refused->DebugString() : "no reply");
  EXPECT_EQ(refused->error().field(), "laser_scan.seq");
}

}  // namespace
}  // namespace occgeo::testing
