#include "occgeo/mapping/distance_field.h"

#include <fcl/geometry/shape/box.h>
#include <fcl/narrowphase/distance.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <random>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "occgeo/mapfile/map_file.h"
#include "occgeo/mapping/himm_grid.h"

namespace occgeo::mapping {
namespace {

using geometry::CellIndex;

constexpr double kCell = 0.1;

// A world of width x height cells from cell (0, 0), each occupied or free.
struct World {
  int width;
  int height;
  std::vector<bool> occupied;

  World(int w, int h) : width(w), height(h), occupied(static_cast<std::size_t>(w) * h, false) {}
  std::vector<bool>::reference at(int x, int y) { return occupied[static_cast<std::size_t>(y) * width + x]; }

  // The world as a map_server image whose grey levels HimmGrid::from_image reads as certainty 15 or 0.
  [[nodiscard]] mapfile::OccupancyImage image() const {
    mapfile::OccupancyImage image;
    image.width = static_cast<std::uint32_t>(width);
    image.height = static_cast<std::uint32_t>(height);
    image.resolution = kCell;
    image.pixels.resize(occupied.size());
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        image.pixels[static_cast<std::size_t>(height - 1 - y) * width + x] =
            occupied[static_cast<std::size_t>(y) * width + x] ? 0 : 254;
      }
    }
    return image;
  }
  [[nodiscard]] std::shared_ptr<const GridSnapshot> snapshot() const {
    return HimmGrid::from_image(image(), HimmParams{}).snapshot();
  }
};

// Random occupied cells and boxes.
World random_world(std::mt19937& rng, int width, int height, int boxes, int singles) {
  World world(width, height);
  std::uniform_int_distribution<int> x_of(0, width - 1);
  std::uniform_int_distribution<int> y_of(0, height - 1);
  std::uniform_int_distribution<int> side(1, 12);
  for (int b = 0; b < boxes; ++b) {
    const int x0 = x_of(rng), y0 = y_of(rng), w = side(rng), h = side(rng);
    for (int y = y0; y < std::min(y0 + h, height); ++y) {
      for (int x = x0; x < std::min(x0 + w, width); ++x) world.at(x, y) = true;
    }
  }
  for (int s = 0; s < singles; ++s) world.at(x_of(rng), y_of(rng)) = true;
  return world;
}

// Distance from the centre of cell c to the nearest occupied cell's square by brute force, capped at cap; metres.
double brute_force_distance(const GridSnapshot& grid, const CellBox& box, const CellIndex& c, double cap) {
  double best = cap;
  grid.for_each_occupied(box.min, box.max, [&](const CellIndex& o) {
    const double dx = std::max(std::abs(c.ix - o.ix) - 0.5, 0.0) * kCell;
    const double dy = std::max(std::abs(c.iy - o.iy) - 0.5, 0.0) * kCell;
    best = std::min(best, std::hypot(dx, dy));
    return true;
  });
  return best;
}

// Every cell of the field against brute force.
void expect_field_exact(const DistanceFieldSnapshot& field) {
  const CellBox box = *field.bounds();
  const CellBox all = *field.grid().tile_bounds();
  int mismatches = 0;
  for (int iy = box.min.iy; iy <= box.max.iy; ++iy) {
    for (int ix = box.min.ix; ix <= box.max.ix; ++ix) {
      const double expected = brute_force_distance(field.grid(), all, {ix, iy}, field.max_distance());
      if (std::abs(field.distance({ix, iy}) - expected) > 1e-12 && ++mismatches < 5) {
        ADD_FAILURE() << "cell (" << ix << ", " << iy << "): field " << field.distance({ix, iy}) << ", brute force "
                      << expected;
      }
    }
  }
  EXPECT_EQ(mismatches, 0);
}

void expect_same_field(const DistanceFieldSnapshot& a, const DistanceFieldSnapshot& b) {
  ASSERT_EQ(a.bounds(), b.bounds());
  const CellBox box = *a.bounds();  // every cell beyond is at max_distance in both
  int mismatches = 0;
  for (int iy = box.min.iy; iy <= box.max.iy; ++iy) {
    for (int ix = box.min.ix; ix <= box.max.ix; ++ix) {
      if (a.distance({ix, iy}) != b.distance({ix, iy}) && ++mismatches < 5) {
        ADD_FAILURE() << "cell (" << ix << ", " << iy << "): " << a.distance({ix, iy}) << " vs "
                      << b.distance({ix, iy});
      }
    }
  }
  EXPECT_EQ(mismatches, 0);
}

