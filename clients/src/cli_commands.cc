// occgeo's commands: status, queries, map export, cloud insert, leases, driving and the e-stop.
#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>
#include "occgeo/client/connection.h"
#include "occgeo/client/grid.h"
#include "occgeo/client/json.h"
#include "occgeo/client/option_values.h"
#include "occgeo/mapfile/certainty_image.h"
#include "occgeo/mapfile/map_picture.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/proto/protocol.h"

#include "cli_commands.h"

namespace occgeo::cli {

using occgeo::client::ClientError;
using occgeo::client::Connection;
using occgeo::client::Endpoint;
namespace v1 = occgeo::v1;

Connection connect_query(const Options& options) {
  Connection connection = Connection::open(Endpoint::parse(options.text("server", "127.0.0.1:7700")));
  v1::Hello hello;
  hello.set_protocol_version(occgeo::proto::kProtocolVersion);
  hello.set_role(v1::ROLE_QUERY);
  hello.set_client_name("occgeo-cli");
  connection.hello(hello);
  return connection;
}

using occgeo::client::json_string;

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

int run_status(const Options& options) {
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  request.mutable_status();
  request.set_request_id(1);
  const bool detailed = options.switches.contains("detailed");
  request.mutable_status()->set_detailed(detailed);
  const v1::StatusReply status = connection.call(request, 1).status();
  const auto json_points = [](const google::protobuf::RepeatedPtrField<v1::Point2D>& points) {
    std::string out = "[";
    for (int k = 0; k < points.size(); ++k) {
      out += (k ? ",[" : "[") + fmt(points[k].x()) + "," + fmt(points[k].y()) + "]";
    }
    return out + "]";
  };
  if (options.json) {
    std::ostringstream out;
    out << "{\"server_version\":" << json_string(status.server_version()) << ",\"clients\":" << status.clients()
        << ",\"uptime_s\":" << fmt(status.uptime_s()) << ",\"robots\":[";
    for (int i = 0; i < status.robots_size(); ++i) {
      const auto& r = status.robots(i);
      out << (i ? "," : "") << "{\"id\":" << json_string(r.id()) << ",\"world\":" << json_string(r.world())
          << ",\"model\":" << json_string(r.model()) << ",\"connected\":" << (r.connected() ? "true" : "false")
          << ",\"pose\":{\"x\":" << fmt(r.pose().x()) << ",\"y\":" << fmt(r.pose().y())
          << ",\"theta\":" << fmt(r.pose().theta()) << "},\"scans_ingested\":" << r.scans_ingested()
          << ",\"scans_rejected\":" << r.scans_rejected() << ",\"behaviour\":" << json_string(r.behaviour())
          << ",\"behaviour_state\":" << json_string(r.behaviour_state())
          << ",\"estop\":" << (r.estop() ? "true" : "false")
          << ",\"sensor_stale\":" << (r.sensor_stale() ? "true" : "false") << ",\"lease_holder\":";
      if (r.has_lease_holder()) {
        out << "{\"session_id\":" << r.lease_holder().session_id()
            << ",\"client_name\":" << json_string(r.lease_holder().client_name())
            << ",\"expires_in_s\":" << fmt(r.lease_expires_in_s()) << "}";
      } else {
        out << "null";
      }
      if (detailed) {
        out << ",\"path\":" << json_points(r.path()) << ",\"scan\":" << json_points(r.scan())
            << ",\"scan_stamp_s\":" << fmt(r.scan_stamp_s());
      }
      out << "}";
    }
    out << "],\"worlds\":[";
    for (int i = 0; i < status.worlds_size(); ++i) {
      const auto& w = status.worlds(i);
      out << (i ? "," : "") << "{\"name\":" << json_string(w.name()) << ",\"cell_size_m\":" << fmt(w.cell_size_m())
          << ",\"version\":" << w.version() << ",\"tiles\":" << w.tiles()
          << ",\"occupied_cells\":" << w.occupied_cells() << ",\"octomap_version\":" << w.octomap_version()
          << ",\"octomap_nodes\":" << w.octomap_nodes() << ",\"octomap_leaves\":" << w.octomap_leaves() << "}";
    }
    out << "]}";
    std::cout << out.str() << "\n";
    return 0;
  }
  std::cout << status.server_version() << ", up " << fmt(status.uptime_s()) << " s, " << status.clients()
            << " client(s)\n";
  std::cout << "robots:\n";
  for (const auto& r : status.robots()) {
    std::cout << "  " << r.id() << " (" << r.model() << ") world " << r.world() << ", "
              << (r.connected() ? "connected" : "offline") << ", pose (" << fmt(r.pose().x()) << ", "
              << fmt(r.pose().y()) << ", " << fmt(r.pose().theta()) << "), scans " << r.scans_ingested() << " ("
              << r.scans_rejected() << " rejected), " << r.behaviour() << ": " << r.behaviour_state()
              << (r.estop() ? ", E-STOP" : "") << (r.sensor_stale() ? ", sensors stale" : "");
    if (r.has_lease_holder()) {
      std::cout << ", lease: session " << r.lease_holder().session_id() << " (" << r.lease_holder().client_name()
                << ")";
    }
    std::cout << "\n";
    if (detailed) {
      std::cout << "    path: " << r.path_size() << " point(s)";
      for (const auto& p : r.path()) std::cout << " (" << fmt(p.x()) << ", " << fmt(p.y()) << ")";
      std::cout << "\n    scan: " << r.scan_size() << " return(s) at " << fmt(r.scan_stamp_s()) << " s\n";
    }
  }
  std::cout << "worlds:\n";
  for (const auto& w : status.worlds()) {
    std::cout << "  " << w.name() << ": " << w.occupied_cells() << " occupied cells of " << fmt(w.cell_size_m())
              << " m in " << w.tiles() << " tiles, version " << w.version() << "; octree " << w.octomap_leaves()
              << " leaves of " << fmt(w.octomap_resolution_m()) << " m, version " << w.octomap_version() << "\n";
  }
  return 0;
}

int run_query_collision(const Options& options) {
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  auto* query = request.mutable_collision();
  request.set_request_id(1);
  query->set_robot_id(options.required("robot"));
  *query->mutable_pose() = pose_from(options);
  for (const v1::Model model : models_from(options)) query->add_models(model);
  if (const auto footprint = footprint_from(options)) *query->mutable_footprint() = *footprint;
  const v1::CollisionReply reply = connection.call(request, 1).collision();
  if (options.json) {
    std::cout << "{\"hit\":" << (reply.hit() ? "true" : "false");
    if (reply.hit()) {
      std::cout << ",\"model\":" << json_string(model_name(reply.model()))
                << ",\"contact\":{\"x\":" << fmt(reply.contact().x()) << ",\"y\":" << fmt(reply.contact().y())
                << ",\"z\":" << fmt(reply.contact().z()) << "}";
      if (reply.has_cell()) {
        std::cout << ",\"cell\":{\"ix\":" << reply.cell().ix() << ",\"iy\":" << reply.cell().iy()
                  << "},\"cell_center\":{\"x\":" << fmt(reply.cell_center().x())
                  << ",\"y\":" << fmt(reply.cell_center().y()) << "}";
      }
    }
    if (reply.keep_out()) {
      std::cout << ",\"keep_out\":true,\"keep_out_point\":{\"x\":" << fmt(reply.keep_out_point().x())
                << ",\"y\":" << fmt(reply.keep_out_point().y()) << "}";
    }
    std::cout << ",\"cells_tested\":" << reply.cells_tested() << "}\n";
  } else if (reply.hit()) {
    std::cout << "hit (" << model_name(reply.model()) << ") at (" << fmt(reply.contact().x()) << ", "
              << fmt(reply.contact().y()) << ", " << fmt(reply.contact().z()) << ")";
    if (reply.has_cell()) std::cout << ": occupied cell (" << reply.cell().ix() << ", " << reply.cell().iy() << ")";
    std::cout << "\n";
  } else {
    std::cout << "free\n";
  }
  if (!options.json && reply.keep_out()) {
    std::cout << "keep-out: reaches into the PTEM's restricted region at (" << fmt(reply.keep_out_point().x()) << ", "
              << fmt(reply.keep_out_point().y()) << ")\n";
  }
  return 0;
}

int run_query_clearance(const Options& options) {
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  auto* query = request.mutable_clearance();
  request.set_request_id(1);
  query->set_robot_id(options.required("robot"));
  *query->mutable_pose() = pose_from(options);
  query->set_max_distance_m(options.number("max-distance", 0.0));
  if (const auto footprint = footprint_from(options)) *query->mutable_footprint() = *footprint;
  for (const v1::Model model : models_from(options)) query->add_models(model);
  const v1::ClearanceReply reply = connection.call(request, 1).clearance();
  if (options.json) {
    std::cout << "{\"clearance_m\":" << fmt(reply.clearance_m()) << ",\"found\":" << (reply.found() ? "true" : "false");
    if (reply.found()) {
      std::cout << ",\"model\":" << json_string(model_name(reply.model()));
      if (reply.has_nearest_cell()) {
        std::cout << ",\"nearest_cell\":{\"ix\":" << reply.nearest_cell().ix()
                  << ",\"iy\":" << reply.nearest_cell().iy() << "}";
      }
      std::cout << ",\"nearest_point\":{\"x\":" << fmt(reply.nearest_point().x())
                << ",\"y\":" << fmt(reply.nearest_point().y()) << "}";
    }
    if (reply.has_restricted_clearance_m()) {
      std::cout << ",\"keep_out\":" << (reply.keep_out() ? "true" : "false")
                << ",\"restricted_clearance_m\":" << fmt(reply.restricted_clearance_m());
    }
    std::cout << "}\n";
  } else if (reply.found()) {
    std::cout << "clearance " << fmt(reply.clearance_m()) << " m to the " << model_name(reply.model()) << " at ("
              << fmt(reply.nearest_point().x()) << ", " << fmt(reply.nearest_point().y()) << ")\n";
  } else {
    std::cout << "clearance at least " << fmt(reply.clearance_m())
              << " m (nothing occupied within the search radius)\n";
  }
  if (!options.json && reply.has_restricted_clearance_m()) {
    if (reply.keep_out()) {
      std::cout << "keep-out: inside the PTEM's restricted region\n";
    } else {
      std::cout << "keep-out: " << fmt(reply.restricted_clearance_m()) << " m to the PTEM's restricted region\n";
    }
  }
  return 0;
}

int run_query_ptem(const Options& options) {
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  auto* query = request.mutable_ptem();
  request.set_request_id(1);
  query->set_world(options.required("world"));
  auto* point = query->add_points();
  point->set_x(options.number("x"));
  point->set_y(options.number("y"));
  const v1::PtemReply reply = connection.call(request, 1).ptem();
  if (reply.samples_size() != 1) throw ClientError("the server answered with no sample for the point");
  const v1::PtemSample& sample = reply.samples(0);
  if (options.json) {
    std::cout << "{\"world\":" << json_string(reply.world()) << ",\"version\":" << reply.version()
              << ",\"threat\":" << fmt(sample.threat()) << ",\"gradient\":{\"x\":" << fmt(sample.gradient().x())
              << ",\"y\":" << fmt(sample.gradient().y())
              << "},\"restricted\":" << (sample.restricted() ? "true" : "false")
              << ",\"threshold_f_r\":" << fmt(reply.threshold_f_r()) << ",\"clusters\":" << reply.cluster_count()
              << ",\"scans\":" << reply.scans() << ",\"construction\":" << json_string(reply.construction()) << "}\n";
  } else {
    std::cout << "threat " << fmt(sample.threat()) << " /m^2 (f_r " << fmt(reply.threshold_f_r()) << "), gradient ("
              << fmt(sample.gradient().x()) << ", " << fmt(sample.gradient().y()) << ") /m^3, "
              << (sample.restricted() ? "restricted" : "not restricted") << "; " << reply.cluster_count()
              << " cluster(s) from " << reply.scans() << " scan(s), " << reply.construction() << "\n";
  }
  return 0;
}

int run_query_raycast(const Options& options) {
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  auto* query = request.mutable_raycast();
  request.set_request_id(1);
  if (options.values.contains("world")) query->set_world(options.required("world"));
  *query->add_rays() = pose_from(options);
  query->set_max_range_m(options.number("max-range"));
  for (const v1::Model model : models_from(options)) query->add_models(model);
  const v1::RaycastReply reply = connection.call(request, 1).raycast();
  if (reply.results_size() != 1) throw ClientError("the server answered with no result for the ray");
  const v1::RaycastResult& result = reply.results(0);
  if (options.json) {
    std::cout << "{\"hit\":" << (result.hit() ? "true" : "false") << ",\"range_m\":" << fmt(result.range_m())
              << ",\"model\":" << json_string(model_name(result.model())) << ",\"per_model\":[";
    for (int i = 0; i < result.per_model_size(); ++i) {
      const v1::RaycastHit& hit = result.per_model(i);
      std::cout << (i > 0 ? "," : "") << "{\"model\":" << json_string(model_name(hit.model()))
                << ",\"hit\":" << (hit.hit() ? "true" : "false") << ",\"range_m\":" << fmt(hit.range_m())
                << ",\"point\":{\"x\":" << fmt(hit.point().x()) << ",\"y\":" << fmt(hit.point().y()) << "}}";
    }
    std::cout << "]}\n";
  } else if (result.hit()) {
    std::cout << "hit the " << model_name(result.model()) << " at " << fmt(result.range_m()) << " m\n";
  } else {
    std::cout << "nothing within " << fmt(result.range_m()) << " m\n";
  }
  return 0;
}

int run_query_occupancy(const Options& options) {
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  auto* query = request.mutable_occupancy();
  request.set_request_id(1);
  if (options.values.contains("world")) query->set_world(options.required("world"));
  auto* point = query->add_points();
  point->set_x(options.number("x"));
  point->set_y(options.number("y"));
  point->set_z(options.number("z", 0.3));
  for (const v1::Model model : models_from(options)) query->add_models(model);
  const v1::OccupancyReply reply = connection.call(request, 1).occupancy();
  if (reply.samples_size() != 1) throw ClientError("the server answered with no sample for the point");
  const v1::OccupancySample& s = reply.samples(0);
  if (options.json) {
    std::cout << "{\"version\":" << reply.version() << ",\"cell\":{\"ix\":" << s.cell().ix()
              << ",\"iy\":" << s.cell().iy() << "},\"observed\":" << (s.observed() ? "true" : "false")
              << ",\"certainty\":" << s.certainty() << ",\"occupied\":" << (s.occupied() ? "true" : "false")
              << ",\"octree_known\":" << (s.octree_known() ? "true" : "false")
              << ",\"octree_probability\":" << fmt(s.octree_probability()) << ",\"threat\":" << fmt(s.threat())
              << ",\"restricted\":" << (s.restricted() ? "true" : "false") << "}\n";
  } else {
    std::cout << "grid certainty " << s.certainty() << (s.occupied() ? " (occupied)" : "")
              << (s.observed() ? "" : " (never observed)") << ", octree "
              << (s.octree_known() ? fmt(s.octree_probability()) : std::string("unknown")) << ", threat "
              << fmt(s.threat()) << (s.restricted() ? " (restricted)" : "") << "\n";
  }
  return 0;
}

int run_query_swept(const Options& options) {
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  auto* query = request.mutable_swept();
  request.set_request_id(1);
  query->set_robot_id(options.required("robot"));
  for (const v1::Model model : models_from(options)) query->add_models(model);
  auto* motion = query->add_motions();
  *motion->mutable_start() = pose_from(options);
  motion->set_linear_mps(options.number("v"));
  motion->set_angular_radps(options.number("w"));
  motion->set_duration_s(options.number("duration"));
  if (const auto footprint = footprint_from(options)) *query->mutable_footprint() = *footprint;
  const v1::SweptReply reply = connection.call(request, 1).swept();
  if (reply.results_size() != 1) throw ClientError("the server answered with no result for the motion");
  const v1::SweptResult& r = reply.results(0);
  if (options.json) {
    std::cout << "{\"hit\":" << (r.hit() ? "true" : "false") << ",\"time_s\":" << fmt(r.time_s())
              << ",\"pose\":{\"x\":" << fmt(r.pose().x()) << ",\"y\":" << fmt(r.pose().y())
              << ",\"theta\":" << fmt(r.pose().theta()) << "}";
    if (r.hit()) {
      std::cout << ",\"model\":" << json_string(model_name(r.model())) << ",\"contact\":{\"x\":" << fmt(r.contact().x())
                << ",\"y\":" << fmt(r.contact().y()) << "}";
    }
    std::cout << "}\n";
  } else if (r.hit()) {
    std::cout << "contact with the " << model_name(r.model()) << " after " << fmt(r.time_s()) << " s at ("
              << fmt(r.pose().x()) << ", " << fmt(r.pose().y()) << ", " << fmt(r.pose().theta()) << ")\n";
  } else {
    std::cout << "free for the whole " << fmt(r.time_s()) << " s\n";
  }
  return 0;
}

int run_query_window(const Options& options) {
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  auto* query = request.mutable_grid_window();
  request.set_request_id(1);
  if (options.values.contains("world")) query->set_world(options.required("world"));
  query->mutable_min_corner()->set_x(options.number("min-x"));
  query->mutable_min_corner()->set_y(options.number("min-y"));
  query->mutable_max_corner()->set_x(options.number("max-x"));
  query->mutable_max_corner()->set_y(options.number("max-y"));
  const double since = options.number("since", 0.0);
  if (since < 0.0 || since != std::floor(since)) throw UsageError("option '--since' takes a version number (>= 0)");
  query->set_since_version(static_cast<std::uint64_t>(since));
  const v1::GridWindowReply reply = connection.call(request, 1, std::chrono::seconds(60)).grid_window();
  std::size_t changed_cells = 0;
  for (const v1::GridBlock& block : reply.changed()) changed_cells += block.cells().size();
  if (options.json) {
    std::cout << "{\"version\":" << reply.version() << ",\"min_cell\":{\"ix\":" << reply.min_cell().ix()
              << ",\"iy\":" << reply.min_cell().iy() << "},\"width\":" << reply.width()
              << ",\"height\":" << reply.height() << ",\"cell_size_m\":" << fmt(reply.cell_size_m());
    if (!reply.cells().empty()) {
      std::cout << ",\"cells\":[";
      for (std::size_t i = 0; i < reply.cells().size(); ++i) {
        std::cout << (i > 0 ? "," : "") << static_cast<unsigned>(static_cast<std::uint8_t>(reply.cells()[i]));
      }
      std::cout << "]";
    }
    std::cout << ",\"changed_blocks\":" << reply.changed_size() << ",\"changed_cells\":" << changed_cells << "}\n";
  } else {
    std::cout << "window " << reply.width() << " x " << reply.height() << " cells from (" << reply.min_cell().ix()
              << ", " << reply.min_cell().iy() << ") at version " << reply.version();
    if (query->since_version() > 0 && reply.cells().empty()) {
      std::cout << ": " << reply.changed_size() << " changed block(s), " << changed_cells << " cells";
    }
    std::cout << "\n";
  }
  return 0;
}

int run_octree_export(const Options& options) {
  const std::string prefix = options.required("out");
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  request.mutable_octree();
  request.set_request_id(1);
  request.mutable_octree()->set_world(options.required("world"));
  const v1::OctreeReply octree = connection.call(request, 1, std::chrono::seconds(60)).octree();
  const std::string path = prefix + ".bt";
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(octree.bt().data(), static_cast<std::streamsize>(octree.bt().size()));
    if (!out) throw ClientError("cannot write " + path);
  }
  if (options.json) {
    std::cout << "{\"bt\":" << json_string(path) << ",\"bytes\":" << octree.bt().size()
              << ",\"resolution_m\":" << fmt(octree.resolution_m()) << ",\"nodes\":" << octree.node_count()
              << ",\"leaves\":" << octree.leaf_count() << ",\"version\":" << octree.version() << "}\n";
  } else {
    std::cout << "wrote " << path << " (" << octree.bt().size() << " bytes, " << octree.node_count() << " nodes, "
              << octree.leaf_count() << " leaves of " << fmt(octree.resolution_m()) << " m, octree version "
              << octree.version() << ")\n";
  }
  return 0;
}

