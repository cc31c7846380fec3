// occgeo's status and query commands: collision, clearance, ptem, raycast, occupancy, swept and window.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cli_common.h"
#include "occgeo/client/option_values.h"
#include "occgeo/proto/labels.h"

namespace occgeo::cli {

namespace {

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

}  // namespace

int run_status(const Options& options) {
  Connection connection = connect_query(options);
  v1::ClientMessage request;
  request.mutable_status();
  request.set_request_id(1);
  const bool detailed = options.switches.contains("detailed");
  request.mutable_status()->set_detailed(detailed);
  const v1::StatusReply status = connection.call(request, 1).status();
  if (options.json) {
    print_json(status);
    return 0;
  }
  std::cout << status.server_version() << ", up " << fmt(status.uptime_s()) << " s, " << status.clients()
            << " client(s)\n";
  std::cout << "robots:\n";
  for (const auto& r : status.robots()) {
    std::cout << "  " << r.id() << " (" << r.model() << ") world " << r.world() << ", "
              << (r.connected() ? "connected" : "offline") << ", pose (" << fmt(r.pose().x()) << ", "
              << fmt(r.pose().y()) << ", " << fmt(r.pose().theta()) << "), scans " << r.scans_ingested() << " ("
              << r.scans_rejected() << " rejected), " << proto::behaviour_label(r.behaviour()) << ": "
              << proto::behaviour_state_label(r.behaviour_state()) << (r.estop() ? ", E-STOP" : "")
              << (r.sensor_stale() ? ", sensors stale" : "");
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
    print_json(reply);
  } else if (reply.hit()) {
    std::cout << "hit (" << proto::model_label(reply.model()) << ") at (" << fmt(reply.contact().x()) << ", "
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
    print_json(reply);
  } else if (reply.found()) {
    std::cout << "clearance " << fmt(reply.clearance_m()) << " m to the " << proto::model_label(reply.model())
              << " at (" << fmt(reply.nearest_point().x()) << ", " << fmt(reply.nearest_point().y()) << ")\n";
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
    print_json(reply);
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
    print_json(reply);
  } else if (result.hit()) {
    std::cout << "hit the " << proto::model_label(result.model()) << " at " << fmt(result.range_m()) << " m\n";
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
    print_json(reply);
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
    print_json(reply);
  } else if (r.hit()) {
    std::cout << "contact with the " << proto::model_label(r.model()) << " after " << fmt(r.time_s()) << " s at ("
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

}  // namespace occgeo::cli
