// Helpers the `occgeo` tool's commands share (cli_common.h).
#include <cstdio>
#include <optional>
#include <sstream>
#include <string>
#include <vector>
#include "occgeo/client/option_values.h"
#include "occgeo/proto/protocol.h"

#include "cli_common.h"

namespace occgeo::cli {

Connection connect_query(const Options& options) {
  Connection connection = Connection::open(Endpoint::parse(options.text("server", "127.0.0.1:7700")));
  v1::Hello hello;
  hello.set_protocol_version(occgeo::proto::kProtocolVersion);
  hello.set_role(v1::ROLE_QUERY);
  hello.set_client_name("occgeo-cli");
  connection.hello(hello);
  return connection;
}

std::string fmt(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", v);
  return buffer;
}

// "grid,octomap,ptem" as Model values; throws UsageError for an unknown name.
std::vector<v1::Model> models_from(const Options& options) {
  std::vector<v1::Model> models;
  std::stringstream list(options.text("models"));
  std::string name;
  while (std::getline(list, name, ',')) {
    if (name == "grid") {
      models.push_back(v1::MODEL_GRID);
    } else if (name == "octomap") {
      models.push_back(v1::MODEL_OCTOMAP);
    } else if (name == "ptem") {
      models.push_back(v1::MODEL_PTEM);
    } else {
      throw UsageError("option '--models' takes grid, octomap and ptem separated by commas, got '" + name + "'");
    }
  }
  return models;
}

std::string model_name(v1::Model model) {
  switch (model) {
    case v1::MODEL_GRID:
      return "grid";
    case v1::MODEL_OCTOMAP:
      return "octomap";
    case v1::MODEL_PTEM:
      return "ptem";
    default:
      return "";
  }
}

// Comma-separated numbers of a --footprint part; throws UsageError naming the option.
std::vector<double> footprint_numbers(const std::string& text, const std::string& spec) {
  std::vector<double> numbers;
  std::stringstream list(text);
  std::string item;
  while (std::getline(list, item, ',')) {
    const std::optional<double> value = finite_number(item);
    if (!value) throw UsageError("option '--footprint': '" + item + "' in '" + spec + "' is not a number");
    numbers.push_back(*value);
  }
  return numbers;
}

// --footprint box:L,W,H[,CX] | cylinder:R,H | polygon:H:X1,Y1:X2,Y2:...; nullopt when absent. The server checks the
// values themselves (positive sizes, convex outline) and names the bad field.
std::optional<v1::Footprint> footprint_from(const Options& options) {
  const std::string spec = options.text("footprint");
  if (spec.empty()) return std::nullopt;
  const auto colon = spec.find(':');
  const std::string shape = spec.substr(0, colon);
  const std::string rest = colon == std::string::npos ? std::string() : spec.substr(colon + 1);
  v1::Footprint footprint;
  if (shape == "box") {
    const std::vector<double> n = footprint_numbers(rest, spec);
    if (n.size() != 3 && n.size() != 4) {
      throw UsageError("option '--footprint': box takes LENGTH,WIDTH,HEIGHT[,CENTER_X]");
    }
    auto* box = footprint.mutable_box();
    box->set_length_m(n[0]);
    box->set_width_m(n[1]);
    box->set_height_m(n[2]);
    box->set_center_x_m(n.size() == 4 ? n[3] : 0.0);
  } else if (shape == "cylinder") {
    const std::vector<double> n = footprint_numbers(rest, spec);
    if (n.size() != 2) throw UsageError("option '--footprint': cylinder takes RADIUS,HEIGHT");
    footprint.mutable_cylinder()->set_radius_m(n[0]);
    footprint.mutable_cylinder()->set_height_m(n[1]);
  } else if (shape == "polygon") {
    std::stringstream parts(rest);
    std::string part;
    std::getline(parts, part, ':');
    const std::vector<double> height = footprint_numbers(part, spec);
    if (height.size() != 1) throw UsageError("option '--footprint': polygon takes HEIGHT:X1,Y1:X2,Y2:X3,Y3...");
    auto* polygon = footprint.mutable_polygon();
    polygon->set_height_m(height[0]);
    while (std::getline(parts, part, ':')) {
      const std::vector<double> xy = footprint_numbers(part, spec);
      if (xy.size() != 2) throw UsageError("option '--footprint': polygon vertex '" + part + "' is not X,Y");
      auto* vertex = polygon->add_vertices();
      vertex->set_x(xy[0]);
      vertex->set_y(xy[1]);
    }
  } else {
    throw UsageError("option '--footprint' takes box:..., cylinder:... or polygon:..., got '" + spec + "'");
  }
  return footprint;
}

v1::Pose2D pose_from(const Options& options) {
  v1::Pose2D pose;
  pose.set_x(options.number("x"));
  pose.set_y(options.number("y"));
  pose.set_theta(options.number("theta", 0.0));
  return pose;
}

}  // namespace occgeo::cli