// Largest --scale of a png export: a 1000 x 1000 cell grid is then 16000 pixels a side, 768 MB of RGB.
constexpr std::uint32_t kMaxPictureScale = 16;

// The --scale of a png export: a whole number from 1 to kMaxPictureScale; throws UsageError naming --scale.
std::uint32_t picture_scale(const Options& options) {
  const std::string text = options.text("scale", "1");
  std::size_t used = 0;
  long value = 0;
  try {
    value = std::stol(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || value < 1 || value > static_cast<long>(kMaxPictureScale)) {
    throw UsageError("option '--scale' needs a whole number from 1 to " + std::to_string(kMaxPictureScale) + ", got '" +
                     text + "'");
  }
  return static_cast<std::uint32_t>(value);
}

// The base_link poses of an occgeo-sim --trace-out CSV (header t,x,y,theta, then one line per scan; metres and
// radians). Throws std::runtime_error naming --trajectory, the file and the line at fault.
std::vector<occgeo::mapfile::PicturePose> read_trajectory(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("option '--trajectory': cannot read '" + path + "'");
  const auto fail = [&](std::size_t line_number, const std::string& problem) {
    return std::runtime_error("option '--trajectory': " + path + " line " + std::to_string(line_number) + ": " +
                              problem);
  };
  std::vector<occgeo::mapfile::PicturePose> poses;
  std::string line;
  std::size_t line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line_number == 1) {
      if (line != "t,x,y,theta")
        throw fail(1, "expected the header 't,x,y,theta' (occgeo-sim --trace-out), got '" + line + "'");
      continue;
    }
    if (line.empty()) continue;
    std::vector<double> values;
    std::stringstream fields(line);
    std::string field;
    while (std::getline(fields, field, ',')) {
      const std::optional<double> value = finite_number(field);
      if (!value) throw fail(line_number, "expected 4 numbers t,x,y,theta, got '" + line + "'");
      values.push_back(*value);
    }
    if (values.size() != 4) throw fail(line_number, "expected 4 numbers t,x,y,theta, got '" + line + "'");
    poses.push_back({values[1], values[2], values[3]});
  }
  if (line_number == 0) throw std::runtime_error("option '--trajectory': '" + path + "' is empty");
  return poses;
}

