// Writes the fuzz targets' seed corpus: valid frames and sessions of every message kind, edge cases
// of the framing, short excerpts of each robot log format, configurations and small maps.
// Usage: occgeo_fuzz_corpus SOURCE_DIR (writes SOURCE_DIR/tests/fuzz/corpus/<target>/seed-*).
#include <zlib.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "occgeo/proto/framing.h"
#include "occgeo/proto/protocol.h"
#include "occgeo/v1/session.pb.h"
#include "replay_excerpts.h"
#include "sensor_robot_spec.h"

namespace {

namespace v1 = occgeo::v1;
namespace fs = std::filesystem;

fs::path corpus_root;

void write_seed(const std::string& target, const std::string& name, const std::string& bytes) {
  const fs::path dir = corpus_root / target;
  fs::create_directories(dir);
  std::ofstream out(dir / ("seed-" + name), std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + (dir / name).string());
}

v1::ClientMessage hello(v1::Role role, const std::string& robot_id = {}, const std::string& token = {}) {
  v1::ClientMessage message;
  auto* body = message.mutable_hello();
  body->set_protocol_version(occgeo::proto::kProtocolVersion);
  body->set_role(role);
  body->set_robot_id(robot_id);
  body->set_auth_token(token);
  body->set_client_name("fuzz");
  return message;
}

// A differential-drive robot with a 181-beam laser ("laser") over 180°, 0.05-8 m.
v1::RobotSpec laser_spec() {
  v1::RobotSpec spec;
  spec.set_model("laser-probe");
  auto* drive = spec.mutable_kinematics()->mutable_differential();
  drive->set_wheel_separation_m(0.4);
  drive->set_wheel_radius_m(0.05);
  drive->set_max_wheel_speed_mps(0.5);
  auto* box = spec.mutable_footprint()->mutable_box();
  box->set_length_m(0.6);
  box->set_width_m(0.4);
  box->set_height_m(0.5);
  spec.set_command_timeout_s(0.5);
  auto* sensor = spec.add_sensors();
  sensor->set_name("laser");
  sensor->mutable_mount()->mutable_position()->set_z(0.3);
  auto* laser = sensor->mutable_laser();
  laser->set_angle_min_rad(-M_PI / 2);
  laser->set_angle_increment_rad(M_PI / 180);
  laser->set_beam_count(181);
  laser->set_range_min_m(0.05);
  laser->set_range_max_m(8.0);
  laser->set_scan_period_s(0.1);
  return spec;
}

v1::ClientMessage spec_message(const v1::RobotSpec& spec) {
  v1::ClientMessage message;
  *message.mutable_robot_spec() = spec;
  return message;
}

v1::ClientMessage odometry(std::uint64_t seq, double stamp, double x, double y, double theta) {
  v1::ClientMessage message;
  auto* body = message.mutable_odometry();
  body->set_seq(seq);
  body->set_stamp_s(stamp);
  body->mutable_pose()->set_x(x);
  body->mutable_pose()->set_y(y);
  body->mutable_pose()->set_theta(theta);
  body->set_linear_mps(0.2);
  return message;
}

// A laser scan of a wall 2 m ahead (beams to the sides see nothing).
v1::ClientMessage laser_scan(std::uint64_t seq, double stamp) {
  v1::ClientMessage message;
  auto* body = message.mutable_laser_scan();
  body->set_sensor("laser");
  body->set_seq(seq);
  body->set_stamp_s(stamp);
  for (int k = 0; k < 181; ++k) {
    const double bearing = -M_PI / 2 + k * M_PI / 180;
    const double range = std::abs(std::cos(bearing)) > 0.3 ? 2.0 / std::cos(bearing) : 9.0;
    body->add_ranges(static_cast<float>(range > 0 ? range : 9.0));
  }
  return message;
}

v1::ClientMessage range_array(std::uint64_t seq, double stamp) {
  v1::ClientMessage message;
  auto* body = message.mutable_range_array();
  body->set_sensor("sonar");
  body->set_seq(seq);
  body->set_stamp_s(stamp);
  for (int k = 0; k < occgeo::testing::SensorRobot::kSonarElements; ++k)
    body->add_ranges(1.0F + 0.25F * static_cast<float>(k));
  return message;
}

v1::ClientMessage servo_range(std::uint64_t seq, double stamp) {
  v1::ClientMessage message;
  auto* body = message.mutable_servo_range();
  body->set_sensor("lidar_lite");
  body->set_seq(seq);
  body->set_stamp_s(stamp);
  body->set_servo_angle_rad(0.3);
  body->set_range_m(1.5F);
  return message;
}

v1::ClientMessage wheel_encoders(std::uint64_t seq, double stamp, std::int64_t left, std::int64_t right) {
  v1::ClientMessage message;
  auto* body = message.mutable_wheel_encoders();
  body->set_seq(seq);
  body->set_stamp_s(stamp);
  body->set_left_ticks(left);
  body->set_right_ticks(right);
  return message;
}

v1::ClientMessage point_cloud(std::uint64_t seq, double stamp) {
  v1::ClientMessage message;
  auto* body = message.mutable_point_cloud();
  body->set_sensor("depth");
  body->set_seq(seq);
  body->set_stamp_s(stamp);
  for (int k = 0; k < 16; ++k) {
    body->add_xyz(2.0F);
    body->add_xyz(-0.4F + 0.05F * static_cast<float>(k));
    body->add_xyz(0.1F * static_cast<float>(k % 4));
  }
  return message;
}

v1::ClientMessage collision(const std::string& robot_id, double x, double y) {
  v1::ClientMessage message;
  message.set_request_id(11);
  auto* body = message.mutable_collision();
  body->set_robot_id(robot_id);
  body->mutable_pose()->set_x(x);
  body->mutable_pose()->set_y(y);
  body->add_models(v1::MODEL_GRID);
  body->add_models(v1::MODEL_OCTOMAP);
  body->add_models(v1::MODEL_PTEM);
  return message;
}

v1::ClientMessage collision_with_footprint(const std::string& robot_id) {
  v1::ClientMessage message = collision(robot_id, 1.0, 0.0);
  message.mutable_collision()->mutable_footprint()->mutable_cylinder()->set_radius_m(0.3);
  message.mutable_collision()->mutable_footprint()->mutable_cylinder()->set_height_m(0.4);
  return message;
}

v1::ClientMessage clearance(const std::string& robot_id) {
  v1::ClientMessage message;
  message.set_request_id(12);
  auto* body = message.mutable_clearance();
  body->set_robot_id(robot_id);
  body->mutable_pose()->set_x(0.5);
  body->set_max_distance_m(3.0);
  return message;
}

v1::ClientMessage status() {
  v1::ClientMessage message;
  message.mutable_status();
  message.set_request_id(13);
  return message;
}

v1::ClientMessage grid(const std::string& world) {
  v1::ClientMessage message;
  message.set_request_id(14);
  message.mutable_grid()->set_world(world);
  return message;
}

v1::ClientMessage ptem(const std::string& world) {
  v1::ClientMessage message;
  message.set_request_id(15);
  auto* body = message.mutable_ptem();
  body->set_world(world);
  for (int k = 0; k < 4; ++k) {
    auto* point = body->add_points();
    point->set_x(0.5 * k);
    point->set_y(0.1);
  }
  body->set_include_clusters(true);
  return message;
}

v1::ClientMessage octree(const std::string& world) {
  v1::ClientMessage message;
  message.set_request_id(16);
  message.mutable_octree()->set_world(world);
  return message;
}

v1::ClientMessage lease(const std::string& robot_id, v1::LeaseRequest::Action action, double timeout_s = 0.0) {
  v1::ClientMessage message;
  message.set_request_id(17);
  auto* body = message.mutable_lease();
  body->set_robot_id(robot_id);
  body->set_action(action);
  body->set_timeout_s(timeout_s);
  return message;
}

v1::ClientMessage drive(const std::string& robot_id, v1::Behaviour behaviour, double linear = 0.0,
                        double angular = 0.0) {
  v1::ClientMessage message;
  message.set_request_id(18);
  auto* body = message.mutable_drive();
  body->set_robot_id(robot_id);
  body->set_behaviour(behaviour);
  body->set_linear_mps(linear);
  body->set_angular_radps(angular);
  return message;
}

v1::ClientMessage estop(const std::string& robot_id, bool engage) {
  v1::ClientMessage message;
  message.set_request_id(19);
  auto* body = message.mutable_estop();
  body->set_robot_id(robot_id);
  body->set_engage(engage);
  return message;
}

v1::ClientMessage collision_batch(const std::string& robot_id) {
  v1::ClientMessage message;
  message.set_request_id(20);
  auto* body = message.mutable_collision_batch();
  body->set_robot_id(robot_id);
  for (int k = 0; k < 4; ++k) body->add_poses()->set_x(0.5 * k);
  return message;
}

v1::ClientMessage clearance_batch(const std::string& robot_id) {
  v1::ClientMessage message;
  message.set_request_id(21);
  auto* body = message.mutable_clearance_batch();
  body->set_robot_id(robot_id);
  for (int k = 0; k < 4; ++k) body->add_poses()->set_y(0.5 * k);
  body->set_max_distance_m(2.0);
  return message;
}

v1::ClientMessage raycast(const std::string& world) {
  v1::ClientMessage message;
  message.set_request_id(22);
  auto* body = message.mutable_raycast();
  body->set_world(world);
  for (int k = 0; k < 4; ++k) body->add_rays()->set_theta(0.4 * k);
  body->set_max_range_m(5.0);
  return message;
}

v1::ClientMessage occupancy(const std::string& world) {
  v1::ClientMessage message;
  message.set_request_id(23);
  auto* body = message.mutable_occupancy();
  body->set_world(world);
  for (int k = 0; k < 4; ++k) {
    auto* point = body->add_points();
    point->set_x(0.5 * k);
    point->set_z(0.3);
  }
  return message;
}

v1::ClientMessage swept(const std::string& robot_id) {
  v1::ClientMessage message;
  message.set_request_id(24);
  auto* body = message.mutable_swept();
  body->set_robot_id(robot_id);
  auto* motion = body->add_motions();
  motion->set_linear_mps(0.3);
  motion->set_angular_radps(0.2);
  motion->set_duration_s(2.0);
  auto* path = body->add_motions();
  for (int k = 0; k < 3; ++k) path->add_path()->set_x(0.2 * k);
  path->set_path_dt_s(0.5);
  return message;
}

v1::ClientMessage grid_window(const std::string& world) {
  v1::ClientMessage message;
  message.set_request_id(25);
  auto* body = message.mutable_grid_window();
  body->set_world(world);
  body->mutable_min_corner()->set_x(-1.0);
  body->mutable_min_corner()->set_y(-1.0);
  body->mutable_max_corner()->set_x(3.0);
  body->mutable_max_corner()->set_y(1.0);
  return message;
}

v1::ClientMessage octree_window(const std::string& world) {
  v1::ClientMessage message;
  message.set_request_id(26);
  auto* body = message.mutable_octree_window();
  body->set_world(world);
  body->mutable_min_corner()->set_x(-1.0);
  body->mutable_max_corner()->set_x(3.0);
  body->mutable_max_corner()->set_y(1.0);
  body->mutable_max_corner()->set_z(1.0);
  return message;
}

v1::ClientMessage watch(const std::string& world) {
  v1::ClientMessage message;
  message.set_request_id(35);
  message.mutable_watch()->set_world(world);
  return message;
}

// Every kind of ClientMessage, valid, with a name.
std::vector<std::pair<std::string, v1::ClientMessage>> every_client_message() {
  return {
      {"hello", hello(v1::ROLE_DRIVER, "r1")},
      {"robot_spec", spec_message(laser_spec())},
      {"robot_spec_sensors", spec_message(occgeo::testing::sensor_robot_spec())},
      {"odometry", odometry(1, 1.0, 0.0, 0.0, 0.0)},
      {"laser_scan", laser_scan(1, 1.0)},
      {"range_array", range_array(1, 1.0)},
      {"servo_range", servo_range(1, 1.0)},
      {"wheel_encoders", wheel_encoders(1, 1.0, 100, 120)},
      {"point_cloud", point_cloud(1, 1.0)},
      {"collision", collision("r1", 0.0, 0.0)},
      {"clearance", clearance("r1")},
      {"status", status()},
      {"grid", grid("default")},
      {"ptem", ptem("default")},
      {"octree", octree("default")},
      {"lease", lease("r1", v1::LeaseRequest::ACQUIRE, 5.0)},
      {"drive", drive("r1", v1::BEHAVIOUR_TELEOP, 0.2, 0.1)},
      {"estop", estop("r1", true)},
      {"collision_batch", collision_batch("r1")},
      {"clearance_batch", clearance_batch("r1")},
      {"raycast", raycast("default")},
      {"occupancy", occupancy("default")},
      {"swept", swept("r1")},
      {"grid_window", grid_window("default")},
      {"octree_window", octree_window("default")},
      {"watch", watch("")},
  };
}

std::string frames(const std::vector<v1::ClientMessage>& messages) {
  std::string out;
  for (const auto& message : messages) out += occgeo::proto::encode_frame(message);
  return out;
}

// The server target's records: one session byte, then one frame.
std::string records(const std::vector<std::pair<int, v1::ClientMessage>>& messages) {
  std::string out;
  for (const auto& [session, message] : messages) {
    out += static_cast<char>(session);
    out += occgeo::proto::encode_frame(message);
  }
  return out;
}

void framing_seeds() {
  // Byte 0 picks the frame limit (0: 64 B, 1: 1 KiB, 2: 64 KiB, 3: 4 MiB), byte 1 seeds the piece sizes.
  for (const auto& [name, message] : every_client_message()) {
    write_seed("framing", name, std::string("\x03\x07", 2) + occgeo::proto::encode_frame(message));
  }
  const std::string session = frames({hello(v1::ROLE_DRIVER, "r1"), spec_message(laser_spec()),
                                      odometry(1, 1.0, 0, 0, 0), laser_scan(1, 1.0), laser_scan(2, 1.1)});
  write_seed("framing", "driver_session", std::string("\x02\x2a", 2) + session);
  write_seed("framing", "driver_session_small_limit", std::string("\x00\x05", 2) + session);
  write_seed("framing", "truncated_frame", std::string("\x03\x01", 2) + session.substr(0, session.size() - 7));
  write_seed("framing", "five_byte_prefix", std::string("\x03\x01\xff\xff\xff\xff\x7f", 7));
  write_seed("framing", "unterminated_prefix", std::string("\x03\x01\xff\xff\xff\xff\xff\x01", 8));
  write_seed("framing", "over_limit", std::string("\x01\x01\x80\x10", 4) + std::string(16, 'x'));
  write_seed("framing", "empty_frame", std::string("\x03\x01\x00\x00", 4));
  write_seed("framing", "garbage_body", std::string("\x03\x01\x04\xff\xff\xff\xff", 7));
}

void message_seeds() {
  for (const auto& [name, message] : every_client_message())
    write_seed("messages", "client_" + name, message.SerializeAsString());
  v1::ServerMessage reply;
  reply.mutable_welcome()->set_protocol_version(occgeo::proto::kProtocolVersion);
  reply.mutable_welcome()->set_session_id(7);
  write_seed("messages", "server_welcome", reply.SerializeAsString());
  reply.Clear();
  reply.mutable_error()->set_code(v1::ERROR_INVALID_ARGUMENT);
  reply.mutable_error()->set_field("laser_scan.ranges[17]");
  reply.mutable_error()->set_message("NaN");
  write_seed("messages", "server_error", reply.SerializeAsString());
  reply.Clear();
  reply.set_request_id(11);  // an Error answering a request carries its id on the envelope
  reply.mutable_error()->set_code(v1::ERROR_UNKNOWN_ROBOT);
  reply.mutable_error()->set_field("collision.robot_id");
  reply.mutable_error()->set_message("no robot 'ghost'");
  write_seed("messages", "server_error_answering_request", reply.SerializeAsString());
  reply.Clear();
  reply.mutable_scan_ack()->set_seq(3);
  reply.mutable_scan_ack()->set_world_version(9);
  write_seed("messages", "server_scan_ack", reply.SerializeAsString());
  reply.Clear();
  auto* command = reply.mutable_motion_command();
  command->set_linear_mps(0.2);
  command->set_behaviour(v1::BEHAVIOUR_BEARCAT);
  command->set_state(v1::BEHAVIOUR_STATE_CLEAR);
  write_seed("messages", "server_motion_command", reply.SerializeAsString());
  reply.Clear();
  auto* grid_reply = reply.mutable_grid();
  grid_reply->set_world("default");
  grid_reply->set_cell_size_m(0.1);
  grid_reply->mutable_min_cell()->set_ix(-2);
  grid_reply->mutable_min_cell()->set_iy(-1);
  grid_reply->set_width(4);
  grid_reply->set_height(3);
  grid_reply->set_cells(std::string("\x00\x01\x02\x03\x04\x05\x0f\xff\xff\x03\x02\x01", 12));
  grid_reply->set_occupied_threshold(3);
  grid_reply->set_max_certainty(15);
  reply.set_request_id(14);  // answers grid("default")
  write_seed("messages", "server_grid", reply.SerializeAsString());
  grid_reply->set_width(5);  // cells no longer match width * height
  write_seed("messages", "server_grid_inconsistent", reply.SerializeAsString());
  reply.Clear();
  reply.mutable_status()->add_robots()->set_id("r1");
  reply.mutable_status()->add_worlds()->set_name("default");
  reply.set_request_id(13);
  write_seed("messages", "server_status", reply.SerializeAsString());
  reply.Clear();
  reply.mutable_lease()->set_granted(true);
  reply.mutable_lease()->mutable_holder()->set_session_id(2);
  reply.set_request_id(17);
  write_seed("messages", "server_lease", reply.SerializeAsString());
  reply.Clear();
  reply.mutable_ptem()->add_samples()->set_threat(0.5);
  reply.mutable_ptem()->add_clusters()->set_radius_m(0.3);
  reply.set_request_id(15);
  write_seed("messages", "server_ptem", reply.SerializeAsString());
}

void server_seeds() {
  // Session 0 drives robot r1 (laser), session 1 controls, session 2 queries or drives r2 (sensor robot).
  const std::string r1 = "r1";
  write_seed("server", "laser_driver",
             records({{0, hello(v1::ROLE_DRIVER, r1)},
                      {0, spec_message(laser_spec())},
                      {0, odometry(1, 1.0, 0, 0, 0)},
                      {0, laser_scan(1, 1.0)},
                      {0, odometry(2, 1.1, 0.1, 0, 0.05)},
                      {0, laser_scan(2, 1.1)}}));
  write_seed("server", "sensor_driver",
             records({{2, hello(v1::ROLE_DRIVER, "r2")},
                      {2, spec_message(occgeo::testing::sensor_robot_spec())},
                      {2, wheel_encoders(1, 1.0, 0, 0)},
                      {2, range_array(1, 1.0)},
                      {2, servo_range(2, 1.05)},
                      {2, wheel_encoders(2, 1.1, 40, 44)},
                      {2, point_cloud(3, 1.1)},
                      {2, range_array(4, 1.2)}}));
  write_seed("server", "controller",
             records({{0, hello(v1::ROLE_DRIVER, r1)},
                      {0, spec_message(laser_spec())},
                      {1, hello(v1::ROLE_CONTROLLER)},
                      {1, lease(r1, v1::LeaseRequest::ACQUIRE, 5.0)},
                      {1, drive(r1, v1::BEHAVIOUR_TELEOP, 0.3, 0.2)},
                      {0, odometry(1, 1.0, 0, 0, 0)},
                      {0, laser_scan(1, 1.0)},
                      {1, estop(r1, true)},
                      {1, estop(r1, false)},
                      {1, drive(r1, v1::BEHAVIOUR_BEARCAT)},
                      {1, lease(r1, v1::LeaseRequest::RETAIN)},
                      {1, lease(r1, v1::LeaseRequest::RETURN)}}));
  write_seed("server", "operator_take",
             records({{0, hello(v1::ROLE_DRIVER, r1)},
                      {0, spec_message(laser_spec())},
                      {1, hello(v1::ROLE_CONTROLLER)},
                      {1, lease(r1, v1::LeaseRequest::ACQUIRE)},
                      {2, hello(v1::ROLE_CONTROLLER, {}, "fuzz-operator")},
                      {2, lease(r1, v1::LeaseRequest::TAKE, 2.0)},
                      {2, drive(r1, v1::BEHAVIOUR_STOP)},
                      {1, drive(r1, v1::BEHAVIOUR_TELEOP, 1.0, 0.0)}}));
  write_seed("server", "queries",
             records({{0, hello(v1::ROLE_DRIVER, r1)},
                      {0, spec_message(laser_spec())},
                      {0, odometry(1, 1.0, 0, 0, 0)},
                      {0, laser_scan(1, 1.0)},
                      {2, hello(v1::ROLE_QUERY)},
                      {2, collision(r1, 1.9, 0.0)},
                      {2, collision_with_footprint(r1)},
                      {2, clearance(r1)},
                      {2, status()},
                      {2, grid("default")},
                      {2, ptem("default")},
                      {2, octree("default")},
                      {1, hello(v1::ROLE_OBSERVER)},
                      {1, estop(r1, true)},
                      {1, status()}}));
  write_seed("server", "batch_queries_and_watch",
             records({{2, hello(v1::ROLE_OBSERVER)},
                      {2, watch("")},
                      {0, hello(v1::ROLE_DRIVER, r1)},
                      {0, spec_message(laser_spec())},
                      {0, odometry(1, 1.0, 0, 0, 0)},
                      {0, laser_scan(1, 1.0)},
                      {1, hello(v1::ROLE_QUERY)},
                      {1, collision_batch(r1)},
                      {1, clearance_batch(r1)},
                      {1, raycast("default")},
                      {1, occupancy("default")},
                      {1, swept(r1)},
                      {1, grid_window("default")},
                      {1, octree_window("default")},
                      {0, laser_scan(2, 1.1)}}));
  write_seed("server", "out_of_order",
             records({{0, laser_scan(1, 1.0)},
                      {0, hello(v1::ROLE_DRIVER, r1)},
                      {0, laser_scan(1, 1.0)},
                      {0, hello(v1::ROLE_DRIVER, r1)},
                      {1, hello(v1::ROLE_QUERY)},
                      {1, lease(r1, v1::LeaseRequest::ACQUIRE)},
                      {1, spec_message(laser_spec())},
                      {0, spec_message(laser_spec())},
                      {0, laser_scan(2, 2.0)},
                      {0, laser_scan(1, 1.0)},
                      {0, odometry(1, 3.0, 0, 0, 0)},
                      {0, odometry(2, 2.0, 0, 0, 0)}}));
}

void log_seeds() {
  // Byte 0: 0 CARMEN, 1 DP-SLAM, 2 URG; +4 read back through a file.
  using namespace occgeo::replay::testing;
  write_seed("log_parser", "carmen", std::string(1, '\0') + kCarmenIntelExcerpt);
  write_seed("log_parser", "dpslam", std::string(1, '\1') + kDpslamLoop5Excerpt);
  write_seed("log_parser", "urg", std::string(1, '\2') + kUrg04LxMinesExcerpt);
  write_seed("log_parser", "carmen_file", std::string(1, '\4') + "ODOM 1 2 0.5 0 0 0 10.5 host 10.5\n");
  write_seed("log_parser", "carmen_quirks",
             std::string(1, '\0') +
                 "FLASER 3 1.0 -1.0 81.91 0 0 0 0 0 0 0 host 0\nFLASER 2 nan 1 0 0 0 0 0 0 5 h 5\nFLASER 999999 1\n"
                 "FLASER 3 1 1 1 0 0 0 0 0 0 4 h 4\nPARAM a b c\n# comment\n\n");
  write_seed("log_parser", "dpslam_quirks",
             std::string(1, '\1') + "Laser 2 1 1\nOdometry 1 2\nOdometry 1 2 3\nLaser 3 1 2\nLaser 2 1.5 2.5\n");
  // gzip of a short CARMEN log, through the file path (the gzip magic makes LineSource inflate it).
  const std::string text = "ODOM 0 0 0 0 0 0 1 h 1\nFLASER 3 1 2 3 0 0 0 0 0 0 1.5 h 1.5\n";
  z_stream stream{};
  deflateInit2(&stream, Z_BEST_COMPRESSION, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY);
  std::string gz(256, '\0');
  stream.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(text.data()));
  stream.avail_in = static_cast<uInt>(text.size());
  stream.next_out = reinterpret_cast<Bytef*>(gz.data());
  stream.avail_out = static_cast<uInt>(gz.size());
  deflate(&stream, Z_FINISH);
  gz.resize(stream.total_out);
  deflateEnd(&stream);
  write_seed("log_parser", "carmen_gzip", std::string(1, '\4') + gz);
}