TEST(DistanceFieldParamsTest, ValidationNamesTheField) {
  const auto message = [](DistanceFieldParams params) {
    try {
      params.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  DistanceFieldParams params;
  params.max_distance_m = 0.0;
  EXPECT_NE(message(params).find("max_distance_m"), std::string::npos) << message(params);
  params = {};
  params.max_distance_m = std::nan("");
  EXPECT_THROW(DistanceField{params}, std::invalid_argument);
  EXPECT_NO_THROW(DistanceFieldParams{}.validate());

  // Limits in cells are checked against the grid's cell size at the first update.
  params = {};
  params.max_distance_m = 500.0;  // 5000 cells of 0.1 m
  DistanceField field(params);
  try {
    static_cast<void>(field.update(World(4, 4).snapshot()));
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_distance_m"), std::string::npos) << e.what();
  }
  EXPECT_THROW(static_cast<void>(DistanceField(DistanceFieldParams{}).update(nullptr)), std::invalid_argument);
}

TEST(DistanceFieldTest, QueryValidationNamesTheField) {
  DistanceField field(DistanceFieldParams{});
  static_cast<void>(field.update(World(8, 8).snapshot()));
  const auto message = [&](const geometry::ClearanceRequest& request) {
    try {
      static_cast<void>(field.snapshot()->compute_clearance(request));
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  geometry::ClearanceRequest request;
  request.pose.x = std::nan("");
  EXPECT_EQ(message(request), "ClearanceRequest.pose must be finite");
  request = {};
  request.footprint = geometry::BoxFootprint{.length = -1.0};
  EXPECT_NE(message(request).find("ClearanceRequest.footprint.length"), std::string::npos);
  request = {};
  request.footprint = geometry::CylinderFootprint{.radius = 0.0};
  EXPECT_NE(message(request).find("ClearanceRequest.footprint.radius"), std::string::npos);
  request = {};
  request.max_distance_m = -1.0;
  EXPECT_NE(message(request).find("ClearanceRequest.max_distance_m"), std::string::npos);
}

TEST(DistanceFieldTest, EmptyGridHasNoBounds) {
  DistanceField field(DistanceFieldParams{});
  EXPECT_EQ(field.snapshot(), nullptr);
  static_cast<void>(field.update(HimmGrid(HimmParams{}).snapshot()));
  ASSERT_NE(field.snapshot(), nullptr);
  EXPECT_FALSE(field.snapshot()->bounds());
  EXPECT_EQ(field.snapshot()->distance({0, 0}), DistanceFieldParams{}.max_distance_m);
}

TEST(DistanceFieldTest, DistancesEqualBruteForce) {
  std::mt19937 rng(7);
  DistanceFieldParams params;
  params.max_distance_m = 1.5;
  for (int trial = 0; trial < 3; ++trial) {
    DistanceField field(params);
    static_cast<void>(field.update(random_world(rng, 70, 50, 8, 40).snapshot()));
    SCOPED_TRACE(trial);
    expect_field_exact(*field.snapshot());
  }
}

// Random insertions and deletions, fed incrementally, end where a field built from scratch on the same grid does, and
// where brute force does.
TEST(DistanceFieldTest, IncrementalUpdatesEqualFromScratch) {
  std::mt19937 rng(11);
  DistanceFieldParams params;
  params.max_distance_m = 2.0;
  World world = random_world(rng, 80, 60, 6, 30);
  DistanceField field(params);
  ASSERT_TRUE(field.update(world.snapshot()).rebuilt);
  std::uniform_int_distribution<int> x_of(0, world.width - 1);
  std::uniform_int_distribution<int> y_of(0, world.height - 1);
  std::uniform_int_distribution<int> count_of(1, 60);
  for (int step = 0; step < 30; ++step) {
    // Flip cells in a random window (insertions and deletions, both), sometimes in clumps.
    const int x0 = x_of(rng), y0 = y_of(rng);
    const CellBox touched{{std::max(x0 - 10, 0), std::max(y0 - 10, 0)},
                          {std::min(x0 + 10, world.width - 1), std::min(y0 + 10, world.height - 1)}};
    std::uniform_int_distribution<int> tx(touched.min.ix, touched.max.ix);
    std::uniform_int_distribution<int> ty(touched.min.iy, touched.max.iy);
    for (int n = count_of(rng); n > 0; --n) {
      auto cell = world.at(tx(rng), ty(rng));
      cell = !cell;
    }
    const auto grid = world.snapshot();
    const DistanceFieldUpdate update = field.update(grid, step % 3 == 0 ? std::nullopt : std::optional(touched));
    EXPECT_FALSE(update.rebuilt);
    DistanceField scratch(params);
    static_cast<void>(scratch.update(grid));
    SCOPED_TRACE(step);
    expect_same_field(*field.snapshot(), *scratch.snapshot());
  }
  expect_field_exact(*field.snapshot());
}

// Scans into a HimmGrid, the field fed only the box each scan can touch, agree with a rebuild after every scan.
TEST(DistanceFieldTest, FollowsHimmScans) {
  HimmGrid grid(HimmParams{});
  DistanceFieldParams params;
  params.max_distance_m = 1.0;
  DistanceField field(params);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> range(0.5F, 4.0F);
  std::size_t changed = 0;
  for (int scan = 0; scan < 40; ++scan) {
    const geometry::Pose2 X_WS{0.05 * scan, 0.02 * scan, 0.3 * scan};
    std::vector<float> ranges(91);
    for (float& r : ranges) r = range(rng);
    constexpr float kRangeMax = 4.5F;
    grid.insert_scan(X_WS, -std::numbers::pi_v<float> / 2, std::numbers::pi_v<float> / 90, ranges, kRangeMax);
    const geometry::GridGeometry cells(grid.params().cell_size_m);
    const double reach = static_cast<double>(kRangeMax) + grid.params().cell_size_m;
    const CellBox touched{cells.cell_of(X_WS.position() - Eigen::Vector2d::Constant(reach)),
                          cells.cell_of(X_WS.position() + Eigen::Vector2d::Constant(reach))};
    changed += field.update(grid.snapshot(), touched).changed_cells;
    EXPECT_EQ(field.snapshot()->version(), grid.version());
  }
  EXPECT_GT(changed, 0U);
  DistanceField scratch(params);
  static_cast<void>(scratch.update(grid.snapshot()));
  expect_same_field(*field.snapshot(), *scratch.snapshot());
}

TEST(DistanceFieldTest, OldSnapshotsStayUnchanged) {
  World world(30, 30);
  world.at(10, 10) = true;
  DistanceField field(DistanceFieldParams{});
  static_cast<void>(field.update(world.snapshot()));
  const auto before = field.snapshot();
  world.at(10, 10) = false;
  world.at(20, 20) = true;
  static_cast<void>(field.update(world.snapshot()));
  EXPECT_EQ(before->distance({10, 10}), 0.0);
  EXPECT_EQ(before->nearest_occupied({11, 11}), (CellIndex{10, 10}));
  EXPECT_EQ(field.snapshot()->nearest_occupied({11, 11}), (CellIndex{20, 20}));
}

// Grows the grid far in every direction: the field follows without a rebuild, exact everywhere, its older snapshots
// untouched, and its memory in blocks near what was seen.
TEST(DistanceFieldTest, FollowsGridGrowthWithoutRebuilding) {
  HimmGrid grid(HimmParams{});
  const auto hit = [&grid](double x, double y) {
    for (int i = 0; i < 3; ++i) grid.insert_ray({x - 0.5, y}, {x, y}, true);
  };
  hit(1.0, 1.0);
  DistanceFieldParams params;
  params.max_distance_m = 1.0;
  DistanceField field(params);
  EXPECT_TRUE(field.update(grid.snapshot()).rebuilt);
  const auto first = field.snapshot();
  for (const auto& [x, y] : {std::pair{1.2, 1.3}, {20.0, 1.0}, {-150.0, 3.0}, {400.0, -250.0}, {1.0, 900.0}}) {
    hit(x, y);
    const auto changed = grid.take_occupancy_changes();
    ASSERT_TRUE(changed.has_value());
    EXPECT_FALSE(field.update(grid.snapshot(), std::span<const CellIndex>(*changed)).rebuilt);
    EXPECT_EQ(field.snapshot()->distance(grid.grid_geometry().cell_of({x, y})), 0.0);
    EXPECT_EQ(field.snapshot()->distance(grid.grid_geometry().cell_of({x, y + 5.0})), 1.0);
  }
  EXPECT_EQ(first->distance(grid.grid_geometry().cell_of({20.0, 1.0})), 1.0);
  EXPECT_EQ(first->distance(grid.grid_geometry().cell_of({1.0, 1.0})), 0.0);
  // Clearance near a far obstacle comes from the field, within a cell of the exact answer.
  geometry::ClearanceRequest near_far;
  near_far.footprint = geometry::CylinderFootprint{.radius = 0.3};
  near_far.pose = {400.0, -249.2, 0.0};
  near_far.max_distance_m = 1.0;
  const auto snapshot = field.snapshot();
  const double exact = geometry::compute_clearance(near_far, snapshot->grid()).clearance_m;
  const double from_field = snapshot->compute_clearance(near_far).clearance_m;
  EXPECT_GE(from_field, exact - 1e-9);
  EXPECT_LE(from_field, exact + grid.params().cell_size_m);
}

// A map of obstacles every 10 m over 300 x 300 m, then one obstacle added: the new snapshot copies the few reference
// blocks the wavefront wrote and the chunks holding them, and shares the rest of the field with the previous snapshot.
// The first update (a rebuild) copies every block written.
TEST(DistanceFieldTest, AnUpdateCopiesWhatItChangedNotTheMap) {
  HimmGrid grid(HimmParams{});
  const auto hit = [&grid](double x, double y) {
    for (int i = 0; i < 3; ++i) grid.insert_ray({x - 0.5, y}, {x, y}, true);
  };
  for (double y = -150.0; y <= 150.0; y += 10.0) {
    for (double x = -150.0; x <= 150.0; x += 10.0) hit(x, y);
  }
  static_cast<void>(grid.take_occupancy_changes());
  DistanceFieldParams params;
  params.max_distance_m = 1.0;
  DistanceField field(params);
  const DistanceFieldUpdate built = field.update(grid.snapshot());
  ASSERT_TRUE(built.rebuilt);
  EXPECT_GE(built.copied_blocks, 31U * 31U);  // every obstacle's neighbourhood
  const auto before = field.snapshot();
  hit(3.0, 3.0);  // 3.2 m inside a block: its 1 m wavefront stays there
  const auto changed = grid.take_occupancy_changes();
  ASSERT_TRUE(changed.has_value());
  const DistanceFieldUpdate local = field.update(grid.snapshot(), std::span<const CellIndex>(*changed));
  EXPECT_FALSE(local.rebuilt);
  EXPECT_EQ(local.copied_blocks, 1U);
  EXPECT_EQ(local.copied_chunks, 1U);
  EXPECT_EQ(field.snapshot()->distance(grid.grid_geometry().cell_of({3.0, 3.0})), 0.0);
  EXPECT_EQ(before->distance(grid.grid_geometry().cell_of({3.0, 3.0})), 1.0);  // nothing within 1 m before
  // Far from the change, both snapshots read the same shared blocks.
  for (const auto& [x, y] : {std::pair{-150.0, -149.5}, {140.0, 140.3}, {-0.4, 0.0}}) {
    const CellIndex cell = grid.grid_geometry().cell_of({x, y});
    EXPECT_EQ(field.snapshot()->distance(cell), before->distance(cell)) << x << ", " << y;
    EXPECT_LT(before->distance(cell), 1.0) << x << ", " << y;
  }
  // An update that changes nothing copies nothing.
  const DistanceFieldUpdate idle = field.update(grid.snapshot(), std::span<const CellIndex>{});
  EXPECT_EQ(idle.copied_blocks, 0U);
  EXPECT_EQ(idle.copied_chunks, 0U);
}

// FCL's distance between the footprint box and the cell prisms near it (GST_INDEP: FCL 0.7's libccd GJK is off by up
// to 0.45 m for two boxes, its own GJK by up to 0.03 m; see geometry/src/collision.cc). 0 in contact.
double fcl_box_clearance(const geometry::BoxFootprint& box, const geometry::Pose2& pose, const GridSnapshot& grid,
                         double max_distance) {
  const fcl::Boxd footprint(box.length, box.width, box.height);
  fcl::Transform3d X_WF = fcl::Transform3d::Identity();
  X_WF.linear() = Eigen::AngleAxisd(pose.theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  X_WF.translation() << pose.x + box.center_x * std::cos(pose.theta), pose.y + box.center_x * std::sin(pose.theta),
      box.height / 2.0;
  const fcl::Boxd cell(kCell, kCell, box.height + 1.0);
  fcl::DistanceRequestd request;
  request.gjk_solver_type = fcl::GST_INDEP;
  const double reach = std::hypot(box.length / 2 + std::abs(box.center_x), box.width / 2) + max_distance;
  const geometry::GridGeometry cells(kCell);
  double best = max_distance;
  grid.for_each_occupied(cells.cell_of({pose.x - reach, pose.y - reach}),
                         cells.cell_of({pose.x + reach, pose.y + reach}), [&](const CellIndex& c) {
                           fcl::Transform3d X_WC = fcl::Transform3d::Identity();
                           X_WC.translation() << cells.center_of(c), box.height / 2.0;
                           fcl::DistanceResultd result;
                           fcl::distance(&footprint, X_WF, &cell, X_WC, request, result);
                           best = std::min(best, std::max(result.min_distance, 0.0));
                           return true;
                         });
  return best;
}

struct Agreement {
  int queries = 0;
  int fcl_queries = 0;
  double worst_over_exact = 0.0;
  double worst_vs_fcl = 0.0;
};

// A clearance request at a random pose inside [lo, hi]^2 with a reach of max_distance_m: a cylinder every fourth
// request (i % 4 == 3), else a box, 0.2 to 1.5 m across, its centre up to 0.3 m off base_link.
geometry::ClearanceRequest random_request(std::mt19937& rng, int i, double lo, double hi, double max_distance_m) {
  std::uniform_real_distribution<double> coordinate(lo, hi);
  std::uniform_real_distribution<double> angle(-std::numbers::pi, std::numbers::pi);
  std::uniform_real_distribution<double> size(0.2, 1.5);
  std::uniform_real_distribution<double> offset(-0.3, 0.3);
  geometry::ClearanceRequest request;
  request.pose = {coordinate(rng), coordinate(rng), angle(rng)};
  request.max_distance_m = max_distance_m;
  if (i % 4 == 3) {
    request.footprint = geometry::CylinderFootprint{.radius = size(rng) / 2.0};
  } else {
    request.footprint = geometry::BoxFootprint{.length = size(rng), .width = size(rng), .center_x = offset(rng)};
  }
  return request;
}

// Field clearance against the exact search on random poses and footprints inside [lo, hi]^2, and against FCL for
// boxes; the field may exceed the exact value by one cell at most and never be below it.
Agreement check_clearances(const DistanceFieldSnapshot& field, std::mt19937& rng, double lo, double hi, int poses) {
  Agreement agreement;
  for (int i = 0; i < poses; ++i) {
    const geometry::ClearanceRequest request = random_request(rng, i, lo, hi, 2.0);
    const geometry::ClearanceResult fast = field.compute_clearance(request);
    const geometry::ClearanceResult exact = geometry::compute_clearance(request, field.grid());
    ++agreement.queries;
    // Tolerance: one cell, the documented bound, plus rounding of the two closed forms.
    EXPECT_GE(fast.clearance_m, exact.clearance_m - 1e-9) << "pose " << i;
    EXPECT_LE(fast.clearance_m, exact.clearance_m + kCell + 1e-9) << "pose " << i;
    agreement.worst_over_exact = std::max(agreement.worst_over_exact, fast.clearance_m - exact.clearance_m);
    if (const auto* box = std::get_if<geometry::BoxFootprint>(&request.footprint)) {
      const double fcl = fcl_box_clearance(*box, request.pose, field.grid(), request.max_distance_m);
      ++agreement.fcl_queries;
      // One cell for the field plus FCL GST_INDEP's measured box-box error of 0.03 m.
      EXPECT_NEAR(fast.clearance_m, fcl, kCell + 0.03 + 1e-9) << "pose " << i;
      agreement.worst_vs_fcl = std::max(agreement.worst_vs_fcl, std::abs(fast.clearance_m - fcl));
    }
  }
  return agreement;
}

TEST(DistanceFieldClearanceTest, AgreesWithExactAndFclOnRandomWorld) {
  std::mt19937 rng(5);
  DistanceField field(DistanceFieldParams{});
  static_cast<void>(field.update(random_world(rng, 200, 200, 60, 300).snapshot()));
  const Agreement agreement = check_clearances(*field.snapshot(), rng, 1.0, 19.0, 1200);
  EXPECT_GE(agreement.fcl_queries, 800);
  RecordProperty("worst_over_exact_m", std::to_string(agreement.worst_over_exact));
  RecordProperty("worst_vs_fcl_m", std::to_string(agreement.worst_vs_fcl));
  RecordProperty("exact_fallbacks", std::to_string(field.snapshot()->exact_fallback_count()));
  // The exact check near the footprint settles the cases where the field's bounds are over a cell apart.
  EXPECT_LT(field.snapshot()->exact_fallback_count(), 600U);
}

TEST(DistanceFieldClearanceTest, AgreesWithExactAndFclOnOpenField) {
  const mapfile::OccupancyImage image =
      mapfile::read_map_yaml(std::string(OCCGEO_SOURCE_DIR) + "/clients/sim/worlds/open_field.yaml");
  const HimmGrid grid = HimmGrid::from_image(image, HimmParams{});
  DistanceField field(DistanceFieldParams{});
  static_cast<void>(field.update(grid.snapshot()));
  std::mt19937 rng(17);
  const Agreement agreement = check_clearances(*field.snapshot(), rng, -29.0, 29.0, 1200);
  RecordProperty("worst_over_exact_m", std::to_string(agreement.worst_over_exact));
  RecordProperty("worst_vs_fcl_m", std::to_string(agreement.worst_vs_fcl));
  RecordProperty("exact_fallbacks", std::to_string(field.snapshot()->exact_fallback_count()));
  EXPECT_LT(field.snapshot()->exact_fallback_count(), 600U);
}

// A reach shorter than the obstacles' distances, down to less than a cell, as an all-model query asks a later model
// (within the answer so far): what the field finds is never below the exact clearance and at most a cell above it,
// and when it finds nothing within the reach, the exact clearance is at least the reach less a cell.
TEST(DistanceFieldClearanceTest, AShortReachMissesNoObstacleMoreThanACellWithinIt) {
  std::mt19937 rng(31);
  DistanceField field(DistanceFieldParams{});
  static_cast<void>(field.update(random_world(rng, 200, 200, 60, 300).snapshot()));
  const DistanceFieldSnapshot& snapshot = *field.snapshot();
  std::uniform_real_distribution<double> reach(0.0, 0.6);
  int found = 0, missed_within_a_cell = 0;
  for (int i = 0; i < 2000; ++i) {
    const geometry::ClearanceRequest request = random_request(rng, i, 1.0, 19.0, reach(rng));
    const geometry::ClearanceResult fast = snapshot.compute_clearance(request);
    // The exact clearance without the cut, so that an obstacle just beyond the reach still shows its distance.
    geometry::ClearanceRequest unlimited = request;
    unlimited.max_distance_m = 2.0;
    const geometry::ClearanceResult exact = geometry::compute_clearance(unlimited, snapshot.grid());
    const double exact_m = exact.found ? exact.clearance_m : unlimited.max_distance_m;
    if (fast.found) {
      ++found;
      EXPECT_GE(fast.clearance_m, exact_m - 1e-9) << "pose " << i;
      EXPECT_LE(fast.clearance_m, exact_m + kCell + 1e-9) << "pose " << i;
      EXPECT_LE(fast.clearance_m, request.max_distance_m) << "pose " << i;
    } else {
      EXPECT_EQ(fast.clearance_m, request.max_distance_m) << "pose " << i;
      EXPECT_GE(exact_m, request.max_distance_m - kCell - 1e-9) << "pose " << i << ": an obstacle within the reach";
      missed_within_a_cell += exact_m <= request.max_distance_m ? 1 : 0;
    }
  }
  EXPECT_GT(found, 400);
  RecordProperty("not_found_within_a_cell_of_the_reach", std::to_string(missed_within_a_cell));
}

// Convex polygon footprints (3 to 10 vertices on a tilted ellipse, base_link possibly outside): the field's clearance
// is never below the exact search's and at most a cell above it, and contact is contact.
TEST(DistanceFieldClearanceTest, PolygonAgreesWithExactOnRandomWorld) {
  std::mt19937 rng(23);
  DistanceField field(DistanceFieldParams{});
  static_cast<void>(field.update(random_world(rng, 200, 200, 60, 300).snapshot()));
  const DistanceFieldSnapshot& snapshot = *field.snapshot();
  std::uniform_real_distribution<double> coordinate(1.0, 19.0), angle(-std::numbers::pi, std::numbers::pi);
  std::uniform_real_distribution<double> semi_axis(0.1, 0.7), offset(-0.3, 0.3);
  int in_contact = 0, apart = 0;
  for (int i = 0; i < 1000; ++i) {
    const int n = std::uniform_int_distribution<int>(3, 10)(rng);
    const double a = semi_axis(rng), b = semi_axis(rng), cx = offset(rng), cy = offset(rng), tilt = angle(rng);
    geometry::ConvexPolygonFootprint polygon{{}, 1.0};
    for (int k = 0; k < n; ++k) {
      // Evenly spread angles with a random phase: strictly convex in this order.
      const double t = tilt + 2.0 * std::numbers::pi * k / n;
      polygon.vertices_B.emplace_back(cx + a * std::cos(t), cy + b * std::sin(t));
    }
    geometry::ClearanceRequest request{polygon, {coordinate(rng), coordinate(rng), angle(rng)}, 2.0};
    const geometry::ClearanceResult fast = snapshot.compute_clearance(request);
    const geometry::ClearanceResult exact = geometry::compute_clearance(request, snapshot.grid());
    EXPECT_GE(fast.clearance_m, exact.clearance_m - 1e-9) << "pose " << i;
    EXPECT_LE(fast.clearance_m, exact.clearance_m + kCell + 1e-9) << "pose " << i;
    EXPECT_EQ(fast.clearance_m == 0.0, exact.clearance_m == 0.0) << "pose " << i;
    in_contact += exact.clearance_m == 0.0;
    apart += exact.found && exact.clearance_m > 0.0;
  }
  EXPECT_GT(in_contact, 100);
  EXPECT_GT(apart, 100);
}

TEST(DistanceFieldClearanceTest, ContactAndNothingInRange) {
  World world(40, 40);
  world.at(20, 20) = true;
  DistanceField field(DistanceFieldParams{});
  static_cast<void>(field.update(world.snapshot()));
  geometry::ClearanceRequest request;
  request.footprint = geometry::BoxFootprint{.length = 0.4, .width = 0.4};
  request.pose = {2.05, 2.05, 0.3};
  const geometry::ClearanceResult contact = field.snapshot()->compute_clearance(request);
  EXPECT_TRUE(contact.found);
  EXPECT_EQ(contact.clearance_m, 0.0);
  EXPECT_EQ(contact.nearest_cell, (CellIndex{20, 20}));
  request.pose = {0.5, 0.5, 0.0};
  request.max_distance_m = 0.5;
  const geometry::ClearanceResult none = field.snapshot()->compute_clearance(request);
  EXPECT_FALSE(none.found);
  EXPECT_EQ(none.clearance_m, 0.5);
  EXPECT_EQ(field.snapshot()->clearance_gradient(request), Eigen::Vector2d::Zero());
}

// A lookup reads the cells along the footprint's edge and only vouches for the cells inside (a free cell's distance
// clears its neighbours along the row), so an obstacle deep inside a large footprint, far from every edge cell, must
// still be contact; and large footprints at random poses among single-cell obstacles, the case where the inside is
// skipped most, agree with the exact search.
TEST(DistanceFieldClearanceTest, ObstaclesDeepInsideALargeFootprintAreContact) {
  World world(200, 200);
  world.at(100, 100) = true;
  DistanceField field(DistanceFieldParams{});
  static_cast<void>(field.update(world.snapshot()));
  for (const double theta : {0.0, 0.4, 1.2, 2.9}) {
    for (const geometry::Footprint& footprint :
         {geometry::Footprint{geometry::BoxFootprint{.length = 4.0, .width = 3.0}},
          geometry::Footprint{geometry::CylinderFootprint{.radius = 1.8}}}) {
      const geometry::ClearanceRequest request{footprint, {10.03, 9.98, theta}, 2.0};
      const geometry::ClearanceResult result = field.snapshot()->compute_clearance(request);
      EXPECT_TRUE(result.found) << theta;
      EXPECT_EQ(result.clearance_m, 0.0) << theta;
      EXPECT_EQ(result.nearest_cell, (CellIndex{100, 100})) << theta;
    }
  }
  std::mt19937 rng(41);
  World scattered(200, 200);
  std::uniform_int_distribution<int> cell(0, 199);
  for (int i = 0; i < 150; ++i) scattered.at(cell(rng), cell(rng)) = true;
  DistanceField scattered_field(DistanceFieldParams{});
  static_cast<void>(scattered_field.update(scattered.snapshot()));
  std::uniform_real_distribution<double> coordinate(3.0, 17.0), angle(-std::numbers::pi, std::numbers::pi),
      size(1.0, 4.0);
  int contacts = 0;
  for (int i = 0; i < 1000; ++i) {
    geometry::ClearanceRequest request;
    request.pose = {coordinate(rng), coordinate(rng), angle(rng)};
    request.max_distance_m = 2.0;
    if (i % 3 == 2) {
      request.footprint = geometry::CylinderFootprint{.radius = size(rng) / 2.0};
    } else {
      request.footprint = geometry::BoxFootprint{.length = size(rng), .width = size(rng)};
    }
    const geometry::ClearanceResult fast = scattered_field.snapshot()->compute_clearance(request);
    const geometry::ClearanceResult exact = geometry::compute_clearance(request, scattered_field.snapshot()->grid());
    EXPECT_GE(fast.clearance_m, exact.clearance_m - 1e-9) << "pose " << i;
    EXPECT_LE(fast.clearance_m, exact.clearance_m + kCell + 1e-9) << "pose " << i;
    EXPECT_EQ(fast.clearance_m == 0.0, exact.clearance_m == 0.0) << "pose " << i;
    contacts += exact.clearance_m == 0.0;
  }
  // Most of these footprints hold an obstacle: the case the inside's skipping has to get right.
  EXPECT_GT(contacts, 300);
}

// Moving the footprint a little along the gradient raises the exact clearance by about that much.
TEST(DistanceFieldClearanceTest, GradientPointsAwayFromTheNearestObstacle) {
  std::mt19937 rng(23);
  DistanceField field(DistanceFieldParams{});
  static_cast<void>(field.update(random_world(rng, 150, 150, 30, 100).snapshot()));
  const auto snapshot = field.snapshot();
  std::uniform_real_distribution<double> coordinate(1.0, 14.0);
  std::uniform_real_distribution<double> angle(-std::numbers::pi, std::numbers::pi);
  int tested = 0;
  int rising = 0;
  for (int i = 0; i < 500; ++i) {
    geometry::ClearanceRequest request;
    request.footprint = geometry::BoxFootprint{.length = 0.8, .width = 0.5, .center_x = 0.1};
    request.pose = {coordinate(rng), coordinate(rng), angle(rng)};
    request.max_distance_m = 2.0;
    const geometry::ClearanceResult here = geometry::compute_clearance(request, snapshot->grid());
    if (!here.found || here.clearance_m < 0.05 || here.clearance_m > 1.9) continue;
    const Eigen::Vector2d gradient = snapshot->clearance_gradient(request);
    EXPECT_NEAR(gradient.norm(), 1.0, 1e-9);
    constexpr double kStep = 0.01;
    request.pose.x += kStep * gradient.x();
    request.pose.y += kStep * gradient.y();
    const double there = geometry::compute_clearance(request, snapshot->grid()).clearance_m;
    ++tested;
    // The field's nearest cell may be a near-tie of the exact one, a cell away, whose direction still raises the
    // clearance, if not at the full rate.
    if (there - here.clearance_m > 0.5 * kStep) ++rising;
  }
  EXPECT_GT(tested, 100);
  EXPECT_GE(rising, tested * 9 / 10);
}

}  // namespace
}  // namespace occgeo::mapping

namespace occgeo::mapping {
namespace {

// Scans into a HimmGrid, the field fed only the grid's log of flipped cells (as the server feeds it), agree with brute
// force; and a snapshot taken earlier keeps its own distances while later updates change the shared field.
TEST(DistanceFieldTest, FollowsTheGridsLogOfFlippedCellsAndKeepsOlderSnapshotsIntact) {
  HimmGrid grid(HimmParams{});
  DistanceFieldParams params;
  params.max_distance_m = 1.0;
  DistanceField field(params);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> range(0.5F, 6.0F);
  std::shared_ptr<const DistanceFieldSnapshot> early;
  std::vector<double> early_distances;
  std::size_t changed = 0;
  for (int scan = 0; scan < 60; ++scan) {
    const geometry::Pose2 X_WS{0.07 * scan, -0.03 * scan, 0.41 * scan};
    std::vector<float> ranges(181);
    for (float& r : ranges) r = range(rng);
    grid.insert_scan(X_WS, -std::numbers::pi_v<float> / 2, std::numbers::pi_v<float> / 180, ranges, 5.5F);
    const auto flipped = grid.take_occupancy_changes();
    ASSERT_TRUE(flipped.has_value());
    changed += field.update(grid.snapshot(), std::span<const CellIndex>(*flipped)).changed_cells;
    if (scan == 20) {
      early = field.snapshot();
      const CellBox box = *early->bounds();
      for (int iy = box.min.iy; iy <= box.max.iy; ++iy) {
        for (int ix = box.min.ix; ix <= box.max.ix; ++ix) early_distances.push_back(early->distance({ix, iy}));
      }
    }
  }
  EXPECT_GT(changed, 0U);
  expect_field_exact(*field.snapshot());
  // The early snapshot still answers for its own grid version.
  const CellBox box = *early->bounds();
  std::size_t i = 0;
  for (int iy = box.min.iy; iy <= box.max.iy; ++iy) {
    for (int ix = box.min.ix; ix <= box.max.ix; ++ix) ASSERT_EQ(early->distance({ix, iy}), early_distances[i++]);
  }
  expect_field_exact(*early);
}

// The grid's log names every cell whose occupancy changed, and overflows to "compare everything" rather than growing
// without bound.
TEST(DistanceFieldTest, TheGridsLogNamesEveryFlippedCell) {
  HimmGrid grid(HimmParams{});
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> range(0.3F, 4.0F);
  const CellBox box{{-60, -60}, {60, 60}};
  const auto occupied_cells = [&] {
    std::vector<bool> cells;
    for (int iy = box.min.iy; iy <= box.max.iy; ++iy) {
      for (int ix = box.min.ix; ix <= box.max.ix; ++ix) cells.push_back(grid.occupied({ix, iy}));
    }
    return cells;
  };
  std::size_t flips = 0;
  for (int scan = 0; scan < 30; ++scan) {
    const std::vector<bool> before = occupied_cells();
    std::vector<float> ranges(91);
    for (float& r : ranges) r = range(rng);
    grid.insert_scan({0.0, 0.0, 0.2 * scan}, -1.5F, 1.5F * 2.0F / 90.0F, ranges, 3.8F);
    const std::vector<bool> after = occupied_cells();
    const auto logged = grid.take_occupancy_changes();
    ASSERT_TRUE(logged.has_value());
    std::size_t i = 0;
    for (int iy = box.min.iy; iy <= box.max.iy; ++iy) {
      for (int ix = box.min.ix; ix <= box.max.ix; ++ix, ++i) {
        if (before[i] == after[i]) continue;
        ++flips;
        EXPECT_NE(std::find(logged->begin(), logged->end(), CellIndex{ix, iy}), logged->end())
            << "cell (" << ix << ", " << iy << ") flipped but was not logged";
      }
    }
  }
  EXPECT_GT(flips, 0U);
  // A map loaded from an image larger than the log's bound says "compare everything".
  mapfile::OccupancyImage image;
  image.width = image.height = 1100;
  image.resolution = kCell;
  image.pixels.assign(static_cast<std::size_t>(image.width) * image.height, 0);
  HimmGrid loaded = HimmGrid::from_image(image, HimmParams{});
  EXPECT_FALSE(loaded.take_occupancy_changes().has_value());
  EXPECT_TRUE(loaded.take_occupancy_changes().has_value());
}

}  // namespace
}  // namespace occgeo::mapping
