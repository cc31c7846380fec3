// GET /metrics on the real server: the body must parse as Prometheus text exposition format 0.0.4 (checked strictly
// by a parser written here), and the counters must move by exactly what the simulator and a query client did.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <regex>
#include <set>
#include <thread>

#include "../support/http_get.h"
#include "../support/process.h"
#include "test_clients.h"

namespace occgeo::testing {
namespace {

// One sample line: name{labels} value.
struct Sample {
  std::string name;
  std::map<std::string, std::string> labels;
  double value = 0.0;
};

// A strict reader of the text exposition format: every line is a HELP, a TYPE or a sample; names and label names
// are valid; label values are quoted with only \\, \" and \n escapes; TYPE comes before its samples and at most once;
// samples of a family are contiguous; a histogram's buckets are cumulative, end in le="+Inf", and equal _count.
class Exposition {
 public:
  explicit Exposition(const std::string& text) {
    std::istringstream in(text);
    std::string line;
    int number = 0;
    std::string current_family;
    std::set<std::string> finished_families;
    while (std::getline(in, line)) {
      ++number;
      const std::string where = "line " + std::to_string(number) + " '" + line + "'";
      if (line.empty()) continue;
      if (line.rfind("# HELP ", 0) == 0 || line.rfind("# TYPE ", 0) == 0) {
        const bool is_type = line[2] == 'T';
        const std::string rest = line.substr(7);
        const auto space = rest.find(' ');
        if (space == std::string::npos) throw std::runtime_error(where + ": HELP/TYPE without text");
        const std::string name = rest.substr(0, space);
        if (!valid_name(name)) throw std::runtime_error(where + ": invalid metric name");
        if (is_type) {
          const std::string type = rest.substr(space + 1);
          if (type != "counter" && type != "gauge" && type != "histogram" && type != "summary" && type != "untyped") {
            throw std::runtime_error(where + ": unknown type");
          }
          if (types.count(name)) throw std::runtime_error(where + ": second TYPE for " + name);
          types[name] = type;
        } else {
          help[name] = rest.substr(space + 1);
        }
        continue;
      }
      if (line[0] == '#') continue;  // other comments are allowed
      Sample sample = parse_sample(line, where);
      const std::string family = family_of(sample.name);
      if (family != current_family) {
        if (finished_families.count(family)) throw std::runtime_error(where + ": family " + family + " is split");
        if (!current_family.empty()) finished_families.insert(current_family);
        current_family = family;
      }
      if (!types.count(family)) throw std::runtime_error(where + ": sample before its TYPE line");
      samples.push_back(std::move(sample));
    }
    check_histograms();
  }

  // The value of the sample with this name and exactly these labels; nullopt when absent.
  [[nodiscard]] std::optional<double> value(const std::string& name,
                                            const std::map<std::string, std::string>& labels = {}) const {
    for (const auto& sample : samples) {
      if (sample.name == name && sample.labels == labels) return sample.value;
    }
    return std::nullopt;
  }

  std::map<std::string, std::string> types;
  std::map<std::string, std::string> help;
  std::vector<Sample> samples;

 private:
  static bool valid_name(const std::string& name) {
    static const std::regex pattern("[a-zA-Z_:][a-zA-Z0-9_:]*");
    return std::regex_match(name, pattern);
  }

  // A histogram's samples belong to the family without _bucket/_sum/_count.
  [[nodiscard]] std::string family_of(const std::string& name) const {
    for (const std::string suffix : {"_bucket", "_sum", "_count"}) {
      if (name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
        const std::string base = name.substr(0, name.size() - suffix.size());
        if (types.count(base) && types.at(base) == "histogram") return base;
      }
    }
    return name;
  }