void config_seeds(const fs::path& source_dir) {
  std::ifstream doc(source_dir / "docs" / "CONFIG.md");
  const std::string text((std::istreambuf_iterator<char>(doc)), std::istreambuf_iterator<char>());
  const auto start = text.find("```yaml\n");
  const auto end = text.find("```", start + 8);
  if (start != std::string::npos && end != std::string::npos) {
    write_seed("config", "documented_defaults", text.substr(start + 8, end - start - 8));
  }
  write_seed("config", "small", "listen: 127.0.0.1:7701\nlog_level: warn\nlimits:\n  max_frame_bytes: 65536\n");
  write_seed(
      "config", "ptem_worlds",
      "ptem:\n  construction: cumulative\n  worlds:\n    lab: {construction: single_scan, cluster_distance_m: 0.8}\n");
  write_seed("config", "bad_type", "limits:\n  max_clients: many\n");
  write_seed("config", "unknown_key", "himm:\n  cell_size: 0.1\n");
  write_seed("config", "not_a_mapping", "- a\n- b\n");
}

void map_seeds() {
  // The YAML text, a NUL, then the image (written as map.pgm).
  const std::string yaml =
      "image: map.pgm\nresolution: 0.05\norigin: [-1.0, -2.0, 0.0]\nnegate: 0\n"
      "occupied_thresh: 0.65\nfree_thresh: 0.196\n";
  write_seed("map_file", "p5", yaml + '\0' + "P5\n3 2\n255\n" + std::string("\x00\xfe\xcd\x10\x80\xff", 6));
  write_seed("map_file", "p2", yaml + '\0' + "P2\n# comment\n3 2\n15\n0 15 7\n3 9 1\n");
  write_seed("map_file", "truncated", yaml + '\0' + "P5\n300 200\n255\n" + std::string(10, 'x'));
  write_seed("map_file", "bad_yaml", std::string("image: [\n") + '\0' + "P5\n1 1\n255\n\x01");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: occgeo_fuzz_corpus SOURCE_DIR\n";
    return 2;
  }
  corpus_root = fs::path(argv[1]) / "tests" / "fuzz" / "corpus";
  framing_seeds();
  message_seeds();
  server_seeds();
  log_seeds();
  config_seeds(argv[1]);
  map_seeds();
  std::cout << "seed corpus written to " << corpus_root.string() << "\n";
  return 0;
}
