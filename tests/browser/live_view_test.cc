// The live view in a real browser: occgeod and a simulated Bearcat (lockstep) on 127.0.0.1, then headless Chromium
// opens the page. The page writes what it drew into #summary (read with --dump-dom); the screenshot is kept as
// tests/browser/live_view.png in the build tree and its pixels are checked where the robot and the walls are drawn.
// Boost.PropertyTree (the JSON reader here) pulls in boost/bind.hpp, which otherwise warns about its placeholders.
#define BOOST_BIND_GLOBAL_PLACEHOLDERS
#include <gtest/gtest.h>
#include <zlib.h>

#include <boost/property_tree/json_parser.hpp>
#include <boost/property_tree/ptree.hpp>
#include <cmath>
#include <fstream>
#include <optional>
#include <regex>
#include <sstream>
#include <thread>

#include "../integration/test_clients.h"
#include "../support/http_get.h"
#include "../support/process.h"

namespace occgeo::testing {
namespace {

using boost::property_tree::ptree;

constexpr const char* kChromium = "/usr/bin/chromium";

// An 8-bit RGB or RGBA PNG (what Chromium writes), decoded to RGB.
struct Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;
  [[nodiscard]] std::array<int, 3> at(int x, int y) const {
    const std::size_t k =
        (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 3;
    return {rgb[k], rgb[k + 1], rgb[k + 2]};
  }
};

std::uint32_t big_endian(const std::string& bytes, std::size_t at) {
  return (std::uint32_t{static_cast<std::uint8_t>(bytes[at])} << 24) |
         (std::uint32_t{static_cast<std::uint8_t>(bytes[at + 1])} << 16) |
         (std::uint32_t{static_cast<std::uint8_t>(bytes[at + 2])} << 8) | static_cast<std::uint8_t>(bytes[at + 3]);
}

Image read_png(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() < 8 || bytes.compare(1, 3, "PNG") != 0) throw std::runtime_error("not a PNG: " + file.string());
  Image image;
  int channels = 0;
  std::string compressed;
  for (std::size_t at = 8; at + 8 <= bytes.size();) {
    const std::uint32_t length = big_endian(bytes, at);
    const std::string type = bytes.substr(at + 4, 4);
    if (type == "IHDR") {
      image.width = static_cast<int>(big_endian(bytes, at + 8));
      image.height = static_cast<int>(big_endian(bytes, at + 12));
      const int depth = static_cast<std::uint8_t>(bytes[at + 16]);
      const int colour = static_cast<std::uint8_t>(bytes[at + 17]);
      const int interlace = static_cast<std::uint8_t>(bytes[at + 20]);
      if (depth != 8 || (colour != 2 && colour != 6) || interlace != 0) throw std::runtime_error("unsupported PNG");
      channels = colour == 6 ? 4 : 3;
    } else if (type == "IDAT") {
      compressed += bytes.substr(at + 8, length);
    }
    at += 12 + length;
  }
  const std::size_t stride = static_cast<std::size_t>(image.width) * static_cast<std::size_t>(channels);
  std::vector<std::uint8_t> raw((stride + 1) * static_cast<std::size_t>(image.height));
  uLongf raw_size = raw.size();
  if (uncompress(raw.data(), &raw_size, reinterpret_cast<const Bytef*>(compressed.data()), compressed.size()) != Z_OK ||
      raw_size != raw.size()) {
    throw std::runtime_error("PNG data does not inflate");
  }
  std::vector<std::uint8_t> pixels(stride * static_cast<std::size_t>(image.height));
  const auto bpp = static_cast<std::size_t>(channels);
  for (std::size_t y = 0; y < static_cast<std::size_t>(image.height); ++y) {
    const std::uint8_t filter = raw[y * (stride + 1)];
    const std::uint8_t* line = &raw[y * (stride + 1) + 1];
    std::uint8_t* out = &pixels[y * stride];
    const std::uint8_t* up = y > 0 ? &pixels[(y - 1) * stride] : nullptr;
    for (std::size_t i = 0; i < stride; ++i) {
      const int a = i >= bpp ? out[i - bpp] : 0;
      const int b = up ? up[i] : 0;
      const int c = up && i >= bpp ? up[i - bpp] : 0;
      int predicted = 0;
      switch (filter) {
        case 0:
          break;
        case 1:
          predicted = a;
          break;
        case 2:
          predicted = b;
          break;
        case 3:
          predicted = (a + b) / 2;
          break;
        case 4: {
          const int p = a + b - c;
          const int pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
          predicted = pa <= pb && pa <= pc ? a : (pb <= pc ? b : c);
          break;
        }
        default:
          throw std::runtime_error("bad PNG filter");
      }
      out[i] = static_cast<std::uint8_t>(line[i] + predicted);
    }
  }
  image.rgb.reserve(static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height) * 3);
  for (std::size_t p = 0; p < pixels.size(); p += bpp) image.rgb.insert(image.rgb.end(), &pixels[p], &pixels[p] + 3);
  return image;
}