  static Sample parse_sample(const std::string& line, const std::string& where) {
    Sample sample;
    std::size_t at = 0;
    while (at < line.size() && line[at] != '{' && line[at] != ' ') ++at;
    sample.name = line.substr(0, at);
    if (!valid_name(sample.name)) throw std::runtime_error(where + ": invalid sample name");
    if (at < line.size() && line[at] == '{') {
      ++at;
      while (at < line.size() && line[at] != '}') {
        const auto equals = line.find('=', at);
        if (equals == std::string::npos) throw std::runtime_error(where + ": label without '='");
        const std::string label = line.substr(at, equals - at);
        if (!std::regex_match(label, std::regex("[a-zA-Z_][a-zA-Z0-9_]*"))) {
          throw std::runtime_error(where + ": invalid label name '" + label + "'");
        }
        at = equals + 1;
        if (at >= line.size() || line[at] != '"') throw std::runtime_error(where + ": label value not quoted");
        ++at;
        std::string value;
        while (at < line.size() && line[at] != '"') {
          if (line[at] == '\\') {
            ++at;
            if (at >= line.size()) throw std::runtime_error(where + ": dangling escape");
            if (line[at] == 'n') {
              value += '\n';
            } else if (line[at] == '\\' || line[at] == '"') {
              value += line[at];
            } else {
              throw std::runtime_error(where + ": invalid escape");
            }
          } else {
            value += line[at];
          }
          ++at;
        }
        if (at >= line.size()) throw std::runtime_error(where + ": unterminated label value");
        ++at;
        if (sample.labels.count(label)) throw std::runtime_error(where + ": label " + label + " twice");
        sample.labels[label] = value;
        if (at < line.size() && line[at] == ',') ++at;
      }
      if (at >= line.size()) throw std::runtime_error(where + ": unterminated label set");
      ++at;
    }
    if (at >= line.size() || line[at] != ' ') throw std::runtime_error(where + ": no space before the value");
    const std::string value_text = line.substr(at + 1);
    if (value_text == "+Inf") {
      sample.value = HUGE_VAL;
    } else if (value_text == "-Inf") {
      sample.value = -HUGE_VAL;
    } else {
      std::size_t used = 0;
      sample.value = std::stod(value_text, &used);
      if (used != value_text.size()) throw std::runtime_error(where + ": value is not a number (or has a timestamp)");
    }
    return sample;
  }

  void check_histograms() const {
    for (const auto& [family, type] : types) {
      if (type != "histogram") continue;
      // Group buckets by their labels without le.
      std::map<std::map<std::string, std::string>, std::vector<std::pair<double, double>>> buckets;
      for (const auto& sample : samples) {
        if (sample.name != family + "_bucket") continue;
        auto labels = sample.labels;
        if (!labels.count("le")) throw std::runtime_error(family + ": bucket without le");
        const std::string le = labels["le"];
        labels.erase("le");
        buckets[labels].emplace_back(le == "+Inf" ? HUGE_VAL : std::stod(le), sample.value);
      }
      for (const auto& [labels, series] : buckets) {
        for (std::size_t i = 1; i < series.size(); ++i) {
          if (!(series[i].first > series[i - 1].first)) throw std::runtime_error(family + ": le not increasing");
          if (series[i].second < series[i - 1].second) throw std::runtime_error(family + ": buckets not cumulative");
        }
        if (series.empty() || !std::isinf(series.back().first)) throw std::runtime_error(family + ": no +Inf bucket");
        const auto count = value(family + "_count", labels);
        const auto sum = value(family + "_sum", labels);
        if (!count || !sum) throw std::runtime_error(family + ": _count or _sum missing");
        if (*count != series.back().second) throw std::runtime_error(family + ": _count differs from +Inf bucket");
      }
    }
  }
};

TEST(ExpositionParser, RejectsWhatPrometheusWouldReject) {
  EXPECT_NO_THROW(Exposition("# HELP a_total x\n# TYPE a_total counter\na_total{k=\"v\\\"\"} 3\n"));
  EXPECT_THROW(Exposition("a_total 3\n"), std::runtime_error);                   // no TYPE
  EXPECT_THROW(Exposition("# TYPE a counter\na{k=v} 3\n"), std::runtime_error);  // unquoted
  EXPECT_THROW(Exposition("# TYPE a counter\na 3x\n"), std::runtime_error);      // bad value
  EXPECT_THROW(Exposition("# TYPE h histogram\nh_bucket{le=\"1\"} 2\nh_bucket{le=\"+Inf\"} 1\nh_sum 1\nh_count 1\n"),
               std::runtime_error);  // not cumulative
  EXPECT_THROW(Exposition("# TYPE h histogram\nh_bucket{le=\"1\"} 1\nh_sum 1\nh_count 1\n"), std::runtime_error);
}

class MetricsEndpoint : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<ServerProcess>(dir_.path(), std::vector<std::string>{"--http", "127.0.0.1:0"});
    port_ = http_port(*server_);
  }

