#include "occgeo/mapping/grid_snapshot.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <mutex>
#include <numbers>
#include <random>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "cell_printer.h"
#include "occgeo/mapping/himm_grid.h"

namespace occgeo::mapping {
namespace {

using geometry::CellIndex;
using Cells = std::vector<CellIndex>;

Eigen::Vector2d center(const HimmGrid& grid, int ix, int iy) { return grid.grid_geometry().center_of({ix, iy}); }

// Hits cell `to` `times` times with beams from cell `from`.
void hit(HimmGrid& grid, CellIndex from, CellIndex to, int times = 1) {
  for (int i = 0; i < times; ++i) grid.insert_ray(center(grid, from.ix, from.iy), center(grid, to.ix, to.iy), true);
}

Cells occupied_in(const geometry::OccupiedCellSource& source, CellIndex min, CellIndex max) {
  Cells cells;
  source.for_each_occupied(min, max, [&cells](const CellIndex& c) {
    cells.push_back(c);
    return true;
  });
  std::sort(cells.begin(), cells.end(),
            [](const CellIndex& a, const CellIndex& b) { return a.iy != b.iy ? a.iy < b.iy : a.ix < b.ix; });
  return cells;
}

TEST(GridSnapshotTest, SnapshotDoesNotChangeWhenTheGridDoes) {
  HimmGrid grid{HimmParams{}};
  hit(grid, {0, 2}, {4, 2});
  const std::shared_ptr<const GridSnapshot> before = grid.snapshot();
  hit(grid, {0, 2}, {4, 2});
  hit(grid, {4, 9}, {4, 5});
  EXPECT_EQ(before->certainty({4, 2}), 3);
  EXPECT_FALSE(before->observed({4, 7}));
  EXPECT_EQ(before->version(), 1U);
  EXPECT_EQ(grid.certainty({4, 2}), 6);
  EXPECT_TRUE(grid.observed({4, 7}));
  const std::shared_ptr<const GridSnapshot> after = grid.snapshot();
  EXPECT_EQ(after->certainty({4, 2}), 6);
  EXPECT_TRUE(after->occupied({4, 5}));
  EXPECT_EQ(after->version(), 3U);
}

TEST(GridSnapshotTest, WritesCopyOnlyTheSharedTilesTheyTouch) {
  HimmGrid grid{HimmParams{}};  // 64-cell tiles.
  hit(grid, {0, 2}, {4, 2});
  hit(grid, {200, 2}, {204, 2});
  ASSERT_EQ(grid.tile_count(), 2U);
  std::shared_ptr<const GridSnapshot> snapshot = grid.snapshot();
  EXPECT_EQ(grid.copied_tile_count(), 0U);

  hit(grid, {0, 2}, {4, 2});  // Tile (0, 0) only: it is copied, tile (3, 0) stays shared.
  EXPECT_EQ(grid.copied_tile_count(), 1U);
  hit(grid, {0, 2}, {4, 2});  // The copy belongs to the grid alone now.
  EXPECT_EQ(grid.copied_tile_count(), 1U);
  EXPECT_EQ(snapshot->certainty({4, 2}), 3);
  EXPECT_EQ(snapshot->certainty({204, 2}), 3);

  // The grid keeps what it last published, for its next snapshot to share chunk by chunk, so a tile of it is copied on
  // its first write even once every reader has let go; a tile written since then is written in place.
  snapshot.reset();
  hit(grid, {200, 2}, {204, 2});
  EXPECT_EQ(grid.copied_tile_count(), 2U);
  EXPECT_EQ(grid.certainty({204, 2}), 6);

  // The next snapshot has both writes; the one before it kept neither.
  snapshot = grid.snapshot();
  EXPECT_EQ(snapshot->certainty({4, 2}), 9);
  EXPECT_EQ(snapshot->certainty({204, 2}), 6);
  EXPECT_EQ(snapshot->tile_count(), 2U);
}

// Snapshots taken between batches of writes over many tiles, on both sides of the origin and across the table's chunks
// of 8 x 8 tiles, each keep exactly the cells of their moment, while later snapshots share what did not change.
TEST(GridSnapshotTest, EachSnapshotKeepsItsMomentAcrossManyTilesAndChunks) {
  HimmGrid grid{HimmParams{}};  // 64-cell tiles: the rays below span about 40 x 40 tiles
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> cell(-1300, 1300);
  struct Taken {
    std::shared_ptr<const GridSnapshot> snapshot;
    std::vector<std::uint8_t> cells;  // of the probes, when it was taken
  };
  // Every ray's end (a hit) and middle (cleared), drawn up front so that each snapshot is probed where any batch
  // writes, and random cells besides.
  constexpr int kBatches = 12, kRaysPerBatch = 40;
  std::vector<std::pair<CellIndex, CellIndex>> rays;
  std::vector<CellIndex> probes;
  for (int r = 0; r < kBatches * kRaysPerBatch; ++r) {
    const CellIndex from{cell(rng), cell(rng)}, to{cell(rng), cell(rng)};
    rays.emplace_back(from, to);
    probes.push_back(to);
    probes.push_back({(from.ix + to.ix) / 2, (from.iy + to.iy) / 2});
  }
  for (int i = 0; i < 1000; ++i) probes.push_back({cell(rng), cell(rng)});
  std::vector<Taken> taken;
  for (int batch = 0; batch < kBatches; ++batch) {
    for (int r = 0; r < kRaysPerBatch; ++r) {
      const auto& [from, to] = rays[static_cast<std::size_t>(batch * kRaysPerBatch + r)];
      hit(grid, from, to);
    }
    Taken now{grid.snapshot(), {}};
    for (const CellIndex& c : probes) now.cells.push_back(grid.certainty(c));
    EXPECT_EQ(now.snapshot->tile_count(), grid.tile_count());
    taken.push_back(std::move(now));
  }
  for (std::size_t t = 0; t < taken.size(); ++t) {
    for (std::size_t i = 0; i < probes.size(); ++i) {
      ASSERT_EQ(taken[t].snapshot->certainty(probes[i]), taken[t].cells[i])
          << "snapshot " << t << " at " << probes[i].ix << ", " << probes[i].iy;
    }
  }
  EXPECT_GT(taken.back().snapshot->tile_count(), 500U);
  // The probes saw the writes: every batch's ray ends hold a certainty in the last snapshot, one batch's in the first.
  const auto observed = [&](const Taken& t) {
    return std::count_if(t.cells.begin(), t.cells.end(), [](auto v) { return v > 0; });
  };
  EXPECT_GT(observed(taken.back()), 3 * observed(taken.front()));
}

TEST(GridSnapshotTest, SnapshotReportsTheGridsShape) {
  HimmParams params;
  params.cell_size_m = 0.05;
  params.occupied_threshold = 5;
  HimmGrid grid(params);
  hit(grid, {-3, -3}, {-6, -3}, 2);
  const std::shared_ptr<const GridSnapshot> snapshot = grid.snapshot();
  const geometry::OccupiedCellSource& source = *snapshot;
  EXPECT_DOUBLE_EQ(source.cell_size(), 0.05);
  EXPECT_EQ(snapshot->occupied_threshold(), 5);
  EXPECT_EQ(snapshot->tile_count(), 1U);
  EXPECT_EQ(snapshot->tile_bounds(), (CellBox{{-64, -64}, {-1, -1}}));
  EXPECT_EQ(snapshot->certainty({-6, -3}), 6);
  EXPECT_TRUE(snapshot->occupied({-6, -3}));
  EXPECT_FALSE(snapshot->occupied({-5, -3}));
  EXPECT_TRUE(snapshot->observed({-5, -3}));
  EXPECT_FALSE(snapshot->observed({-7, -3}));
  EXPECT_EQ(snapshot->certainty({1000, 1000}), 0);
}

TEST(GridSnapshotTest, ForEachOccupiedVisitsExactlyTheOccupiedCellsInTheBox) {
  HimmParams params;
  params.tile_cells = 8;
  HimmGrid grid(params);
  // Occupied cells in four tiles, on both sides of 0.
  hit(grid, {0, 0}, {5, 0});
  hit(grid, {0, 0}, {-9, 0});
  hit(grid, {0, 0}, {0, -12});
  hit(grid, {0, 0}, {0, 7});
  hit(grid, {0, 0}, {-3, 3});
  const std::shared_ptr<const GridSnapshot> snapshot = grid.snapshot();
  EXPECT_EQ(occupied_in(*snapshot, {-100, -100}, {100, 100}), (Cells{{0, -12}, {-9, 0}, {5, 0}, {-3, 3}, {0, 7}}));
  EXPECT_EQ(occupied_in(*snapshot, {-9, -1}, {4, 7}), (Cells{{-9, 0}, {-3, 3}, {0, 7}}));
  EXPECT_EQ(occupied_in(*snapshot, {-8, 1}, {5, 6}), (Cells{{-3, 3}}));
  EXPECT_EQ(occupied_in(*snapshot, {5, 0}, {5, 0}), (Cells{{5, 0}}));
  EXPECT_EQ(occupied_in(*snapshot, {6, 0}, {5, 0}), Cells{});  // An empty box.
  // A box far larger than the map takes the pass over all tiles; a large empty region none.
  EXPECT_EQ(occupied_in(*snapshot, {-2000000000, -2000000000}, {2000000000, 2000000000}).size(), 5U);
  EXPECT_EQ(occupied_in(*snapshot, {1000, 1000}, {5000, 5000}), Cells{});

  int visits = 0;
  snapshot->for_each_occupied({-100, -100}, {100, 100}, [&visits](const CellIndex&) { return ++visits < 2; });
  EXPECT_EQ(visits, 2);
}

TEST(GridSnapshotTest, WindowIsRowMajorFromTheMinimumCell) {
  HimmParams params;
  params.tile_cells = 4;
  HimmGrid grid(params);
  grid.insert_ray({-0.15, 0.05}, center(grid, 2, 0), true);  // Cells -2..1 cleared, 2 hit: across tiles -1 and 0.
  hit(grid, {-1, 3}, {-1, 1}, 2);
  constexpr std::uint8_t N = kUnobserved;
  EXPECT_EQ(grid.snapshot()->window({-3, -1}, 7, 4), (std::vector<std::uint8_t>{
                                                         N, N, N, N, N, N, N,  // iy = -1
                                                         N, 0, 0, 0, 0, 3, N,  // iy = 0
                                                         N, N, 6, N, N, N, N,  // iy = 1: 3 + 3, growth 6
                                                         N, N, 0, N, N, N, N,  // iy = 2
                                                     }));
  EXPECT_TRUE(grid.snapshot()->window({5, 5}, 0, 3).empty());
  EXPECT_THROW((void)grid.snapshot()->window({0, 0}, -1, 3), std::invalid_argument);
  EXPECT_THROW((void)grid.snapshot()->window({2147483000, 0}, 1000, 1), std::invalid_argument);
}

// The latest snapshot, handed from the writer to readers; the lock covers only the pointer swap, never the reads.
class PublishedSnapshot {
 public:
  explicit PublishedSnapshot(std::shared_ptr<const GridSnapshot> snapshot) : snapshot_(std::move(snapshot)) {}
  void store(std::shared_ptr<const GridSnapshot> snapshot) {
    const std::lock_guard lock(mutex_);
    snapshot_.swap(snapshot);
  }
  std::shared_ptr<const GridSnapshot> load() const {
    const std::lock_guard lock(mutex_);
    return snapshot_;
  }