// The restricted disc of one PTEM cluster on its own: where its Gaussian reaches f_r (sigma * sqrt(2 ln(peak / f_r))),
// or its whole circle when no sigma puts f_r on it. Overlapping clusters add up and can restrict more than this.
double restricted_radius(const v1::PtemCluster& cluster, double f_r) {
  if (!cluster.threshold_reachable()) return cluster.radius_m();
  const double sigma = cluster.sigma_m();
  if (!(f_r > 0.0) || !(sigma > 0.0)) return 0.0;
  const double peak = 1.0 / (2.0 * std::numbers::pi * sigma * sigma);
  return peak > f_r ? sigma * std::sqrt(2.0 * std::log(peak / f_r)) : 0.0;
}

// map export --format png: the grid as a picture, with PTEM clusters and a trajectory when asked.
int run_picture_export(const Options& options) {
  const std::string prefix = options.required("out");
  const std::string world = options.required("world");
  const std::uint32_t scale = picture_scale(options);
  occgeo::mapfile::PictureOverlays overlays;
  // Read before connecting so a bad file fails before any network work.
  if (options.values.contains("trajectory")) {
    const auto poses = read_trajectory(options.values.at("trajectory"));
    for (const auto& pose : poses) overlays.trajectory.push_back({pose.x, pose.y});
    if (!poses.empty()) overlays.markers.push_back(poses.back());
  }
  overlays.line_width_px = std::max<std::uint32_t>(1, scale / 2);

  Connection connection = connect_query(options);
  v1::ClientMessage request;
  request.mutable_grid();
  request.set_request_id(1);
  request.mutable_grid()->set_world(world);
  const v1::GridReply grid = connection.call(request, 1, std::chrono::seconds(60)).grid();
  if (grid.width() == 0 || grid.height() == 0) {
    std::cerr << "occgeo: world '" << grid.world() << "' has no cells observed yet; nothing written\n";
    return 1;
  }
  std::size_t clusters = 0;
  if (options.switches.contains("ptem")) {
    v1::ClientMessage ptem_request;
    ptem_request.mutable_ptem();
    ptem_request.set_request_id(2);
    ptem_request.mutable_ptem()->set_world(world);
    ptem_request.mutable_ptem()->set_include_clusters(true);
    const v1::PtemReply ptem = connection.call(ptem_request, 2, std::chrono::seconds(60)).ptem();
    for (const v1::PtemCluster& cluster : ptem.clusters()) {
      overlays.circles.push_back({{cluster.center().x(), cluster.center().y()},
                                  cluster.radius_m(),
                                  restricted_radius(cluster, ptem.threshold_f_r())});
    }
    clusters = static_cast<std::size_t>(ptem.clusters_size());
  }
  occgeo::mapfile::MapPicture picture =
      occgeo::mapfile::render_certainty(occgeo::client::certainty_window(grid), scale);
  occgeo::mapfile::draw_overlays(picture, overlays);
  const std::string path = prefix + ".png";
  picture.write_png(path);
  if (options.json) {
    std::cout << "{\"png\":" << json_string(path) << ",\"width\":" << picture.image.width()
              << ",\"height\":" << picture.image.height() << ",\"scale\":" << scale
              << ",\"cells_width\":" << grid.width() << ",\"cells_height\":" << grid.height();
    // Only what was asked for: a 0 would not tell "no clusters" from "not fetched".
    if (options.switches.contains("ptem")) std::cout << ",\"clusters\":" << clusters;
    if (options.values.contains("trajectory")) std::cout << ",\"trajectory_points\":" << overlays.trajectory.size();
    std::cout << ",\"version\":" << grid.version() << "}\n";
  } else {
    std::cout << "wrote " << path << " (" << picture.image.width() << " x " << picture.image.height()
              << " pixels: " << grid.width() << " x " << grid.height() << " cells of " << fmt(grid.cell_size_m())
              << " m at scale " << scale << ", map version " << grid.version();
    if (options.switches.contains("ptem")) std::cout << ", " << clusters << " PTEM cluster(s)";
    if (options.values.contains("trajectory"))
      std::cout << ", " << overlays.trajectory.size() << " trajectory point(s)";
    std::cout << ")\n";
  }
  return 0;
}

