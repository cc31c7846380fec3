#include "occgeo/service/config.h"

#include <gtest/gtest.h>

#include <fstream>

#include "../support/process.h"

namespace occgeo::service {
namespace {

std::string load_error(const std::string& yaml) {
  testing::TempDir dir;
  const auto file = dir.path() / "occgeod.yaml";
  std::ofstream(file) << yaml;
  try {
    load_config(file);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(Config, DefaultsAreValidAndListenOnLoopback) {
  const ServerConfig config;
  EXPECT_NO_THROW(config.validate());
  EXPECT_EQ(config.listen, "127.0.0.1:7700");
  EXPECT_DOUBLE_EQ(config.himm.cell_size_m, 0.1);
}

TEST(Config, FileOverridesDefaults) {
  testing::TempDir dir;
  const auto file = dir.path() / "occgeod.yaml";
  std::ofstream(file) << "listen: 127.0.0.1:9000\nhimm:\n  cell_size_m: 0.05\nbearcat:\n  base_speed_mps: 0.3\n";
  const ServerConfig config = load_config(file);
  EXPECT_EQ(config.listen, "127.0.0.1:9000");
  EXPECT_DOUBLE_EQ(config.himm.cell_size_m, 0.05);
  EXPECT_DOUBLE_EQ(config.bearcat.base_speed_mps, 0.3);
}

TEST(Config, UnknownKeysAreErrorsNamingTheKey) {
  EXPECT_NE(load_error("himm:\n  cell_sise_m: 0.1\n").find("'himm.cell_sise_m'"), std::string::npos);
  EXPECT_NE(load_error("lisen: 1.2.3.4:5\n").find("'lisen'"), std::string::npos);
}

TEST(Config, BadValuesNameTheField) {
  EXPECT_NE(load_error("himm:\n  cell_size_m: fast\n").find("himm.cell_size_m"), std::string::npos);
  EXPECT_NE(load_error("control:\n  command_expiry_s: -1\n").find("control.command_expiry_s"), std::string::npos);
  EXPECT_NE(load_error("himm:\n  cell_size_m: -0.1\n").find("cell_size_m"), std::string::npos);
  EXPECT_NE(load_error("listen: nowhere\n").find("listen"), std::string::npos);
}

TEST(Config, PointCloudLimitIsReadCheckedAndSpelledExactly) {
  testing::TempDir dir;
  const auto file = dir.path() / "occgeod.yaml";
  std::ofstream(file) << "limits:\n  max_point_cloud_points: 5000\n";
  EXPECT_EQ(load_config(file).limits.max_point_cloud_points, 5000U);
  EXPECT_EQ(ServerConfig{}.limits.max_point_cloud_points, 200000U);
  EXPECT_NE(load_error("limits:\n  max_point_cloud_points: 0\n").find("limits.max_point_cloud_points"),
            std::string::npos);
  EXPECT_NE(load_error("limits:\n  max_pointcloud_points: 10\n").find("'limits.max_pointcloud_points'"),
            std::string::npos);
}

}  // namespace
}  // namespace occgeo::service
