// The shape world file reader: ShapeWorld::parse and ShapeWorld::load (the YAML format is in clients/sim/README.md).
#include "occgeo/sim/shape_world.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace occgeo::sim {

namespace {

class Parser {
 public:
  explicit Parser(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const std::string& path, const std::string& message) const {
    throw WorldError(source_ + ": " + path + ": " + message);
  }

  void check_keys(const YAML::Node& node, const std::string& path, const std::set<std::string>& allowed) const {
    if (!node.IsMap()) fail(path, "expected a mapping");
    for (const auto& entry : node) {
      const std::string key = entry.first.as<std::string>();
      if (!allowed.contains(key)) {
        std::string names;
        for (const std::string& name : allowed) names += (names.empty() ? "" : ", ") + name;
        fail(path.empty() ? key : path + "." + key, "unknown key '" + key + "' (expected one of: " + names + ")");
      }
    }
  }

  double number(const YAML::Node& node, const std::string& path) const {
    double value = 0.0;
    if (!node.IsScalar() || !YAML::convert<double>::decode(node, value) || !std::isfinite(value)) {
      fail(path, "expected a finite number");
    }
    return value;
  }

  Eigen::Vector2d point(const YAML::Node& node, const std::string& path) const {
    if (!node.IsSequence() || node.size() != 2) fail(path, "expected [x, y]");
    return {number(node[0], path + "[0]"), number(node[1], path + "[1]")};
  }

  std::vector<Eigen::Vector2d> points(const YAML::Node& node, const std::string& path) const {
    if (!node.IsSequence() || node.size() == 0) fail(path, "expected a non-empty list of [x, y]");
    std::vector<Eigen::Vector2d> result;
    for (std::size_t i = 0; i < node.size(); ++i)
      result.push_back(point(node[i], path + "[" + std::to_string(i) + "]"));
    return result;
  }

  const YAML::Node required(const YAML::Node& node, const std::string& key, const std::string& path) const {
    const YAML::Node value = node[key];
    if (!value) fail(path, "missing key '" + key + "'");
    return value;
  }

  // One shape entry: a mapping with exactly one of circle / box / polygon. center_optional for moving obstacles.
  Shape shape(const YAML::Node& node, const std::string& path, bool moving) const {
    if (!node.IsMap() || node.size() != 1) fail(path, "expected one of circle:, box:, polygon:, ramp:");
    const std::string kind = node.begin()->first.as<std::string>();
    const YAML::Node params = node.begin()->second;
    const std::string at = path + "." + kind;
    Shape result;
    try {
      if (kind == "circle") {
        check_keys(params, at, {"center", "radius", "base_height", "top_height", "solid"});
        const Eigen::Vector2d center = moving && !params["center"]
                                           ? Eigen::Vector2d::Zero()
                                           : point(required(params, "center", at), at + ".center");
        result = Shape::circle(center, number(required(params, "radius", at), at + ".radius"));
      } else if (kind == "box") {
        check_keys(params, at, {"center", "size", "yaw", "base_height", "top_height", "solid"});
        const Eigen::Vector2d center = moving && !params["center"]
                                           ? Eigen::Vector2d::Zero()
                                           : point(required(params, "center", at), at + ".center");
        const Eigen::Vector2d size = point(required(params, "size", at), at + ".size");
        const double yaw = params["yaw"] ? number(params["yaw"], at + ".yaw") : 0.0;
        result = Shape::box(center, size.x(), size.y(), yaw);
      } else if (kind == "ramp" && !moving) {
        check_keys(params, at, {"center", "size", "yaw", "base_height", "top_height", "solid"});
        const Eigen::Vector2d size = point(required(params, "size", at), at + ".size");
        const double yaw = params["yaw"] ? number(params["yaw"], at + ".yaw") : 0.0;
        result = Shape::ramp(point(required(params, "center", at), at + ".center"), size.x(), size.y(), yaw);
      } else if (kind == "polygon" && !moving) {
        check_keys(params, at, {"points", "base_height", "top_height", "solid"});
        result = Shape::polygon(points(required(params, "points", at), at + ".points"));
      } else {
        fail(path + "." + kind,
             "unknown key '" + kind + "' (expected one of: circle, box" + (moving ? "" : ", polygon, ramp") + ")");
      }
    } catch (const WorldError& error) {
      const std::string message = error.what();
      if (message.starts_with(source_ + ": ")) throw;
      fail(at, message);
    }
    result.base_height_m =
        params["base_height"] ? number(params["base_height"], at + ".base_height") : kDefaultShapeBaseHeight_m;
    result.top_height_m =
        params["top_height"] ? number(params["top_height"], at + ".top_height") : kDefaultShapeTopHeight_m;
    if (!(result.base_height_m >= 0.0 && result.top_height_m > result.base_height_m)) {
      fail(at, "need 0 <= base_height < top_height, got " + std::to_string(result.base_height_m) + " and " +
                   std::to_string(result.top_height_m));
    }
    if (kind == "ramp") {
      // From base_height at the low edge to top_height at the high edge.
      const Eigen::Vector2d size = point(params["size"], at + ".size");
      result.slope_rise = (result.top_height_m - result.base_height_m) / size.x();
    }
    if (params["solid"]) {
      if (moving) fail(at + ".solid", "only static shapes may be non-solid");
      try {
        result.solid = params["solid"].as<bool>();
      } catch (const YAML::Exception&) {
        fail(at + ".solid", "expected true or false");
      }
    }
    result.name = path + " (" + kind + ")";
    return result;
  }