int run_map_export(const Options& options) {
  const std::string format = options.text("format", "pgm");
  if (format == "png") return run_picture_export(options);
  // The picture options draw on the png only; silently ignoring them would hide a mistake.
  for (const char* name : {"trajectory", "scale"}) {
    if (options.values.contains(name)) throw UsageError(std::string("option '--") + name + "' needs --format png");
  }
  if (options.switches.contains("ptem")) throw UsageError("option '--ptem' needs --format png");
  if (format == "bt") return run_octree_export(options);
  if (format != "pgm") throw UsageError("option '--format' takes pgm, png or bt, got '" + format + "'");
  const std::string prefix = options.required("out");
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  request.mutable_grid();
  request.set_request_id(1);
  request.mutable_grid()->set_world(options.required("world"));
  const v1::GridReply grid = connection.call(request, 1, std::chrono::seconds(60)).grid();
  if (grid.width() == 0 || grid.height() == 0) {
    std::cerr << "occgeo: world '" << grid.world() << "' has no cells observed yet; nothing written\n";
    return 1;
  }
  occgeo::mapfile::write_map(prefix, occgeo::mapfile::image_from_certainty(occgeo::client::certainty_window(grid)));
  if (options.json) {
    std::cout << "{\"pgm\":" << json_string(prefix + ".pgm") << ",\"yaml\":" << json_string(prefix + ".yaml")
              << ",\"width\":" << grid.width() << ",\"height\":" << grid.height() << ",\"version\":" << grid.version()
              << "}\n";
  } else {
    std::cout << "wrote " << prefix << ".pgm and " << prefix << ".yaml (" << grid.width() << " x " << grid.height()
              << " cells of " << fmt(grid.cell_size_m()) << " m, map version " << grid.version() << ")\n";
  }
  return 0;
}