std::vector<std::string> chromium_args(const std::filesystem::path& profile) {
  return {kChromium,
          "--headless=new",
          "--no-sandbox",  // CI runs as root
          "--disable-gpu",
          "--no-first-run",
          "--hide-scrollbars",
          "--user-data-dir=" + profile.string(),
          "--window-size=1300,720",
          "--virtual-time-budget=4000"};
}

// The page's #summary after Chromium has run it for a few (virtual) seconds. Virtual time runs ahead of the
// WebSocket when the machine is busy (CI runs the fuzzers beside this test), so a load that ended before the first
// complete map frame arrived is repeated, at most three times in all.
ptree page_summary(const std::filesystem::path& profile, const std::string& url) {
  constexpr int kMaxLoads = 3;
  ptree summary;
  for (int load = 1; load <= kMaxLoads; ++load) {
    auto args = chromium_args(profile);
    args.push_back("--dump-dom");
    args.push_back(url);
    const auto dom = run_process(args, std::chrono::seconds(40));
    if (dom.exit_code != 0) throw std::runtime_error("chromium --dump-dom failed: " + dom.err);
    std::smatch match;
    if (!std::regex_search(dom.out, match, std::regex(R"(<pre id="summary"[^>]*>([^<]*)</pre>)"))) {
      throw std::runtime_error("no #summary in the page: " + dom.out);
    }
    summary = ptree();
    std::istringstream summary_text(match[1].str());
    boost::property_tree::read_json(summary_text, summary);
    std::cout << "page summary (load " << load << "): " << match[1].str() << "\n";
    if (summary.get<int>("frames", 0) > 0 && summary.get<bool>("map_complete", false)) break;
  }
  return summary;
}

// A screenshot of the page, repeated (at most three loads in all) until `drawn` accepts it, for the same reason as
// page_summary: on a busy machine Chromium's virtual time can end before the first frame arrives.
template <typename Drawn>
Image screenshot(const std::filesystem::path& profile, const std::string& url, const std::filesystem::path& png,
                 const Drawn& drawn) {
  constexpr int kMaxLoads = 3;
  Image image;
  for (int load = 1; load <= kMaxLoads; ++load) {
    std::filesystem::remove(png);
    auto args = chromium_args(profile);
    args.push_back("--screenshot=" + png.string());
    args.push_back(url);
    const auto shot = run_process(args, std::chrono::seconds(40));
    if (shot.exit_code != 0) throw std::runtime_error("chromium --screenshot failed: " + shot.err);
    image = read_png(png);
    if (drawn(image)) break;
    std::cout << "screenshot load " << load << " shows no frame yet\n";
  }
  return image;
}

