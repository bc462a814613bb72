#include "hmap/core/pose.hpp"

#include <Eigen/SVD>
#include <cmath>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"

namespace hmap {

Pose rigid_pose(const Eigen::Matrix4d& m) {
  if (!m.allFinite()) throw Error("pose is not finite (it holds NaN or infinity)");
  const double last_row_error = (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff();
  if (last_row_error > 1e-6) {
    throw Error(format("pose is not a rigid transform: its last row is %g %g %g %g, not 0 0 0 1", m(3, 0), m(3, 1),
                       m(3, 2), m(3, 3)));
  }
  const Eigen::Matrix3d rotation = m.topLeftCorner<3, 3>();
  const double orthogonality_error = (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  const double determinant = rotation.determinant();
  // The tolerances of read_poses: 9-digit KITTI files pass.
  if (orthogonality_error > 1e-3 || std::abs(determinant - 1.0) > 1e-2) {
    throw Error(format("pose is not a rigid transform: its 3x3 part is not a rotation (max |RtR - I| = %g, det = %g)",
                       orthogonality_error, determinant));
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(rotation, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Pose pose = Pose::Identity();
  pose.linear() = svd.matrixU() * svd.matrixV().transpose();
  pose.translation() = m.topRightCorner<3, 1>();
  return pose;
}

}  // namespace hmap