// "x,y,z,roll,pitch,yaw" (metres, radians) as a Pose3D; throws UsageError when malformed.
v1::Pose3D pose3_from(const std::string& text) {
  std::vector<double> values;
  std::stringstream list(text);
  std::string item;
  while (std::getline(list, item, ',')) {
    const std::optional<double> value = finite_number(item);
    if (!value) throw UsageError("option '--pose' needs x,y,z,roll,pitch,yaw numbers, got '" + text + "'");
    values.push_back(*value);
  }
  if (values.size() != 6)
    throw UsageError("option '--pose' needs six numbers x,y,z,roll,pitch,yaw, got '" + text + "'");
  v1::Pose3D pose;
  pose.mutable_position()->set_x(values[0]);
  pose.mutable_position()->set_y(values[1]);
  pose.mutable_position()->set_z(values[2]);
  pose.set_roll(values[3]);
  pose.set_pitch(values[4]);
  pose.set_yaw(values[5]);
  return pose;
}

// Points per PointCloud message: 1.2 MB frames, well under the server's default 4 MiB frame limit.
constexpr std::size_t kCloudChunkPoints = 100000;
// The server's default limits.max_sensor_range_m: farther points are dropped here.
constexpr double kCloudMaxRange_m = 200.0;

// Sends a .pcd file as a driver robot whose only sensor is a point cloud mounted at the given pose
// (the robot stands at the world origin, so the mount is the sensor's world pose): the server maps
// it exactly as a depth camera's cloud (grid band and OctoMap with its PCL filters).
int run_cloud_insert(const std::string& file, const Options& options) {
  const v1::Pose3D mount = pose3_from(options.required("pose"));
  const std::string world = options.required("world");
  const std::string robot = options.text("robot", "occgeo-cli-cloud");
  std::vector<Eigen::Vector3f> points;
  std::size_t dropped = 0;
  double farthest = 0.0;
  for (const Eigen::Vector3f& p : occgeo::mapping::read_pcd_points(file)) {
    const double range = p.cast<double>().norm();
    if (!p.allFinite() || range > kCloudMaxRange_m) {
      ++dropped;
      continue;
    }
    farthest = std::max(farthest, range);
    points.push_back(p);
  }
  if (points.empty()) throw ClientError(file + " holds no finite point within " + fmt(kCloudMaxRange_m) + " m");

  Connection connection = Connection::open(Endpoint::parse(options.text("server", "127.0.0.1:7700")));
  v1::Hello hello;
  hello.set_protocol_version(occgeo::proto::kProtocolVersion);
  hello.set_role(v1::ROLE_DRIVER);
  hello.set_robot_id(robot);
  hello.set_world(world);
  hello.set_client_name("occgeo-cli");
  connection.hello(hello);

  v1::ClientMessage spec_message;
  v1::RobotSpec& spec = *spec_message.mutable_robot_spec();
  spec.set_model("occgeo-cli-cloud");
  auto* drive = spec.mutable_kinematics()->mutable_differential();
  drive->set_wheel_separation_m(0.2);
  drive->set_wheel_radius_m(0.05);
  drive->set_max_wheel_speed_mps(0.1);
  auto* box = spec.mutable_footprint()->mutable_box();
  box->set_length_m(0.2);
  box->set_width_m(0.2);
  box->set_height_m(2.0);  // the 2D grid takes the cloud's points between 0.05 m and this height
  spec.set_command_timeout_s(1.0);
  auto* sensor = spec.add_sensors();
  sensor->set_name("cloud");
  *sensor->mutable_mount() = mount;
  sensor->mutable_point_cloud()->set_range_max_m(std::min(kCloudMaxRange_m, farthest + 0.01));
  sensor->mutable_point_cloud()->set_max_points(static_cast<std::uint32_t>(std::min(points.size(), kCloudChunkPoints)));
  connection.send(spec_message);

  v1::ClientMessage odometry;
  odometry.mutable_odometry()->set_seq(1);
  odometry.mutable_odometry()->set_stamp_s(0.0);
  odometry.mutable_odometry()->mutable_pose();
  connection.send(odometry);

  std::uint64_t seq = 0;
  std::uint64_t version = 0;
  for (std::size_t first = 0; first < points.size(); first += kCloudChunkPoints) {
    const std::size_t last = std::min(points.size(), first + kCloudChunkPoints);
    v1::ClientMessage message;
    auto* cloud = message.mutable_point_cloud();
    cloud->set_sensor("cloud");
    cloud->set_seq(++seq);
    cloud->set_stamp_s(0.0);
    cloud->mutable_xyz()->Reserve(static_cast<int>(3 * (last - first)));
    for (std::size_t i = first; i < last; ++i) {
      cloud->add_xyz(points[i].x());
      cloud->add_xyz(points[i].y());
      cloud->add_xyz(points[i].z());
    }
    connection.send(message);
    // The ScanAck says the maps hold it; any error (the spec's or this cloud's) stops here.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (true) {
      const auto now = std::chrono::steady_clock::now();
      if (now >= deadline) throw ClientError("timed out waiting for the server to take cloud " + std::to_string(seq));
      auto reply = connection.receive(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now));
      if (!reply) continue;
      if (reply->has_error()) throw ClientError(occgeo::client::describe(reply->error()));
      if (reply->has_scan_ack() && reply->scan_ack().seq() == seq) {
        version = reply->scan_ack().world_version();
        break;
      }
    }
  }
  connection.close();
  if (options.json) {
    std::cout << "{\"points\":" << points.size() << ",\"dropped\":" << dropped << ",\"messages\":" << seq
              << ",\"world\":" << json_string(world) << ",\"world_version\":" << version << "}\n";
  } else {
    std::cout << "sent " << points.size() << " points of " << file << " in " << seq << " message(s) to world '" << world
              << "' (" << dropped << " non-finite or beyond " << fmt(kCloudMaxRange_m) << " m dropped), world version "
              << version << "\n";
  }
  return 0;
}