TEST(LiveViewInBrowser, DrawsTheRobotWhereTheServerSaysAndTheOccupiedCells) {
  if (!std::filesystem::exists(kChromium)) GTEST_SKIP() << kChromium << " is not installed (Debian package chromium)";
  TempDir dir;
  ServerProcess server(dir.path(), {"--http", "127.0.0.1:0"});
  const std::uint16_t port = http_port(server);
  // 30 simulated seconds of a Bearcat in lockstep, then the simulator leaves: the map and the pose stay still.
  const auto sim = run_process(
      {binary("clients/sim/occgeo-sim").string(), "--world", source("clients/sim/worlds/open_field.yaml").string(),
       "--server", server.address(), "--id", "bearcat-1", "--lockstep", "--duration", "30"},
      std::chrono::seconds(60));
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  auto query = open_query_session(server.address());
  v1::ClientMessage request;
  request.mutable_status();
  request.set_request_id(1);
  const v1::StatusReply status = query.call(request, 1).status();
  ASSERT_EQ(status.robots_size(), 1);
  ASSERT_EQ(status.worlds_size(), 1);
  ASSERT_GT(status.worlds(0).occupied_cells(), 0u);

  const std::string url = "http://127.0.0.1:" + std::to_string(port) + "/";
  const ptree summary = page_summary(dir.path() / "profile-dom", url);

  EXPECT_TRUE(summary.get<bool>("map_complete"));
  EXPECT_EQ(summary.get<std::uint64_t>("map_version"), status.worlds(0).version());
  EXPECT_EQ(summary.get<std::uint64_t>("occupied_cells_rendered"), status.worlds(0).occupied_cells());
  ASSERT_EQ(summary.get_child("robots").size(), 1u);
  const ptree& robot = summary.get_child("robots").begin()->second;
  EXPECT_EQ(robot.get<std::string>("id"), "bearcat-1");
  EXPECT_DOUBLE_EQ(robot.get<double>("x"), status.robots(0).pose().x());
  EXPECT_DOUBLE_EQ(robot.get<double>("y"), status.robots(0).pose().y());
  EXPECT_DOUBLE_EQ(robot.get<double>("theta"), status.robots(0).pose().theta());
  const double px = robot.get<double>("px") + summary.get<double>("canvas.left");
  const double py = robot.get<double>("py") + summary.get<double>("canvas.top");

  // The latest scan is drawn where its returns hit something: every point the page lists lies within the laser's
  // 8 m of the robot and on (or next to) a cell the server's grid holds occupied, since that scan marked it last.
  request.Clear();
  request.set_request_id(2);
  request.mutable_grid()->set_world(status.worlds(0).name());
  const v1::GridReply grid = query.call(request, 2).grid();
  const auto occupied_near = [&](double x, double y) {
    const auto ix = static_cast<std::int64_t>(std::floor(x / grid.cell_size_m()));
    const auto iy = static_cast<std::int64_t>(std::floor(y / grid.cell_size_m()));
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        const std::int64_t col = ix + dx - grid.min_cell().ix(), row = iy + dy - grid.min_cell().iy();
        if (col < 0 || row < 0 || col >= grid.width() || row >= grid.height()) continue;
        const auto c = static_cast<std::uint8_t>(grid.cells()[static_cast<std::size_t>(row * grid.width() + col)]);
        if (c != 255 && c >= grid.occupied_threshold()) return true;
      }
    }
    return false;
  };
  const auto scan = robot.get_child_optional("scan");
  ASSERT_TRUE(scan && !scan->empty()) << "the page drew no scan";
  const auto scan_points = scan->get<std::size_t>("points");
  ASSERT_GT(scan_points, 10u);
  std::vector<std::array<double, 2>> scan_pixels;
  for (const auto& [unused, point] : scan->get_child("sample")) {
    std::vector<double> v;
    for (const auto& [unused_key, number] : point) v.push_back(number.get_value<double>());
    ASSERT_EQ(v.size(), 4u);
    const double range = std::hypot(v[0] - status.robots(0).pose().x(), v[1] - status.robots(0).pose().y());
    EXPECT_LE(range, 8.5) << "scan point (" << v[0] << ", " << v[1] << ")";
    EXPECT_TRUE(occupied_near(v[0], v[1])) << "scan point (" << v[0] << ", " << v[1] << ") is on no occupied cell";
    scan_pixels.push_back({v[2] + summary.get<double>("canvas.left"), v[3] + summary.get<double>("canvas.top")});
  }
  ASSERT_GE(scan_pixels.size(), 5u);

  // The screenshot, kept for people: the robot's own pixel has the robot's colour, and walls are drawn black.
  const auto artifact_dir = std::filesystem::path(OCCGEO_BINARY_DIR) / "tests" / "browser";
  std::filesystem::create_directories(artifact_dir);
  const auto png = artifact_dir / "live_view.png";
  const Image image = screenshot(dir.path() / "profile-shot", url, png, [&](const Image& shot) {
    return shot.width > static_cast<int>(px) && shot.height > static_cast<int>(py) &&
           shot.at(static_cast<int>(std::floor(px)), static_cast<int>(std::floor(py))) ==
               std::array<int, 3>{255, 140, 0};
  });
  std::cout << "screenshot " << png.string() << ": " << image.width << " x " << image.height << "\n";
  ASSERT_GT(image.width, static_cast<int>(px));
  ASSERT_GT(image.height, static_cast<int>(py));
  const auto centre = image.at(static_cast<int>(std::floor(px)), static_cast<int>(std::floor(py)));
  EXPECT_EQ(centre, (std::array<int, 3>{255, 140, 0})) << "at " << px << ", " << py;
  const int left = summary.get<int>("canvas.left"), top = summary.get<int>("canvas.top");
  const int width = summary.get<int>("canvas.width"), height = summary.get<int>("canvas.height");
  int black = 0;
  for (int y = top; y < std::min(image.height, top + height); ++y) {
    for (int x = left; x < std::min(image.width, left + width); ++x) {
      if (image.at(x, y) == std::array<int, 3>{0, 0, 0}) ++black;
    }
  }
  std::cout << black << " black (occupied) pixels on the canvas\n";
  EXPECT_GT(black, 0);
  // The scan's points are drawn in the scan colour at the pixels the page reported (a robot's label may cover a few).
  std::size_t scan_coloured = 0;
  for (const auto& [x, y] : scan_pixels) {
    scan_coloured += image.at(static_cast<int>(x), static_cast<int>(y)) == std::array<int, 3>{0, 230, 64} ? 1 : 0;
  }
  std::cout << scan_coloured << " of " << scan_pixels.size() << " sampled scan points drawn in the scan colour\n";
  EXPECT_GE(scan_coloured * 4, scan_pixels.size() * 3);
}