  Exposition scrape() {
    const HttpResult result = http_get(port_, "/metrics");
    EXPECT_EQ(result.status, 200u);
    EXPECT_EQ(result.content_type, "text/plain; version=0.0.4; charset=utf-8");
    return Exposition(result.body);
  }

  TempDir dir_;
  std::unique_ptr<ServerProcess> server_;
  std::uint16_t port_ = 0;
};

TEST_F(MetricsEndpoint, CountersMoveByWhatTheClientsDid) {
  const Exposition before = scrape();
  EXPECT_FALSE(before.value("occgeo_queries_total", {{"kind", "collision"}}).has_value());

  // A simulated Bearcat for 5 s in lockstep: every scan it sends must be counted once.
  const auto sim = run_process(
      {binary("clients/sim/occgeo-sim").string(), "--world", source("clients/sim/worlds/open_field.yaml").string(),
       "--server", server_->address(), "--id", "bearcat-m", "--lockstep", "--duration", "5"},
      std::chrono::seconds(60));
  ASSERT_EQ(sim.exit_code, 0) << sim.err;

  auto query = open_query_session(server_->address());
  v1::ClientMessage status_request;
  status_request.mutable_status();
  status_request.set_request_id(1);
  const v1::StatusReply status = query.call(status_request, 1).status();
  ASSERT_EQ(status.robots_size(), 1);
  const double scans = static_cast<double>(status.robots(0).scans_ingested());
  ASSERT_GT(scans, 0);

  constexpr int kQueries = 25;
  for (int i = 0; i < kQueries; ++i) {
    v1::ClientMessage request;
    request.set_request_id(static_cast<std::uint64_t>(100 + i));
    auto* collision = request.mutable_collision();
    collision->set_robot_id("bearcat-m");
    collision->mutable_pose()->set_x(0.1 * i);
    ASSERT_TRUE(query.call(request, static_cast<std::uint64_t>(100 + i)).has_collision());
  }

  const Exposition after = scrape();
  EXPECT_EQ(after.types.at("occgeo_scans_ingested_total"), "counter");
  EXPECT_EQ(after.types.at("occgeo_query_duration_seconds"), "histogram");
  EXPECT_EQ(after.value("occgeo_scans_ingested_total",
                        {{"robot", "bearcat-m"}, {"world", "default"}, {"kind", "laser_scan"}}),
            scans);
  // A kind the robot never sent has no series (the per-robot counters are found at each kind's first message).
  EXPECT_FALSE(after.value("occgeo_scans_ingested_total",
                           {{"robot", "bearcat-m"}, {"world", "default"}, {"kind", "range_array"}}));
  EXPECT_EQ(after.value("occgeo_queries_total", {{"kind", "collision"}}), kQueries);
  EXPECT_EQ(after.value("occgeo_queries_total", {{"kind", "status"}}), 1);
  EXPECT_EQ(after.value("occgeo_query_duration_seconds_count", {{"kind", "collision"}}), kQueries);
  EXPECT_GT(after.value("occgeo_query_duration_seconds_sum", {{"kind", "collision"}}).value_or(0), 0.0);
  // The simulator has gone; this test's query session is the one open session.
  EXPECT_EQ(after.value("occgeo_sessions", {{"role", "ROLE_QUERY"}}), 1);
  EXPECT_EQ(after.value("occgeo_sessions", {{"role", "ROLE_DRIVER"}}), 0);
  EXPECT_EQ(after.value("occgeo_sessions_opened_total"), 2);
  EXPECT_GE(after.value("occgeo_http_requests_total", {{"path", "/metrics"}, {"code", "200"}}).value_or(0), 1);
  for (const auto& [name, type] : after.types) EXPECT_TRUE(after.help.count(name)) << name << " has no HELP";
}

