#include "hmap/slam/hmap_slam.hpp"

#include <cmath>

namespace hmap::slam {

Attitude attitude_of(const Pose& T) {
  const Eigen::Matrix3d R = T.linear();
  Attitude a;
  a.z = T.translation().z();
  a.pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  a.roll = std::atan2(R(2, 1), R(2, 2));
  return a;
}

PlanarPose planar_of(const Pose& T) {
  const Eigen::Matrix3d R = T.linear();
  return {T.translation().x(), T.translation().y(), std::atan2(R(1, 0), R(0, 0))};
}

Pose compose(const PlanarPose& xi, const Attitude& attitude) {
  Pose T = Pose::Identity();
  T.linear() = (Eigen::AngleAxisd(xi.yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(attitude.pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(attitude.roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(xi.x, xi.y, attitude.z);
  return T;
}

PlanarPose operator*(const PlanarPose& a, const PlanarPose& b) {
  const double c = std::cos(a.yaw);
  const double s = std::sin(a.yaw);
  return {a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, a.yaw + b.yaw};
}

PlanarPose inverse(const PlanarPose& a) {
  const double c = std::cos(a.yaw);
  const double s = std::sin(a.yaw);
  return {-(c * a.x + s * a.y), s * a.x - c * a.y, -a.yaw};
}

HmapSlam::HmapSlam(const Params& params)
    : params_(params), mapper_(params), matcher_(params), level_hvoxelizer_(params.map) {}

PlanarPose HmapSlam::predict() const {
  if (scans_ < 2) return last_;
  return last_ * (inverse(previous_) * last_);
}

SlamStep HmapSlam::process(std::span<const Point3f> points_sensor, const Attitude& attitude,
                           const std::optional<PlanarPose>& guess) {
  SlamStep step;
  step.guess = guess.value_or(predict());
  PlanarPose estimate = step.guess;
  if (scans_ > 0) {
    // The scan's HVoxels in the gravity-aligned sensor frame (x = y = yaw = 0), so that eq. (6)
    // moves them in the plane only.
    level_hvoxelizer_.build(points_sensor, compose(PlanarPose{}, attitude), scan_level_);
    // The second scan has no motion prior (constant velocity predicts standing still): search.
    const auto search = scans_ == 1 && !guess ? CoarseSearch::kAlways : CoarseSearch::kWhenFailed;
    step.match = matcher_.match(scan_level_, mapper_.map(), step.guess, search);
    step.matched = true;
    estimate = step.match.pose;
  }
  step.T_map_sensor = compose(estimate, attitude);
  step.mapping = mapper_.integrate(points_sensor, step.T_map_sensor);
  previous_ = scans_ > 0 ? last_ : estimate;
  last_ = estimate;
  ++scans_;
  return step;
}

}  // namespace hmap::slam
