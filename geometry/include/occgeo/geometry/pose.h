#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

namespace occgeo::geometry {

// Wraps an angle in radians to (-pi, pi]: the one convention for headings and bearings everywhere (+pi, not -pi, for
// straight behind).
inline double wrap_angle(double a) {
  double wrapped = std::fmod(a + std::numbers::pi, 2.0 * std::numbers::pi);
  if (wrapped < 0) wrapped += 2.0 * std::numbers::pi;
  wrapped -= std::numbers::pi;
  return wrapped <= -std::numbers::pi ? std::numbers::pi : wrapped;
}

// A planar pose: position in metres, heading in radians counter-clockwise from +x. Names of
// variables say which frame it is in, e.g. X_WB is base_link B in world W.
struct Pose2 {
  double x = 0.0;
  double y = 0.0;
  double theta = 0.0;

  // The pose of C in A, given this = X_AB and X_BC.
  [[nodiscard]] Pose2 compose(const Pose2& X_BC) const {
    const double c = std::cos(theta), s = std::sin(theta);
    return {x + c * X_BC.x - s * X_BC.y, y + s * X_BC.x + c * X_BC.y, wrap_angle(theta + X_BC.theta)};
  }
  // The pose of A in B, given this = X_AB.
  [[nodiscard]] Pose2 inverse() const {
    const double c = std::cos(theta), s = std::sin(theta);
    return {-c * x - s * y, s * x - c * y, wrap_angle(-theta)};
  }
  // Maps a point given in this pose's frame into the parent frame.
  [[nodiscard]] Eigen::Vector2d transform(const Eigen::Vector2d& p) const {
    const double c = std::cos(theta), s = std::sin(theta);
    return {x + c * p.x() - s * p.y(), y + s * p.x() + c * p.y()};
  }
  [[nodiscard]] Eigen::Vector2d position() const { return {x, y}; }
};

// A 6-DoF pose: rotation R = Rz(yaw) * Ry(pitch) * Rx(roll), translation in metres.
struct Pose3 {
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();

  static Pose3 from_xyz_rpy(double x, double y, double z, double roll, double pitch, double yaw) {
    Pose3 p;
    p.transform = Eigen::Translation3d(x, y, z) * Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX());
    return p;
  }
  // The same as from_xyz_rpy(x, y, 0, 0, 0, theta), with one sine and cosine instead of three of each: every footprint
  // query against the octree starts here.
  static Pose3 from_pose2(const Pose2& p2) {
    const double c = std::cos(p2.theta), s = std::sin(p2.theta);
    Pose3 p;
    p.transform.linear() << c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0;
    p.transform.translation() = Eigen::Vector3d(p2.x, p2.y, 0.0);
    return p;
  }

  [[nodiscard]] Pose3 compose(const Pose3& X_BC) const { return Pose3{transform * X_BC.transform}; }
  [[nodiscard]] Eigen::Vector3d translation() const { return transform.translation(); }
  // The projection onto the ground plane: x, y and the heading of the frame's x axis.
  [[nodiscard]] Pose2 to_pose2() const {
    const Eigen::Vector3d t = transform.translation();
    const Eigen::Vector3d ax = transform.linear().col(0);
    return {t.x(), t.y(), std::atan2(ax.y(), ax.x())};
  }
};

}  // namespace occgeo::geometry
