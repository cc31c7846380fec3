// occgeo's map commands: map export (pgm, png or bt) and cloud insert.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <fstream>
#include <iostream>
#include <numbers>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>
#include "occgeo/client/grid.h"
#include "occgeo/client/option_values.h"
#include "occgeo/mapfile/certainty_image.h"
#include "occgeo/mapfile/map_picture.h"
#include "occgeo/mapping/octomap_model.h"
#include "occgeo/proto/protocol.h"

#include "cli_common.h"

namespace occgeo::cli {

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

}  // namespace occgeo::cli