TEST(LiveViewInBrowser, DrawsThePathOfAGotoBeingFollowed) {
  if (!std::filesystem::exists(kChromium)) GTEST_SKIP() << kChromium << " is not installed (Debian package chromium)";
  TempDir dir;
  ServerProcess server(dir.path(), {"--http", "127.0.0.1:0"});
  const std::uint16_t port = http_port(server);
  // A Bearcat in real time on the open field, and `occgeo goto` driving it 15 m ahead (half a minute at its speed):
  // the goto is still being followed while the browser looks.
  BackgroundProcess sim(
      {binary("clients/sim/occgeo-sim").string(), "--world", source("clients/sim/worlds/open_field.yaml").string(),
       "--server", server.address(), "--id", "bearcat-1", "--duration", "90"},
      dir.path() / "sim.out", dir.path() / "sim.err");
  auto query = open_query_session(server.address());
  std::uint64_t request_id = 0;
  const auto robot_status = [&]() -> std::optional<v1::RobotStatus> {
    v1::ClientMessage request;
    request.mutable_status();
    request.set_request_id(++request_id);
    const v1::StatusReply status = query.call(request, request_id).status();
    if (status.robots_size() == 0) return std::nullopt;
    return status.robots(0);
  };
  for (int attempt = 0; attempt < 200; ++attempt) {
    const auto robot = robot_status();
    if (robot && robot->scans_ingested() > 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  BackgroundProcess go({binary("clients/occgeo").string(), "goto", "--robot", "bearcat-1", "15", "0", "--limit", "80",
                        "--server", server.address()},
                       dir.path() / "goto.out", dir.path() / "goto.err");
  bool following = false;
  for (int attempt = 0; attempt < 200 && !following; ++attempt) {
    const auto robot = robot_status();
    following = robot && robot->behaviour() == v1::BEHAVIOUR_GOTO;
    if (!following) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_TRUE(following) << "the robot never took the goto";
  // The path is planned when the goto answers a scan: let a few scans through before the page looks.
  const std::uint64_t scans_at_goto = robot_status()->scans_ingested();
  for (int attempt = 0; attempt < 200; ++attempt) {
    const auto robot = robot_status();
    if (robot && robot->scans_ingested() >= scans_at_goto + 3) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }

  const std::string url = "http://127.0.0.1:" + std::to_string(port) + "/";
  const ptree summary = page_summary(dir.path() / "profile-dom", url);
  ASSERT_EQ(summary.get_child("robots").size(), 1u);
  const ptree& path = summary.get_child("robots").begin()->second.get_child("path");
  ASSERT_GE(path.size(), 2u) << "no path drawn while a goto is followed";
  std::vector<double> goal;
  for (const auto& [unused, number] : path.rbegin()->second) goal.push_back(number.get_value<double>());
  ASSERT_EQ(goal.size(), 4u);
  EXPECT_DOUBLE_EQ(goal[0], 15.0);  // the path ends at the goal
  EXPECT_DOUBLE_EQ(goal[1], 0.0);

  // The screenshot shows the path's line in its colour (nothing else is drawn in it).
  const auto png = dir.path() / "goto.png";
  const auto path_colour_count = [](const Image& shot) {
    int count = 0;
    for (int y = 0; y < shot.height; ++y) {
      for (int x = 0; x < shot.width; ++x) count += shot.at(x, y) == std::array<int, 3>{46, 196, 182} ? 1 : 0;
    }
    return count;
  };
  const Image image =
      screenshot(dir.path() / "profile-shot", url, png, [&](const Image& shot) { return path_colour_count(shot) > 0; });
  const int path_pixels = path_colour_count(image);
  std::cout << path_pixels << " pixels of the path's colour\n";
  EXPECT_GT(path_pixels, 100);
  const auto robot = robot_status();
  ASSERT_TRUE(robot);
  EXPECT_EQ(robot->behaviour(), v1::BEHAVIOUR_GOTO) << "the goto ended before the screenshot";
}

}  // namespace
}  // namespace occgeo::testing