// Each world's model sizes and the process's resident memory: in the status reply and as gauges, the same numbers,
// growing with what the robot saw.
TEST_F(MetricsEndpoint, ReportsModelSizesAndResidentMemoryAsTheStatusDoes) {
  auto query = open_query_session(server_->address());
  const auto status = [&query](std::uint64_t id) {
    v1::ClientMessage request;
    request.mutable_status();
    request.set_request_id(id);
    return query.call(request, id).status();
  };
  const v1::StatusReply empty = status(1);
  ASSERT_EQ(empty.worlds_size(), 1);
  EXPECT_EQ(empty.worlds(0).tiles(), 0U);
  EXPECT_GT(empty.resident_bytes(), 1U << 20) << "a running server holds more than a megabyte";

  const auto sim = run_process(
      {binary("clients/sim/occgeo-sim").string(), "--world", source("clients/sim/worlds/open_field.yaml").string(),
       "--server", server_->address(), "--id", "bearcat-m", "--lockstep", "--duration", "5"},
      std::chrono::seconds(60));
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  // The octree publishes at most every octomap.min_publish_interval_s (0.2 s): wait for the last scans to show.
  std::this_thread::sleep_for(std::chrono::milliseconds(400));

  const v1::StatusReply mapped = status(2);
  ASSERT_EQ(mapped.worlds_size(), 1);
  const v1::WorldStatus& world = mapped.worlds(0);
  ASSERT_GT(world.tiles(), 0U);
  // One byte per cell of each 64 x 64 tile, and less than an eighth more for the tile's record and index entry.
  EXPECT_GE(world.grid_bytes(), world.tiles() * 4096U);
  EXPECT_LT(world.grid_bytes(), world.tiles() * 4608U + 4096U);
  EXPECT_GT(world.grid_bytes(), empty.worlds(0).grid_bytes());
  EXPECT_GT(world.distance_field_bytes(), 0U);
  ASSERT_GT(world.octomap_leaves(), 0U);
  // Every octree node is an allocation of its own: at least 32 bytes per node of the published copy.
  EXPECT_GE(world.octomap_bytes(), world.octomap_nodes() * 32U);
  EXPECT_GT(world.octomap_bytes(), empty.worlds(0).octomap_bytes());
  EXPECT_GT(mapped.resident_bytes(), 1U << 20);

  const Exposition metrics = scrape();
  EXPECT_EQ(metrics.types.at("occgeo_world_model_bytes"), "gauge");
  const auto gauge = [&metrics](const std::string& model) {
    return metrics.value("occgeo_world_model_bytes", {{"world", "default"}, {"model", model}});
  };
  // Nothing was ingested since the status: the same numbers.
  EXPECT_EQ(gauge("grid"), static_cast<double>(world.grid_bytes()));
  EXPECT_EQ(gauge("distance_field"), static_cast<double>(world.distance_field_bytes()));
  EXPECT_EQ(gauge("octomap"), static_cast<double>(world.octomap_bytes()));
  EXPECT_EQ(gauge("ptem"), static_cast<double>(world.ptem_bytes()));
  EXPECT_GT(metrics.value("occgeo_process_resident_bytes").value_or(0), static_cast<double>(1U << 20));

  // Every sensor message the world took is published, in a publication of its own or in a later message's.
  double ingested = 0.0;
  for (const auto& sample : metrics.samples) {
    if (sample.name == "occgeo_scans_ingested_total" && sample.labels.at("world") == "default")
      ingested += sample.value;
  }
  EXPECT_GT(ingested, 0.0);
  EXPECT_EQ(metrics.types.at("occgeo_world_publications"), "gauge");
  const auto publications = metrics.value("occgeo_world_publications", {{"world", "default"}});
  const auto merged = metrics.value("occgeo_world_merged_publications", {{"world", "default"}});
  ASSERT_TRUE(publications && merged);
  EXPECT_GE(*publications, 1.0);
  EXPECT_EQ(*publications + *merged, ingested);
}

TEST_F(MetricsEndpoint, ServesThePageAnswers404ForUnknownPathsAndCanBeTurnedOff) {
  EXPECT_EQ(http_get(port_, "/nope").status, 404u);
  const HttpResult page = http_get(port_, "/");
  EXPECT_EQ(page.status, 200u);
  EXPECT_NE(page.body.find("<canvas id=\"map\""), std::string::npos);
  EXPECT_EQ(http_get(port_, "/app.js").content_type, "text/javascript; charset=utf-8");
  // Off means off: no HTTP listener is logged.
  TempDir other;
  ServerProcess without(other.path(), {"--http", "off"});
  for (int attempt = 0; attempt < 200 && without.log().find("server_listening") == std::string::npos; ++attempt) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_NE(without.log().find("server_listening"), std::string::npos);
  EXPECT_EQ(without.log().find("http_listening"), std::string::npos);
}

}  // namespace
}  // namespace occgeo::testing