Connection connect_role(const Options& options, v1::Role role) {
  Connection connection = Connection::open(Endpoint::parse(options.text("server", "127.0.0.1:7700")));
  v1::Hello hello;
  hello.set_protocol_version(occgeo::proto::kProtocolVersion);
  hello.set_role(role);
  hello.set_client_name("occgeo-cli");
  hello.set_auth_token(options.text("token"));
  connection.hello(hello);
  return connection;
}

v1::LeaseReply lease_call(Connection& connection, const std::string& robot, v1::LeaseRequest::Action action,
                          double timeout_s, std::uint64_t request_id) {
  v1::ClientMessage request;
  auto* lease = request.mutable_lease();
  request.set_request_id(request_id);
  lease->set_robot_id(robot);
  lease->set_action(action);
  lease->set_timeout_s(timeout_s);
  return connection.call(request, request_id).lease();
}

std::string holder_text(const v1::LeaseReply& reply) {
  if (!reply.has_holder()) return "nobody";
  return "session " + std::to_string(reply.holder().session_id()) + " (" + reply.holder().client_name() + ")";
}

std::string lease_json(const v1::LeaseReply& reply) {
  std::string out =
      "{\"robot\":" + json_string(reply.robot_id()) + ",\"granted\":" + (reply.granted() ? "true" : "false");
  if (reply.has_holder()) {
    out += ",\"holder\":{\"session_id\":" + std::to_string(reply.holder().session_id()) +
           ",\"client_name\":" + json_string(reply.holder().client_name()) + "}";
  } else {
    out += ",\"holder\":null";
  }
  return out + ",\"expires_in_s\":" + fmt(reply.expires_in_s()) + "}";
}

// Refusals (lease held by another session) print the holder and exit 1.
void require_granted(const v1::LeaseReply& reply, const std::string& what) {
  if (!reply.granted()) {
    throw ClientError(what + " of robot '" + reply.robot_id() + "' refused: the lease is held by " +
                      holder_text(reply));
  }
}