 private:
  mutable std::mutex mutex_;
  std::shared_ptr<const GridSnapshot> snapshot_;
};

TEST(GridSnapshotTest, ReadersSeeConsistentSnapshotsWhileTheGridIngests) {
  HimmGrid grid{HimmParams{}};
  PublishedSnapshot published(grid.snapshot());
  std::atomic<bool> ingesting{true};
  constexpr int kScans = 300;

  std::thread writer([&] {
    std::vector<float> ranges(181);
    for (int scan = 0; scan < kScans; ++scan) {
      for (std::size_t i = 0; i < ranges.size(); ++i) {
        ranges[i] = 2.0F + static_cast<float>((static_cast<int>(i) + scan) % 40) * 0.1F;
      }
      const geometry::Pose2 X_WS{0.01 * scan, -0.005 * scan, 0.02 * scan};
      grid.insert_scan(X_WS, -std::numbers::pi_v<float> / 2, std::numbers::pi_v<float> / 180, ranges, 8.0F);
      published.store(grid.snapshot());
    }
    ingesting.store(false);
  });

  const auto read = [&] {
    std::uint64_t last_version = 0;
    int checked = 0;
    while (ingesting.load() || checked == 0) {
      const std::shared_ptr<const GridSnapshot> snapshot = published.load();
      EXPECT_GE(snapshot->version(), last_version);
      last_version = snapshot->version();
      const std::vector<std::uint8_t> first = snapshot->window({-80, -80}, 160, 160);
      std::size_t occupied = 0;
      snapshot->for_each_occupied({-80, -80}, {79, 79}, [&occupied](const CellIndex&) {
        ++occupied;
        return true;
      });
      const std::vector<std::uint8_t> second = snapshot->window({-80, -80}, 160, 160);
      ASSERT_EQ(first, second) << "snapshot changed while being read, version " << snapshot->version();
      std::size_t occupied_in_window = 0;
      for (const std::uint8_t value : first) occupied_in_window += value != kUnobserved && value >= 3;
      ASSERT_EQ(occupied, occupied_in_window);
      ++checked;
    }
  };
  std::thread reader_a(read);
  std::thread reader_b(read);
  writer.join();
  reader_a.join();
  reader_b.join();
  EXPECT_EQ(published.load()->version(), static_cast<std::uint64_t>(kScans));
}

// A reader that lets go of the only snapshot while the grid ingests: the grid then writes those tiles in place, and
// the reader's last reads must come before (the grid syncs with the snapshot's release through the tile's count).
TEST(GridSnapshotTest, GridWritesInPlaceOnlyAfterTheLastReaderLetsGo) {
  HimmGrid grid{HimmParams{}};
  std::vector<float> ranges(181, 3.0F);
  const auto insert_scan = [&](int scan) {
    const geometry::Pose2 X_WS{0.02 * (scan % 50), 0.0, 0.01 * scan};
    grid.insert_scan(X_WS, -std::numbers::pi_v<float> / 2, std::numbers::pi_v<float> / 180, ranges, 8.0F);
  };
  for (int round = 0; round < 40; ++round) {
    std::shared_ptr<const GridSnapshot> snapshot = grid.snapshot();
    const std::vector<std::uint8_t> expected = snapshot->window({-40, -40}, 80, 80);
    std::thread reader([snapshot = std::move(snapshot), &expected]() mutable {
      EXPECT_EQ(snapshot->window({-40, -40}, 80, 80), expected);
      snapshot.reset();
    });
    const std::uint64_t copied_before = grid.copied_tile_count();
    for (int scan = 0; scan < 20; ++scan) insert_scan(round * 20 + scan);
    reader.join();
    EXPECT_LE(grid.copied_tile_count() - copied_before, 4U);  // Each shared tile is copied at most once.
  }
}

}  // namespace
}  // namespace occgeo::mapping
