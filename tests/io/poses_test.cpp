#include "hmap/io/poses.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "io/io_test_util.hpp"

namespace hmap {
namespace {

using test::contains;
using test::input_error_of;

class PosesTest : public test::IoTest {};

Pose make_pose(double yaw, double pitch, const Eigen::Vector3d& t) {
  Pose pose = Pose::Identity();
  pose.linear() =
      (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  pose.translation() = t;
  return pose;
}

TEST_F(PosesTest, ReadsKittiLines) {
  const auto path = write("poses.txt",
                          "1 0 0 0.5 0 1 0 -1 0 0 1 2\n"
                          "0 -1 0 10 1 0 0 20 0 0 1 30\n");
  const PoseFile file = read_pose_file(path);
  EXPECT_EQ(file.format, PoseFileFormat::kKitti);
  EXPECT_TRUE(file.times.empty());
  ASSERT_EQ(file.poses.size(), 2U);
  EXPECT_TRUE(file.poses[0].linear().isIdentity());
  EXPECT_EQ(file.poses[0].translation(), Eigen::Vector3d(0.5, -1, 2));
  // Second pose: 90° about z.
  EXPECT_TRUE(file.poses[1].linear().isApprox(
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix()));
  EXPECT_EQ(file.poses[1].translation(), Eigen::Vector3d(10, 20, 30));
}

TEST_F(PosesTest, ReadsTumLinesWithTimestamps) {
  const double s = std::sqrt(0.5);
  const auto path = write("traj.tum",
                          "# timestamp tx ty tz qx qy qz qw\n1630577758.5 1 2 3 0 0 0 1\n"
                          "1630577759.0 4 5 6 0 0 " +
                              std::to_string(s) + " " + std::to_string(s) + "\n");
  const PoseFile file = read_pose_file(path);
  EXPECT_EQ(file.format, PoseFileFormat::kTum);
  ASSERT_EQ(file.times.size(), 2U);
  EXPECT_DOUBLE_EQ(file.times[0], 1630577758.5);
  ASSERT_EQ(file.poses.size(), 2U);
  EXPECT_EQ(file.poses[0].translation(), Eigen::Vector3d(1, 2, 3));
  EXPECT_TRUE(file.poses[1].linear().isApprox(
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix(), 1e-6));
  EXPECT_EQ(read_poses(path).size(), 2U);
}

TEST_F(PosesTest, OrthonormalizesNineDigitRotations) {
  // A rotation printed with %.9e, as KITTI does: RᵀR − I is ~1e-9, not 0.
  const Pose pose = make_pose(0.7, 0.1, {1, 2, 3});
  char line[512];
  const Eigen::Matrix4d m = pose.matrix();
  std::snprintf(line, sizeof line, "%.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e\n", m(0, 0),
                m(0, 1), m(0, 2), m(0, 3), m(1, 0), m(1, 1), m(1, 2), m(1, 3), m(2, 0), m(2, 1), m(2, 2),
                m(2, 3));
  const PoseList poses = read_poses(write("poses.txt", line));
  ASSERT_EQ(poses.size(), 1U);
  const Eigen::Matrix3d r = poses[0].linear();
  EXPECT_LT((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_TRUE(r.isApprox(pose.linear(), 1e-8));
}

TEST_F(PosesTest, RoundTripsKittiAndTumExactly) {
  PoseList poses;
  std::vector<double> times;
  for (int i = 0; i < 5; ++i) {
    poses.push_back(make_pose(0.3 * i, -0.05 * i, {0.1 * i, -1.0 / 3.0 * i, 1e-7 * i}));
    times.push_back(1630577758.569490 + 0.5 * i);
  }
  const auto kitti = dir_ / "k.txt";
  write_poses_kitti(kitti, poses);
  const PoseList kitti_back = read_poses(kitti);
  ASSERT_EQ(kitti_back.size(), poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    EXPECT_TRUE(kitti_back[i].matrix().isApprox(poses[i].matrix(), 1e-14)) << i;
  }

  const auto tum = dir_ / "t.txt";
  write_poses_tum(tum, times, poses);
  const PoseFile tum_back = read_pose_file(tum);
  ASSERT_EQ(tum_back.poses.size(), poses.size());
  EXPECT_EQ(tum_back.times, times);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    EXPECT_TRUE(tum_back.poses[i].matrix().isApprox(poses[i].matrix(), 1e-12)) << i;
  }
}

TEST_F(PosesTest, ReadsEmptyFileAsNoPoses) { EXPECT_TRUE(read_poses(write("p.txt", "")).empty()); }

TEST_F(PosesTest, RejectsBadLinesByLineNumber) {
  const std::string good = "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const auto error = [&](const std::string& text) {
    return input_error_of([&] { (void)read_poses(write("poses.txt", text)); });
  };
  EXPECT_TRUE(contains(error(good + good + "1 0 0 0 0 1 0 0 0 0 1 nan\n"),
                       "poses.txt: line 3: value 12 'nan' is not finite"));
  EXPECT_TRUE(contains(error(good + "1 0 0 inf 0 1 0 0 0 0 1 0\n"), "line 2: value 4 'inf' is not finite"));
  EXPECT_TRUE(contains(error(good + "1 0 0 0 0 1 0 0 0 0 1 x\n"), "line 2: value 12 'x' is not a number"));
  EXPECT_TRUE(contains(error(good + "1 0 0 0 0 1 0 0 0 0 1\n"),
                       "line 2: expected 12 values like the first pose line, found 11"));
  EXPECT_TRUE(contains(error("1 2 3\n"), "line 1: expected 12 values (KITTI 3×4 matrix) or 8 (TUM"));
  EXPECT_TRUE(contains(error(good + "2 0 0 0 0 2 0 0 0 0 2 0\n"), "line 2: the 3×3 part is not a rotation"));
  EXPECT_TRUE(contains(error("\n# c\n-1 0 0 0 0 1 0 0 0 0 1 0\n"), "line 3: the 3×3 part is not a rotation"));
  EXPECT_TRUE(
      contains(error("1 0 0 0 0 1 0 0 0 0 1 0\n1 0.01 0 0 0 1 0 0 0 0 1 0\n"), "line 2: the 3×3 part"));
  EXPECT_TRUE(
      contains(error("0 0 0 0 0 0 0 1\n0 0 0 0 0 0 0 2\n"), "line 2: quaternion norm 2.000000 is not 1"));
  EXPECT_TRUE(contains(error("0 0 0 0 0 0 0 0\n"), "line 1: quaternion norm 0.000000 is not 1"));
  EXPECT_TRUE(
      contains(input_error_of([&] { (void)read_poses(dir_ / "absent.txt"); }), "absent.txt: cannot open"));
}

TEST_F(PosesTest, WritersRejectInconsistentInput) {
  PoseList poses(2, Pose::Identity());
  const std::vector<double> one_time = {0.0};
  EXPECT_THROW(write_poses_tum(dir_ / "t.txt", one_time, poses), Error);
  poses[1].translation().x() = std::nan("");
  EXPECT_THROW(write_poses_kitti(dir_ / "k.txt", poses), Error);
  EXPECT_FALSE(std::filesystem::exists(dir_ / "k.txt"));
  EXPECT_TRUE(std::filesystem::is_empty(dir_));  // no temporary file left behind
}

// Stamps for a KITTI file from times.txt beside it (KITTI's layout), none without it, a TUM
// file's own (a times.txt beside it ignored), and a times.txt of another count refused.
TEST_F(PosesTest, StampedPoseFileTakesTimesTxtBesideAKittiFile) {
  const auto kitti = write("poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 1 0 1 0 0 0 0 1 0\n");
  EXPECT_TRUE(read_stamped_pose_file(kitti).times.empty());
  write("times.txt", "# seconds\n1700000000.25\n1700000000.75\n");
  const PoseFile stamped = read_stamped_pose_file(kitti);
  EXPECT_EQ(stamped.times, (std::vector<double>{1700000000.25, 1700000000.75}));
  EXPECT_EQ(stamped.poses.size(), 2U);
  EXPECT_TRUE(read_pose_file(kitti).times.empty());  // the plain reader reads the one file

  const auto tum = write("traj.tum", "3.5 0 0 0 0 0 0 1\n4.5 1 0 0 0 0 0 1\n");
  EXPECT_EQ(read_stamped_pose_file(tum).times, (std::vector<double>{3.5, 4.5}));

  write("times.txt", "0.1\n0.2\n0.3\n");
  const std::string message = input_error_of([&] { (void)read_stamped_pose_file(kitti); });
  EXPECT_TRUE(contains(message, "times.txt")) << message;
  EXPECT_TRUE(contains(message, "3 timestamps for the 2 poses")) << message;
}

TEST(PosesRealData, ReadsBalmPoses) {
  HMAP_REQUIRE_DATA("balm_os0");
  const PoseFile file = read_pose_file(test::data_dir() / "balm_os0" / "poses.txt");
  EXPECT_EQ(file.format, PoseFileFormat::kKitti);
  ASSERT_EQ(file.poses.size(), 80U);
  EXPECT_LT((file.poses[0].matrix() - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff(),
            0.01);  // almost identity
  // 24.8 m of path in total.
  double path_length = 0.0;
  for (std::size_t i = 1; i < file.poses.size(); ++i) {
    path_length += (file.poses[i].translation() - file.poses[i - 1].translation()).norm();
  }
  EXPECT_NEAR(path_length, 24.8, 1.0);
}

}  // namespace
}  // namespace hmap
