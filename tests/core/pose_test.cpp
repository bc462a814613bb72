#include "hmap/core/pose.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

std::string message_of(const Eigen::Matrix4d& m) {
  try {
    (void)rigid_pose(m);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(RigidPoseTest, TakesARotationAndTranslation) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  m.topRightCorner<3, 1>() = Eigen::Vector3d(1.5, -2, 3);
  const Pose p = rigid_pose(m);
  EXPECT_TRUE(p.matrix().isApprox(m, 1e-12));
}

TEST(RigidPoseTest, NineDigitRotationIsMadeExactlyOrthonormal) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(0, 0) = 1.0 + 1e-5;  // within the pose files' tolerance of 1e-3
  const Pose p = rigid_pose(m);
  EXPECT_LT((p.linear().transpose() * p.linear() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_NEAR(p.linear()(0, 0), 1.0, 1e-5);
}

TEST(RigidPoseTest, RefusesWhatIsNotRigidSayingWhy) {
  EXPECT_EQ(message_of(Eigen::Vector4d(2, 2, 2, 1).asDiagonal().toDenseMatrix()),
            "pose is not a rigid transform: its 3x3 part is not a rotation (max |RtR - I| = 3, det = 8)");
  EXPECT_EQ(message_of(Eigen::Vector4d(1, 1, -1, 1).asDiagonal().toDenseMatrix()),
            "pose is not a rigid transform: its 3x3 part is not a rotation (max |RtR - I| = 0, det = -1)");
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(3, 2) = 1.0;
  EXPECT_EQ(message_of(m), "pose is not a rigid transform: its last row is 0 0 1 1, not 0 0 0 1");
  m = Eigen::Matrix4d::Identity();
  m(1, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(message_of(m), "pose is not finite (it holds NaN or infinity)");
  m(1, 3) = std::numeric_limits<double>::infinity();
  EXPECT_EQ(message_of(m), "pose is not finite (it holds NaN or infinity)");
}

}  // namespace
}  // namespace hmap
