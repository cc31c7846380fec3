#include "occgeo/mapfile/map_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "../support/temp_dir.h"

namespace occgeo::mapfile {
namespace {

using CellState = OccupancyImage::CellState;

class MapFileTest : public ::testing::Test {
 protected:
  // Writes text (or bytes) to a file of the temp folder and returns its path.
  std::filesystem::path write(const std::string& name, const std::string& contents) const {
    const std::filesystem::path file = dir_.path() / name;
    std::ofstream(file, std::ios::binary) << contents;
    return file;
  }

  // The message of the MapFileError that reading yaml_file throws, or "" when it reads.
  static std::string read_error(const std::filesystem::path& yaml_file) {
    try {
      (void)read_map_yaml(yaml_file);
    } catch (const MapFileError& e) {
      return e.what();
    }
    return "";
  }

  // A 3x2 plain PGM and a valid YAML naming it, with extra YAML lines appended.
  std::filesystem::path valid_map_with(const std::string& extra_yaml) const {
    write("tiny.pgm", "P2\n3 2\n255\n0 205 254\n10 20 30\n");
    return write("tiny.yaml", "image: tiny.pgm\nresolution: 0.05\norigin: [-1.0, 2.0, 0.0]\n" + extra_yaml);
  }

  occgeo::testing::TempDir dir_;
};

TEST_F(MapFileTest, ReadsPlainPgmWithItsYaml) {
  const OccupancyImage image =
      read_map_yaml(valid_map_with("negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n"));
  EXPECT_EQ(image.width, 3U);
  EXPECT_EQ(image.height, 2U);
  EXPECT_EQ(image.pixels, (std::vector<std::uint8_t>{0, 205, 254, 10, 20, 30}));
  EXPECT_DOUBLE_EQ(image.resolution, 0.05);
  EXPECT_DOUBLE_EQ(image.origin_x, -1.0);
  EXPECT_DOUBLE_EQ(image.origin_y, 2.0);
  EXPECT_FALSE(image.negate);
}

TEST_F(MapFileTest, ReadsBinaryPgmWithHeaderComments) {
  write("map.pgm", std::string("P5\n# made by hand\n2 # width\n2\n255\n") + std::string("\x00\xcd\xfe\x80", 4));
  const OccupancyImage image = read_map_yaml(write("map.yaml", "image: map.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n"));
  EXPECT_EQ(image.pixels, (std::vector<std::uint8_t>{0, 205, 254, 128}));
}

TEST_F(MapFileTest, ScalesPgmWithSmallerMaxval) {
  write("map.pgm", "P2 2 1 15 0 15");
  const OccupancyImage image = read_map_yaml(write("map.yaml", "image: map.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n"));
  EXPECT_EQ(image.pixels, (std::vector<std::uint8_t>{0, 255}));
}

TEST_F(MapFileTest, ImagePathIsRelativeToTheYamlFolder) {
  std::filesystem::create_directories(dir_.path() / "maps");
  write("maps/room.pgm", "P2\n1 1\n255\n7\n");
  const OccupancyImage image =
      read_map_yaml(write("maps/room.yaml", "image: room.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n"));
  EXPECT_EQ(image.pixels, (std::vector<std::uint8_t>{7}));
}

TEST_F(MapFileTest, TrinaryStateFollowsMapServer) {
  OccupancyImage image;
  image.width = 5;
  image.height = 1;
  image.resolution = 0.1;
  image.pixels = {0, 89, 90, 205, 254};  // p = 1, 0.651, 0.647, 0.196, 0.004
  EXPECT_EQ(image.state(0, 0), CellState::occupied);
  EXPECT_EQ(image.state(1, 0), CellState::occupied);
  EXPECT_EQ(image.state(2, 0), CellState::unknown);
  EXPECT_EQ(image.state(3, 0), CellState::unknown);
  EXPECT_EQ(image.state(4, 0), CellState::free);
  image.negate = true;  // p = pixel / 255.
  EXPECT_EQ(image.state(0, 0), CellState::free);
  EXPECT_EQ(image.state(4, 0), CellState::occupied);
}

TEST_F(MapFileTest, PixelCentreCountsRowsFromTheTop) {
  OccupancyImage image;
  image.width = 4;
  image.height = 3;
  image.resolution = 0.5;
  image.origin_x = -1.0;
  image.origin_y = 2.0;
  const MapPoint top_left = image.pixel_center(0, 0);
  EXPECT_DOUBLE_EQ(top_left.x, -0.75);
  EXPECT_DOUBLE_EQ(top_left.y, 3.25);
  const MapPoint bottom_right = image.pixel_center(3, 2);
  EXPECT_DOUBLE_EQ(bottom_right.x, 0.75);
  EXPECT_DOUBLE_EQ(bottom_right.y, 2.25);
}

TEST_F(MapFileTest, WriteThenReadKeepsEverything) {
  OccupancyImage image;
  image.width = 3;
  image.height = 2;
  image.resolution = 0.1;
  image.origin_x = -12.3;
  image.origin_y = 4.5;
  image.pixels = {0, 1, 2, 205, 254, 255};
  image.occupied_thresh = 0.2;
  image.free_thresh = 0.16862745098039217;
  image.negate = true;
  std::filesystem::create_directories(dir_.path() / "out");
  write_map(dir_.path() / "out" / "world.v2", image);
  ASSERT_TRUE(std::filesystem::exists(dir_.path() / "out" / "world.v2.pgm"));
  const OccupancyImage back = read_map_yaml(dir_.path() / "out" / "world.v2.yaml");
  EXPECT_EQ(back.width, image.width);
  EXPECT_EQ(back.height, image.height);
  EXPECT_EQ(back.pixels, image.pixels);
  EXPECT_EQ(back.resolution, image.resolution);
  EXPECT_EQ(back.origin_x, image.origin_x);
  EXPECT_EQ(back.origin_y, image.origin_y);
  EXPECT_EQ(back.occupied_thresh, image.occupied_thresh);  // Shortest round-trip formatting: exact.
  EXPECT_EQ(back.free_thresh, image.free_thresh);
  EXPECT_EQ(back.negate, image.negate);
}

TEST_F(MapFileTest, MissingKeyIsNamedWithTheFile) {
  write("tiny.pgm", "P2\n1 1\n255\n0\n");
  const std::filesystem::path yaml = write("bad.yaml", "image: tiny.pgm\norigin: [0, 0, 0]\n");
  EXPECT_EQ(read_error(yaml), yaml.string() + ": missing key 'resolution'");
}

TEST_F(MapFileTest, UnknownKeyIsAnError) {
  const std::string message = read_error(valid_map_with("resolutoin: 0.05\n"));
  EXPECT_NE(message.find("tiny.yaml: unknown key 'resolutoin'"), std::string::npos) << message;
}

TEST_F(MapFileTest, BadValuesNameTheirKey) {
  EXPECT_NE(read_error(write("a.yaml", "image: tiny.pgm\nresolution: fine\norigin: [0, 0, 0]\n"))
                .find("a.yaml: key 'resolution': expected a finite number"),
            std::string::npos);
  EXPECT_NE(read_error(write("b.yaml", "image: tiny.pgm\nresolution: -0.1\norigin: [0, 0, 0]\n"))
                .find("b.yaml: key 'resolution' must be > 0, got -0.1"),
            std::string::npos);
  EXPECT_NE(read_error(write("c.yaml", "image: tiny.pgm\nresolution: 0.1\norigin: [0, 0]\n"))
                .find("c.yaml: key 'origin': expected [x, y, yaw]"),
            std::string::npos);
  EXPECT_NE(read_error(valid_map_with("occupied_thresh: 1.5\n")).find("key 'occupied_thresh' must be in [0, 1]"),
            std::string::npos);
  EXPECT_NE(read_error(valid_map_with("negate: 2\n")).find("key 'negate': expected 0, 1, true or false"),
            std::string::npos);
  EXPECT_NE(read_error(valid_map_with("free_thresh: 0.7\n")).find("key 'free_thresh' 0.7 is above occupied_thresh"),
            std::string::npos);
}

TEST_F(MapFileTest, RejectsRotatedOriginAndRawMode) {
  EXPECT_NE(read_error(write("r.yaml", "image: tiny.pgm\nresolution: 0.1\norigin: [0, 0, 0.5]\n"))
                .find("r.yaml: key 'origin': yaw 0.5 is not supported (only 0)"),
            std::string::npos);
  EXPECT_NE(read_error(valid_map_with("mode: raw\n")).find("key 'mode': 'raw' is not supported"), std::string::npos);
}

TEST_F(MapFileTest, ImageProblemsNameTheImageFile) {
  const std::string yaml = "image: broken.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n";
  const std::string missing = read_error(write("m.yaml", yaml));
  EXPECT_NE(missing.find("broken.pgm: cannot open file"), std::string::npos) << missing;

  write("broken.pgm", "\x89PNG\r\n");
  EXPECT_NE(read_error(write("n.yaml", yaml)).find("broken.pgm: not a PGM image"), std::string::npos);
  write("broken.pgm", "P5\n2 2\n65535\n");
  EXPECT_NE(read_error(write("o.yaml", yaml)).find("broken.pgm: maxval 65535 is not supported"), std::string::npos);
  write("broken.pgm", "P5\n4 4\n255\nabc");
  EXPECT_NE(read_error(write("p.yaml", yaml)).find("broken.pgm: truncated: expected 16 pixels"), std::string::npos);
  write("broken.pgm", "P2\n2 1\n255\n7 300\n");
  EXPECT_NE(read_error(write("q.yaml", yaml)).find("broken.pgm: bad or truncated plain PGM pixel data"),
            std::string::npos);
  write("broken.pgm", "P5\nx 1\n255\n");
  EXPECT_NE(read_error(write("s.yaml", yaml)).find("broken.pgm: bad PGM header field 'width'"), std::string::npos);
}

TEST_F(MapFileTest, MalformedYamlIsReported) {
  const std::string message = read_error(write("bad.yaml", "image: [unclosed\n"));
  EXPECT_NE(message.find("bad.yaml: invalid YAML"), std::string::npos) << message;
  EXPECT_NE(read_error(write("list.yaml", "- image\n")).find("list.yaml: expected a map of map_server keys"),
            std::string::npos);
}

TEST_F(MapFileTest, WriteRejectsInconsistentImages) {
  OccupancyImage image;
  image.width = 2;
  image.height = 2;
  image.resolution = 0.1;
  image.pixels = {1, 2, 3};
  EXPECT_THROW(write_map(dir_.path() / "x", image), MapFileError);
  image.pixels.push_back(4);
  image.origin_yaw = 0.1;
  try {
    write_map(dir_.path() / "x", image);
    FAIL() << "expected MapFileError";
  } catch (const MapFileError& e) {
    EXPECT_NE(std::string(e.what()).find("origin yaw 0.1 is not supported"), std::string::npos) << e.what();
  }
  image.origin_yaw = 0.0;
  EXPECT_THROW(write_map(dir_.path() / "no_such_folder" / "x", image), MapFileError);
}

}  // namespace
}  // namespace occgeo::mapfile