int run_lease(const std::string& verb, const Options& options) {
  v1::LeaseRequest::Action action = v1::LeaseRequest::ACTION_UNSPECIFIED;
  if (verb == "acquire") action = v1::LeaseRequest::ACQUIRE;
  if (verb == "retain") action = v1::LeaseRequest::RETAIN;
  if (verb == "return") action = v1::LeaseRequest::RETURN;
  if (verb == "take") action = v1::LeaseRequest::TAKE;
  if (action == v1::LeaseRequest::ACTION_UNSPECIFIED) {
    throw UsageError("lease takes acquire, retain, return or take, got '" + verb + "'");
  }
  const std::string robot = options.required("robot");
  const double timeout_s = options.number("timeout", 0.0);
  Connection connection = connect_role(options, v1::ROLE_CONTROLLER);
  const v1::LeaseReply reply = lease_call(connection, robot, action, timeout_s, 1);
  if (options.json) {
    std::cout << lease_json(reply) << "\n";
  } else if (reply.granted()) {
    std::cout << verb << " granted: robot " << robot << " held by " << holder_text(reply) << " for "
              << fmt(reply.expires_in_s()) << " s\n";
  } else {
    std::cout << verb << " refused: robot " << robot << " held by " << holder_text(reply) << "\n";
  }
  // A lease belongs to its session: this one ends now, so a granted acquire or take lasts only until the server
  // sees the connection close (the robot is then stopped). Use `occgeo drive` to hold a lease.
  connection.close();
  return reply.granted() ? 0 : 1;
}

// occgeo drive --robot ID BEHAVIOUR [options]: the behaviour is the one bare word.
int run_drive(const std::vector<std::string>& words, const Options& options) {
  if (words.size() > 1) throw UsageError("drive takes one behaviour, got '" + words[0] + "' and '" + words[1] + "'");
  const std::string behaviour = words.empty() ? std::string() : words[0];
  if (behaviour != "bearcat" && behaviour != "bearcat_seed" && behaviour != "stop" && behaviour != "teleop" &&
      behaviour != "wander") {
    throw UsageError("drive needs a behaviour: bearcat, bearcat_seed, wander, stop or teleop");
  }
  const std::string robot = options.required("robot");
  const double v = options.number("v", 0.0);
  const double w = options.number("w", 0.0);
  if (behaviour != "teleop" && (options.values.contains("v") || options.values.contains("w"))) {
    throw UsageError("options '--v' and '--w' need the teleop behaviour");
  }
  const double hold_s = options.number("hold", 0.0);
  if (hold_s < 0.0 || hold_s > 86400.0) throw UsageError("option '--hold' takes 0 to 86400 seconds");
  const double timeout_s = options.number("timeout", 0.0);

  Connection connection = connect_role(options, v1::ROLE_CONTROLLER);
  std::uint64_t id = 0;
  const v1::LeaseReply acquired = lease_call(connection, robot, v1::LeaseRequest::ACQUIRE, timeout_s, ++id);
  require_granted(acquired, "acquire");
  v1::ClientMessage request;
  auto* drive = request.mutable_drive();
  request.set_request_id(++id);
  drive->set_robot_id(robot);
  drive->set_behaviour(behaviour);
  drive->set_linear_mps(v);
  drive->set_angular_radps(w);
  const v1::DriveReply reply = connection.call(request, id).drive();
  // Retain at a third of the lease's timeout so one late retain never lets it lapse.
  const double period_s = std::clamp(acquired.expires_in_s() / 3.0, 0.05, 1.0);
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(hold_s);
  std::uint64_t retains = 0;
  while (std::chrono::steady_clock::now() < end) {
    const auto left = std::chrono::duration<double>(end - std::chrono::steady_clock::now()).count();
    std::this_thread::sleep_for(std::chrono::duration<double>(std::min(period_s, std::max(0.0, left))));
    if (std::chrono::steady_clock::now() >= end) break;
    require_granted(lease_call(connection, robot, v1::LeaseRequest::RETAIN, timeout_s, ++id), "retain");
    ++retains;
  }
  const v1::LeaseReply returned = lease_call(connection, robot, v1::LeaseRequest::RETURN, 0.0, ++id);
  connection.close();
  if (options.json) {
    std::cout << "{\"robot\":" << json_string(robot) << ",\"behaviour\":" << json_string(reply.behaviour())
              << ",\"linear_mps\":" << fmt(reply.linear_mps()) << ",\"angular_radps\":" << fmt(reply.angular_radps())
              << ",\"estop\":" << (reply.estop() ? "true" : "false") << ",\"held_s\":" << fmt(hold_s)
              << ",\"retains\":" << retains << ",\"returned\":" << (returned.granted() ? "true" : "false") << "}\n";
  } else {
    std::cout << "robot " << robot << ": " << reply.behaviour();
    if (reply.behaviour() == "teleop") {
      std::cout << " at " << fmt(reply.linear_mps()) << " m/s, " << fmt(reply.angular_radps()) << " rad/s";
    }
    std::cout << (reply.estop() ? " (e-stop engaged: the robot stays stopped)" : "") << ", held " << fmt(hold_s)
              << " s, lease " << (returned.granted() ? "returned" : "lost") << "\n";
  }
  return returned.granted() ? 0 : 1;
}

// Set by SIGINT/SIGTERM while a goal is being followed: the lease is returned before exiting.
volatile std::sig_atomic_t g_interrupted = 0;

extern "C" void on_interrupt(int /*signal*/) { g_interrupted = 1; }

