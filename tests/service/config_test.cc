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

// docs/CONFIG.md lists every key with its default; loading that block must work and change nothing.
TEST(Config, TheDocumentedExampleLoadsAndEqualsTheDefaults) {
  std::ifstream doc(testing::source("docs/CONFIG.md"));
  ASSERT_TRUE(doc) << "docs/CONFIG.md is missing";
  std::string line;
  std::string yaml;
  bool inside = false;
  while (std::getline(doc, line)) {
    if (line == "```yaml") {
      inside = true;
    } else if (inside && line == "```") {
      break;
    } else if (inside) {
      yaml += line + "\n";
    }
  }
  ASSERT_FALSE(yaml.empty()) << "no yaml block in docs/CONFIG.md";
  testing::TempDir dir;
  const auto file = dir.path() / "occgeod.yaml";
  std::ofstream(file) << yaml;
  ServerConfig loaded;
  ASSERT_NO_THROW(loaded = load_config(file)) << load_error(yaml);
  const ServerConfig defaults;
  EXPECT_EQ(loaded.listen, defaults.listen);
  EXPECT_EQ(loaded.data_dir, defaults.data_dir);
  EXPECT_EQ(loaded.limits.max_frame_bytes, defaults.limits.max_frame_bytes);
  EXPECT_EQ(loaded.limits.max_octree_reply_bytes, defaults.limits.max_octree_reply_bytes);
  EXPECT_EQ(loaded.control.command_expiry_s, defaults.control.command_expiry_s);
  EXPECT_EQ(loaded.control.lease_timeout_s, defaults.control.lease_timeout_s);
  EXPECT_EQ(loaded.control.max_lease_timeout_s, defaults.control.max_lease_timeout_s);
  EXPECT_EQ(loaded.control.sensor_timeout_s, defaults.control.sensor_timeout_s);
  EXPECT_EQ(loaded.control.realtime_priority, defaults.control.realtime_priority);
  EXPECT_EQ(loaded.auth.operator_token, defaults.auth.operator_token);
  EXPECT_EQ(loaded.himm.increment, defaults.himm.increment);
  EXPECT_EQ(loaded.himm.tile_cells, defaults.himm.tile_cells);
  EXPECT_DOUBLE_EQ(loaded.bearcat.speed_per_degree_mps, defaults.bearcat.speed_per_degree_mps);
  EXPECT_EQ(loaded.bearcat.max_wheel_speed_mps, defaults.bearcat.max_wheel_speed_mps);
  EXPECT_EQ(loaded.ptem.params.cluster_distance_m, defaults.ptem.params.cluster_distance_m);
  EXPECT_EQ(loaded.octomap.resolution_m, defaults.octomap.resolution_m);
  EXPECT_EQ(loaded.octomap.clamping_min, defaults.octomap.clamping_min);
  EXPECT_EQ(loaded.distance_field.max_distance_m, defaults.distance_field.max_distance_m);
  EXPECT_EQ(loaded.sensors.max_insert_range_m, defaults.sensors.max_insert_range_m);
  EXPECT_EQ(loaded.sensors.max_free_range_m, defaults.sensors.max_free_range_m);
  EXPECT_EQ(loaded.sensors.no_return_clear_m, defaults.sensors.no_return_clear_m);
  EXPECT_EQ(loaded.queries.network_threads, defaults.queries.network_threads);
  EXPECT_EQ(loaded.queries.network_poll_us, defaults.queries.network_poll_us);
  EXPECT_EQ(loaded.queries.network_nice, defaults.queries.network_nice);
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

// YAML allows a mapping or a sequence as a key; a configuration key must be a name, and the refusal says where.
TEST(Config, KeysThatAreNotNamesAreRefusedNamingTheSection) {
  EXPECT_NE(load_error("ptem:\n ? constrtctio:\nsingl_esc").find("in 'ptem' is not a plain name"), std::string::npos);
  EXPECT_NE(load_error("? [a, b]\n: 1\n").find("at the top level is not a plain name"), std::string::npos);
}

TEST(Config, BadValuesNameTheField) {
  EXPECT_NE(load_error("himm:\n  cell_size_m: fast\n").find("himm.cell_size_m"), std::string::npos);
  EXPECT_NE(load_error("control:\n  command_expiry_s: -1\n").find("control.command_expiry_s"), std::string::npos);
  EXPECT_NE(load_error("himm:\n  cell_size_m: -0.1\n").find("cell_size_m"), std::string::npos);
  EXPECT_NE(load_error("listen: nowhere\n").find("listen"), std::string::npos);
}

TEST(Config, NetworkPollWindowIsReadAndChecked) {
  testing::TempDir dir;
  const auto file = dir.path() / "occgeod.yaml";
  std::ofstream(file) << "queries:\n  network_poll_us: 0\n";
  EXPECT_EQ(load_config(file).queries.network_poll_us, 0.0);
  EXPECT_EQ(ServerConfig{}.queries.network_poll_us, 200.0);
  EXPECT_NE(load_error("queries:\n  network_poll_us: -5\n").find("queries.network_poll_us"), std::string::npos);
  EXPECT_NE(load_error("queries:\n  network_poll_us: 1e6\n").find("queries.network_poll_us"), std::string::npos);
}

TEST(Config, NetworkNicenessIsReadAndChecked) {
  testing::TempDir dir;
  const auto file = dir.path() / "occgeod.yaml";
  std::ofstream(file) << "queries:\n  network_nice: 0\n";
  EXPECT_EQ(load_config(file).queries.network_nice, 0);
  EXPECT_EQ(ServerConfig{}.queries.network_nice, 5);
  EXPECT_NE(load_error("queries:\n  network_nice: -1\n").find("queries.network_nice"), std::string::npos);
  EXPECT_NE(load_error("queries:\n  network_nice: 20\n").find("queries.network_nice"), std::string::npos);
}

TEST(Config, RealtimePriorityIsReadAndChecked) {
  testing::TempDir dir;
  const auto file = dir.path() / "occgeod.yaml";
  std::ofstream(file) << "control:\n  realtime_priority: 0\n";
  EXPECT_EQ(load_config(file).control.realtime_priority, 0);
  EXPECT_EQ(ServerConfig{}.control.realtime_priority, 10);
  EXPECT_NE(load_error("control:\n  realtime_priority: -1\n").find("control.realtime_priority"), std::string::npos);
  EXPECT_NE(load_error("control:\n  realtime_priority: 100\n").find("control.realtime_priority"), std::string::npos);
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

TEST(Config, PtemSectionIsReadWithPerWorldOverrides) {
  const ServerConfig defaults;
  EXPECT_EQ(defaults.ptem.params.construction, mapping::PtemConstruction::kSingleScan);
  EXPECT_DOUBLE_EQ(defaults.ptem.params.cluster_distance_m, 0.381);
  EXPECT_DOUBLE_EQ(defaults.ptem.params.restricted_threshold, 0.04);
  EXPECT_EQ(defaults.limits.max_ptem_query_points, 100000U);
  testing::TempDir dir;
  const auto file = dir.path() / "occgeod.yaml";
  std::ofstream(file) << "ptem:\n"
                         "  construction: cumulative\n"
                         "  cluster_distance_m: 0.5\n"
                         "  initial_cluster_radius_m: 0.03\n"
                         "  restricted_threshold: 0.05\n"
                         "  first_cluster_sigma_m: 0.2\n"
                         "  worlds:\n"
                         "    lab: {construction: single_scan, max_cluster_radius_m: 0}\n"
                         "    yard: {cluster_distance_m: 0.9}\n"
                         "limits:\n  max_ptem_query_points: 10\n";
  const ServerConfig config = load_config(file);
  EXPECT_EQ(config.limits.max_ptem_query_points, 10U);
  const mapping::PtemParams base = config.ptem.params_for("elsewhere");
  EXPECT_EQ(base.construction, mapping::PtemConstruction::kCumulative);
  EXPECT_DOUBLE_EQ(base.cluster_distance_m, 0.5);
  EXPECT_DOUBLE_EQ(base.initial_cluster_radius_m, 0.03);
  EXPECT_DOUBLE_EQ(base.restricted_threshold, 0.05);
  ASSERT_TRUE(base.first_cluster_sigma_m);
  EXPECT_DOUBLE_EQ(*base.first_cluster_sigma_m, 0.2);
  const mapping::PtemParams lab = config.ptem.params_for("lab");
  EXPECT_EQ(lab.construction, mapping::PtemConstruction::kSingleScan);
  EXPECT_DOUBLE_EQ(lab.cluster_distance_m, 0.5);
  EXPECT_EQ(lab.max_cluster_radius_m, 0.0) << "the lab's clusters grow unbounded, as the seed's";
  EXPECT_DOUBLE_EQ(base.max_cluster_radius_m, 0.5) << "the others' stay bounded";
  const mapping::PtemParams yard = config.ptem.params_for("yard");
  EXPECT_EQ(yard.construction, mapping::PtemConstruction::kCumulative);
  EXPECT_DOUBLE_EQ(yard.cluster_distance_m, 0.9);
  EXPECT_FALSE(ServerConfig{}.ptem.params.first_cluster_sigma_m);
}

TEST(Config, PtemErrorsNameTheKey) {
  EXPECT_NE(load_error("ptem:\n  sigma: 1\n").find("'ptem.sigma'"), std::string::npos);
  EXPECT_NE(load_error("ptem:\n  worlds:\n    lab: {constructin: cumulative}\n").find("'ptem.worlds.lab.constructin'"),
            std::string::npos);
  EXPECT_NE(load_error("ptem:\n  construction: incremental\n").find("'ptem.construction'"), std::string::npos);
  EXPECT_NE(load_error("ptem:\n  worlds:\n    lab: {construction: both}\n").find("'ptem.worlds.lab.construction'"),
            std::string::npos);
  EXPECT_NE(load_error("ptem:\n  cluster_distance_m: -1\n").find("cluster_distance_m"), std::string::npos);
  EXPECT_NE(load_error("ptem:\n  restricted_threshold: many\n").find("ptem.restricted_threshold"), std::string::npos);
  EXPECT_NE(load_error("ptem:\n  worlds:\n    lab: {cluster_distance_m: -2}\n").find("ptem.worlds.lab"),
            std::string::npos);
  EXPECT_NE(load_error("ptem:\n  worlds:\n    lab: {max_cluster_radius_m: 0.1}\n").find("ptem.worlds.lab"),
            std::string::npos);
  EXPECT_NE(load_error("ptem:\n  worlds: [lab]\n").find("ptem.worlds"), std::string::npos);
  EXPECT_NE(load_error("limits:\n  max_ptem_query_points: 0\n").find("limits.max_ptem_query_points"),
            std::string::npos);
}

}  // namespace
}  // namespace occgeo::service