  ShapeWorld world(const YAML::Node& root) const {
    if (!root.IsMap()) fail("(top level)", "expected a mapping");
    check_keys(root, "", {"occgeo_world", "bounds", "shapes", "moving"});
    if (!root["shapes"] && !root["occgeo_world"])
      fail("(top level)", "a shape world needs 'shapes:' or 'occgeo_world: 1'");
    if (root["occgeo_world"] && number(root["occgeo_world"], "occgeo_world") != 1.0) {
      fail("occgeo_world", "only version 1 is supported");
    }
    std::optional<std::pair<Eigen::Vector2d, Eigen::Vector2d>> bounds;
    if (root["bounds"]) {
      const std::vector<Eigen::Vector2d> corners = points(root["bounds"], "bounds");
      if (corners.size() != 2 || !(corners[0].x() < corners[1].x() && corners[0].y() < corners[1].y())) {
        fail("bounds", "expected [[xmin, ymin], [xmax, ymax]] with min < max");
      }
      bounds = std::pair{corners[0], corners[1]};
    }
    std::vector<Shape> shapes;
    if (const YAML::Node list = root["shapes"]; list && !list.IsNull()) {
      if (!list.IsSequence()) fail("shapes", "expected a list");
      for (std::size_t i = 0; i < list.size(); ++i) {
        shapes.push_back(shape(list[i], "shapes[" + std::to_string(i) + "]", false));
      }
    }
    std::vector<MovingObstacle> moving;
    if (const YAML::Node list = root["moving"]; list && !list.IsNull()) {
      if (!list.IsSequence()) fail("moving", "expected a list");
      for (std::size_t i = 0; i < list.size(); ++i) {
        const std::string at = "moving[" + std::to_string(i) + "]";
        const YAML::Node entry = list[i];
        check_keys(entry, at, {"shape", "waypoints", "speed", "loop", "start"});
        MovingObstacle obstacle;
        obstacle.shape = shape(required(entry, "shape", at), at + ".shape", true);
        obstacle.shape.name = at + " (" + entry["shape"].begin()->first.as<std::string>() + ")";
        obstacle.waypoints = points(required(entry, "waypoints", at), at + ".waypoints");
        obstacle.speed_mps = number(required(entry, "speed", at), at + ".speed");
        if (!(obstacle.speed_mps >= 0.0)) fail(at + ".speed", "must be >= 0");
        if (entry["loop"]) {
          if (!YAML::convert<bool>::decode(entry["loop"], obstacle.loop)) fail(at + ".loop", "expected true or false");
        }
        if (entry["start"]) {
          obstacle.start_s = number(entry["start"], at + ".start");
          if (!(obstacle.start_s >= 0.0)) fail(at + ".start", "must be >= 0 (sim seconds)");
        }
        moving.push_back(std::move(obstacle));
      }
    }
    return ShapeWorld(std::move(shapes), std::move(moving), bounds);
  }

 private:
  std::string source_;
};

}  // namespace

ShapeWorld ShapeWorld::parse(const std::string& yaml_text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& error) {
    throw WorldError(source + ": not valid YAML: " + error.what());
  }
  return Parser(source).world(root);
}

ShapeWorld ShapeWorld::load(const std::filesystem::path& yaml_path) {
  std::ifstream in(yaml_path);
  if (!in) throw WorldError(yaml_path.string() + ": cannot open the file");
  std::ostringstream text;
  text << in.rdbuf();
  return parse(text.str(), yaml_path.string());
}

}  // namespace occgeo::sim