// occgeo goto --robot ID X Y: the two bare words are the goal; negative numbers are goal values, not options.
// occgeo waypoints --robot ID X1,Y1 X2,Y2 ...: each bare word is one waypoint.
int run_goto(bool waypoints, const std::vector<std::string>& goal, const Options& options) {
  const auto number = [](const std::string& text, const std::string& what) {
    const std::optional<double> value = finite_number(text);
    if (!value) throw UsageError(what + " needs a number, got '" + text + "'");
    return *value;
  };
  std::vector<std::pair<double, double>> points;
  if (waypoints) {
    if (goal.empty()) throw UsageError("waypoints needs at least one X,Y (metres, world frame)");
    for (const std::string& word : goal) {
      const auto comma = word.find(',');
      if (comma == std::string::npos) throw UsageError("waypoint '" + word + "' must be X,Y");
      points.emplace_back(number(word.substr(0, comma), "waypoint '" + word + "' X"),
                          number(word.substr(comma + 1), "waypoint '" + word + "' Y"));
    }
  } else {
    if (goal.size() != 2) throw UsageError("goto needs the goal as two numbers X Y (metres, world frame)");
    points.emplace_back(number(goal[0], "goto's X"), number(goal[1], "goto's Y"));
  }
  const double goal_x = points.back().first;
  const double goal_y = points.back().second;
  const std::string robot = options.required("robot");
  const double limit_s = options.number("limit", 600.0);
  if (!(limit_s > 0.0 && limit_s <= 86400.0)) throw UsageError("option '--limit' takes (0, 86400] seconds");
  const double timeout_s = options.number("timeout", 0.0);

  Connection connection = connect_role(options, v1::ROLE_CONTROLLER);
  std::uint64_t id = 0;
  const v1::LeaseReply acquired = lease_call(connection, robot, v1::LeaseRequest::ACQUIRE, timeout_s, ++id);
  require_granted(acquired, "acquire");
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);
  v1::ClientMessage request;
  auto* drive = request.mutable_drive();
  request.set_request_id(++id);
  drive->set_robot_id(robot);
  drive->set_behaviour(waypoints ? "waypoints" : "goto");
  drive->set_escape(!options.switches.contains("no-escape"));
  if (waypoints) {
    for (const auto& [x, y] : points) {
      auto* waypoint = drive->add_waypoints();
      waypoint->set_x_m(x);
      waypoint->set_y_m(y);
    }
  } else {
    drive->mutable_goal()->set_x_m(goal_x);
    drive->mutable_goal()->set_y_m(goal_y);
  }
  static_cast<void>(connection.call(request, id).drive());

  // Retain at a third of the lease's timeout so one late retain never lets it lapse; each retain also reads the
  // robot's status for the progress line.
  const double period_s = std::clamp(acquired.expires_in_s() / 3.0, 0.05, 0.5);
  const auto started = std::chrono::steady_clock::now();
  const auto elapsed_s = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  };
  std::string outcome = "limit";
  std::string last_state;
  v1::RobotStatus last;
  double next_print_s = 0.0;
  while (elapsed_s() < limit_s) {
    if (g_interrupted) {
      outcome = "interrupted";
      break;
    }
    v1::ClientMessage status_request;
    status_request.mutable_status();
    status_request.set_request_id(++id);
    const v1::StatusReply status = connection.call(status_request, id).status();
    const auto it = std::find_if(status.robots().begin(), status.robots().end(),
                                 [&](const v1::RobotStatus& r) { return r.id() == robot; });
    if (it == status.robots().end()) throw ClientError("robot '" + robot + "' is no longer registered");
    last = *it;
    const double distance = std::hypot(goal_x - last.pose().x(), goal_y - last.pose().y());
    if (!options.json && (last.behaviour_state() != last_state || elapsed_s() >= next_print_s)) {
      std::cout << "t=" << fmt(elapsed_s()) << "s pose (" << fmt(last.pose().x()) << ", " << fmt(last.pose().y())
                << ") " << fmt(distance) << " m to go, " << last.behaviour_state()
                << (last.guard().action().empty() || last.guard().action() == "pass"
                        ? ""
                        : ", guard " + last.guard().action() + " (" + last.guard().zone() + ", " +
                              last.guard().model() + ")")
                << std::endl;
      next_print_s = elapsed_s() + 1.0;
      last_state = last.behaviour_state();
    }
    if (last.behaviour() == drive->behaviour() &&
        (last.behaviour_state() == "reached" || last.behaviour_state() == "no_path")) {
      outcome = last.behaviour_state();
      break;
    }
    if (!last.connected()) {
      outcome = "disconnected";
      break;
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(period_s));
    require_granted(lease_call(connection, robot, v1::LeaseRequest::RETAIN, timeout_s, ++id), "retain");
  }
  const v1::LeaseReply returned = lease_call(connection, robot, v1::LeaseRequest::RETURN, 0.0, ++id);
  connection.close();
  const double distance = std::hypot(goal_x - last.pose().x(), goal_y - last.pose().y());
  if (options.json) {
    std::cout << "{\"robot\":" << json_string(robot) << ",\"outcome\":" << json_string(outcome)
              << ",\"x\":" << fmt(last.pose().x()) << ",\"y\":" << fmt(last.pose().y())
              << ",\"distance_to_goal_m\":" << fmt(distance) << ",\"wall_s\":" << fmt(elapsed_s())
              << ",\"returned\":" << (returned.granted() ? "true" : "false") << "}\n";
  } else {
    std::cout << "robot " << robot << ": " << outcome << " at (" << fmt(last.pose().x()) << ", " << fmt(last.pose().y())
              << "), " << fmt(distance) << " m from the goal, lease " << (returned.granted() ? "returned" : "lost")
              << "\n";
  }
  if (outcome == "reached") return 0;
  return outcome == "interrupted" ? 130 : 1;
}

int run_estop(const Options& options) {
  const std::string robot = options.required("robot");
  const bool release = options.switches.contains("release");
  // Engaging needs no lease (any observer may); releasing is for the lease holder only.
  Connection connection = connect_role(options, release ? v1::ROLE_CONTROLLER : v1::ROLE_OBSERVER);
  std::uint64_t id = 0;
  if (release) require_granted(lease_call(connection, robot, v1::LeaseRequest::ACQUIRE, 0.0, ++id), "acquire");
  v1::ClientMessage request;
  auto* estop = request.mutable_estop();
  request.set_request_id(++id);
  estop->set_robot_id(robot);
  estop->set_engage(!release);
  const v1::EStopReply reply = connection.call(request, id).estop();
  if (release) lease_call(connection, robot, v1::LeaseRequest::RETURN, 0.0, ++id);
  connection.close();
  if (options.json) {
    std::cout << "{\"robot\":" << json_string(robot) << ",\"engaged\":" << (reply.engaged() ? "true" : "false")
              << "}\n";
  } else {
    std::cout << "robot " << robot << ": e-stop " << (reply.engaged() ? "engaged" : "released") << "\n";
  }
  return 0;
}

}  // namespace occgeo::cli
