#include "hmap/slam/deskew.hpp"

#include <Eigen/Geometry>
#include <cmath>

#include "hmap/core/error.hpp"

namespace hmap::slam {

namespace {

Eigen::Matrix3d hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d W;
  W << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return W;
}

/// The left Jacobian V of SO(3): the translation of Exp([ω, v]) is V·v.
Eigen::Matrix3d left_jacobian(const Eigen::Vector3d& w) {
  const double a = w.norm();
  const Eigen::Matrix3d W = hat(w);
  if (a < 1e-8) return Eigen::Matrix3d::Identity() + 0.5 * W;
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(a)) / (a * a) * W + (a - std::sin(a)) / (a * a * a) * W * W;
}

}  // namespace

Pose exp_twist(const Twist& xi, double tau) {
  const Eigen::Vector3d w = tau * xi.angular;
  const double a = w.norm();
  Pose T = Pose::Identity();
  if (a > 1e-15) T.linear() = Eigen::AngleAxisd(a, w / a).toRotationMatrix();
  T.translation() = left_jacobian(w) * (tau * xi.linear);
  return T;
}

Twist twist_between(const Pose& T_a, const Pose& T_b, double dt) {
  Twist xi;
  if (!(dt > 0.0)) return xi;
  const Pose T_ab = T_a.inverse() * T_b;
  const Eigen::AngleAxisd aa(T_ab.linear());
  const Eigen::Vector3d w = aa.angle() * aa.axis();
  xi.angular = w / dt;
  xi.linear = left_jacobian(w).inverse() * T_ab.translation() / dt;
  return xi;
}

void deskew(std::span<const Point3f> points_sensor, std::span<const float> times_s, const Twist& velocity,
            PointCloud& points_out, double reference_s) {
  if (points_sensor.size() != times_s.size()) {
    throw Error("deskew: " + std::to_string(points_sensor.size()) + " points but " + std::to_string(times_s.size()) +
                " times");
  }
  points_out.resize(points_sensor.size());
  // Exp(τ·ξ) per point: the rotation by Rodrigues on the fly (no table: times are arbitrary).
  for (std::size_t i = 0; i < points_sensor.size(); ++i) {
    const Pose T = exp_twist(velocity, static_cast<double>(times_s[i]) - reference_s);
    points_out[i] = (T * points_sensor[i].cast<double>()).cast<float>();
  }
}

}  // namespace hmap::slam
