#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <utility>

#include "occgeo/geometry/pose.h"
#include "occgeo/sim/footprint_collision.h"
#include "occgeo/sim/presets.h"
#include "occgeo/sim/raycast.h"
#include "occgeo/sim/world.h"

namespace occgeo::sim {
namespace {

const std::filesystem::path kWorlds = std::filesystem::path(OCCGEO_SOURCE_DIR) / "clients" / "sim" / "worlds";

// A fresh folder under the test temp directory, removed by the fixture.
class WorldFile : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    folder_ = std::filesystem::path(::testing::TempDir()) / (std::string("occgeo_sim_") + test->name());
    std::filesystem::remove_all(folder_);
    std::filesystem::create_directories(folder_);
  }
  void TearDown() override { std::filesystem::remove_all(folder_); }

  std::filesystem::path write(const std::string& name, const std::string& bytes) const {
    const std::filesystem::path path = folder_ / name;
    std::ofstream(path, std::ios::binary) << bytes;
    return path;
  }

  std::filesystem::path folder_;
};

TEST_F(WorldFile, OccupiedPixelsAreObstaclesAndUnknownIsFree) {
  // 3 x 2 pixels, top row: occupied, free, unknown; bottom row: free, occupied, free.
  write("tiny.pgm", std::string("P5\n3 2\n255\n") + std::string("\x00\xfe\xcd\xfe\x00\xfe", 6));
  const auto yaml = write("tiny.yaml",
                          "image: tiny.pgm\nresolution: 0.5\norigin: [-1.0, 2.0, 0.0]\nnegate: 0\n"
                          "occupied_thresh: 0.65\nfree_thresh: 0.196\n");
  const World world = load_world(yaml);
  EXPECT_EQ(world.width(), 3);
  EXPECT_EQ(world.height(), 2);
  EXPECT_EQ(world.resolution_m(), 0.5);
  EXPECT_EQ(world.origin(), Eigen::Vector2d(-1.0, 2.0));
  EXPECT_TRUE(world.is_obstacle({0, 0}));
  EXPECT_FALSE(world.is_obstacle({1, 0}));
  EXPECT_FALSE(world.is_obstacle({2, 0})) << "unknown counts as free";
  EXPECT_FALSE(world.is_obstacle({0, 1}));
  EXPECT_TRUE(world.is_obstacle({1, 1}));
  // Pixel (1, 1) is the square x -0.5..0, y 2.0..2.5: a ray along y = 2.25 from x = -2 enters it at x = -0.5.
  const auto hit = cast_ray(world, {-2.0, 2.25}, {1.0, 0.0}, 8.0);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->distance_m, 1.5);
}

TEST_F(WorldFile, ErrorsNameTheFile) {
  const auto missing = folder_ / "missing.yaml";
  try {
    load_world(missing);
    FAIL() << "expected WorldError";
  } catch (const WorldError& error) {
    EXPECT_NE(std::string(error.what()).find("missing.yaml"), std::string::npos) << error.what();
  }
}

TEST(ShippedWorlds, OpenFieldIsSixtyMetresSquareWithAClearStart) {
  const World world = load_world(kWorlds / "open_field.yaml");
  EXPECT_EQ(world.width(), 600);
  EXPECT_EQ(world.height(), 600);
  EXPECT_EQ(world.resolution_m(), 0.1);
  EXPECT_EQ(world.origin(), Eigen::Vector2d(-30.0, -30.0));
  const RobotPreset& bearcat = *find_robot_preset("bearcat");
  EXPECT_FALSE(find_collision(world, bearcat.footprint, {0.0, 0.0, 0.0}));
  // The fence: 3 pixels thick on every side, free just inside.
  for (int i = 0; i < 3; ++i) {
    EXPECT_TRUE(world.is_obstacle({i, 300}));
    EXPECT_TRUE(world.is_obstacle({599 - i, 300}));
    EXPECT_TRUE(world.is_obstacle({300, i}));
    EXPECT_TRUE(world.is_obstacle({300, 599 - i}));
  }
  EXPECT_FALSE(world.is_obstacle({3, 300}));
  // Nothing within 4 m of the origin: every ray from it reaches at least 4 m.
  for (int degrees = 0; degrees < 360; ++degrees) {
    const double angle = degrees * M_PI / 180.0;
    EXPECT_FALSE(cast_ray(world, {0.0, 0.0}, {std::cos(angle), std::sin(angle)}, 4.0)) << degrees << "°";
  }
}

TEST(ShippedWorlds, CorridorStartsInsideFacingAlongIt) {
  const World world = load_world(kWorlds / "corridor.yaml");
  EXPECT_EQ(world.resolution_m(), 0.1);
  const RobotPreset& bearcat = *find_robot_preset("bearcat");
  EXPECT_FALSE(find_collision(world, bearcat.footprint, {0.0, 0.0, 0.0}));
  // Ahead (+x) the corridor runs to the bend's far wall at x = 25; behind, the closed end is at x = -2.
  const auto ahead = cast_ray(world, {0.0, 0.0}, {1.0, 0.0}, 100.0);
  ASSERT_TRUE(ahead);
  EXPECT_NEAR(ahead->distance_m, 25.0, 1e-9);
  const auto behind = cast_ray(world, {0.0, 0.0}, {-1.0, 0.0}, 100.0);
  ASSERT_TRUE(behind);
  EXPECT_NEAR(behind->distance_m, 2.0, 1e-9);
  // Walls 1.5 m to either side.
  const auto left = cast_ray(world, {0.0, 0.0}, {0.0, 1.0}, 100.0);
  ASSERT_TRUE(left);
  EXPECT_NEAR(left->distance_m, 1.5, 1e-9);
  const auto right = cast_ray(world, {0.0, 0.0}, {0.0, -1.0}, 100.0);
  ASSERT_TRUE(right);
  EXPECT_NEAR(right->distance_m, 1.5, 1e-9);
}

TEST(ShippedWorlds, RoomIsTenByEightMetresWithAClearCentre) {
  const World world = load_world(kWorlds / "room.yaml");
  EXPECT_EQ(world.resolution_m(), 0.1);
  EXPECT_EQ(world.width(), 104);
  EXPECT_EQ(world.height(), 84);
  for (const RobotPreset& preset : robot_presets()) {
    EXPECT_FALSE(find_collision(world, preset.footprint, {0.0, 0.0, 0.0})) << preset.name;
  }
  // The inside of the walls is x -5..5, y -4..4; along the axes nothing stands between the centre and the walls.
  const std::vector<std::pair<Eigen::Vector2d, double>> walls = {
      {{1.0, 0.0}, 5.0}, {{-1.0, 0.0}, 5.0}, {{0.0, 1.0}, 4.0}, {{0.0, -1.0}, 4.0}};
  for (const auto& [direction, distance_m] : walls) {
    const auto hit = cast_ray(world, {0.0, 0.0}, direction, 100.0);
    ASSERT_TRUE(hit);
    EXPECT_NEAR(hit->distance_m, distance_m, 1e-9);
  }
  // Nothing within 1.9 m of the centre: a ring of rays that far sees no obstacle.
  for (int k = 0; k < 360; ++k) {
    const double angle = k * std::numbers::pi / 180.0;
    EXPECT_FALSE(cast_ray(world, {0.0, 0.0}, {std::cos(angle), std::sin(angle)}, 1.9)) << k << " deg";
  }
}

}  // namespace
}  // namespace occgeo::sim
