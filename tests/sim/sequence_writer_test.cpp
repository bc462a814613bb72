// The simulated sequence written by hmap::io loads back with the KITTI readers.

#include "hmap/io/sequence_writer.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <limits>

#include "common/test_data.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/io/pcd.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/sim/builtin_scenes.hpp"
#include "hmap/sim/sensors.hpp"
#include "hmap/sim/trajectory.hpp"

namespace hmap::sim {
namespace {

class SequenceWriter : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::temp_dir("sim_sequence"); }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

TEST_F(SequenceWriter, WrittenSequenceLoadsBack) {
  const Scene scene = make_office_scene();
  Trajectory path = diff_drive_path(office_robot_route(), DiffDriveParams{});
  constexpr std::size_t kFrames = 4;
  path.T_world_sensor.resize(kFrames);
  path.times.resize(kFrames);
  SpinningLidar lidar(SpinningLidarParams::vlp16());
  std::vector<PointCloud> frames;
  for (std::size_t i = 0; i < kFrames; ++i) {
    frames.push_back(lidar.scan(scene, path.T_world_sensor[i], path.times[i]).points_sensor);
  }
  const PoseList odometry = noisy_odometry(path.T_world_sensor, OdometryNoiseParams{});
  std::mt19937_64 rng(1);
  const PointCloud truth = scene.sample_surface(0.2, rng, 0.0);
  write_simulated_sequence(dir_, frames, path.T_world_sensor, path.times, odometry, truth);

  const KittiSequence sequence = open_kitti_sequence(dir_);
  ASSERT_EQ(sequence.scan_paths.size(), kFrames);
  EXPECT_EQ(sequence.scan_paths.front().filename(), "000000.bin");
  ASSERT_TRUE(sequence.T_map_scan.has_value());
  ASSERT_EQ(sequence.times.size(), kFrames);
  for (std::size_t i = 0; i < kFrames; ++i) {
    EXPECT_EQ(read_kitti_bin(sequence.scan_paths[i]), frames[i]);
    EXPECT_TRUE((*sequence.T_map_scan)[i].isApprox(path.T_world_sensor[i], 1e-12));
    EXPECT_EQ(sequence.times[i], path.times[i]);
  }
  const PoseList odometry_read = read_poses(dir_ / "odometry.txt");
  ASSERT_EQ(odometry_read.size(), kFrames);
  EXPECT_TRUE(odometry_read.back().isApprox(odometry.back(), 1e-12));
  EXPECT_TRUE(std::filesystem::exists(dir_ / "truth.ply"));
  EXPECT_GT(std::filesystem::file_size(dir_ / "truth.ply"), truth.size() * 15);
}

TEST_F(SequenceWriter, EmptyCloudAndMismatchedCounts) {
  write_kitti_bin(dir_ / "empty.bin", {});
  EXPECT_TRUE(read_kitti_bin(dir_ / "empty.bin").empty());
  const std::vector<PointCloud> frames(2);
  const PoseList poses(2, Pose::Identity());
  const std::vector<double> times{0.0, 0.1};
  EXPECT_THROW(write_simulated_sequence(dir_ / "a", frames, PoseList(1, Pose::Identity()), times, {}, {}), Error);
  EXPECT_THROW(write_simulated_sequence(dir_ / "b", frames, poses, std::vector<double>{0.0}, {}, {}), Error);
  EXPECT_THROW(write_simulated_sequence(dir_ / "c", frames, poses, times, PoseList(3, Pose::Identity()), {}), Error);
  write_simulated_sequence(dir_ / "d", frames, poses, times, {}, {});
  EXPECT_FALSE(std::filesystem::exists(dir_ / "d" / "odometry.txt"));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "d" / "truth.ply"));
  EXPECT_EQ(open_kitti_sequence(dir_ / "d").scan_paths.size(), 2U);
}

TEST_F(SequenceWriter, SweepsWithPointTimeAreWrittenAsPcdAndReadBack) {
  // hmap simulate --sweep: velodyne/*.pcd with the field t, listed by the KITTI reader, the points
  // and times read back exactly (float in, float out).
  const Scene scene = make_office_scene();
  const Trajectory path = diff_drive_path(office_robot_route(), DiffDriveParams{});
  SpinningLidar lidar(SpinningLidarParams::vlp16());
  std::vector<PointCloud> frames;
  std::vector<std::vector<float>> point_times;
  for (std::size_t i = 0; i < 2; ++i) {
    SimulatedScan s = lidar.sweep(scene, [&](double t) { return pose_at(path, t); }, path.times[i]);
    frames.push_back(std::move(s.points_sensor));
    point_times.push_back(std::move(s.time));
  }
  const PoseList poses(path.T_world_sensor.begin(), path.T_world_sensor.begin() + 2);
  const std::vector<double> times(path.times.begin(), path.times.begin() + 2);
  write_simulated_sequence(dir_, frames, poses, times, {}, {}, point_times);
  const KittiSequence sequence = open_kitti_sequence(dir_);
  ASSERT_EQ(sequence.scan_paths.size(), 2U);
  EXPECT_EQ(sequence.scan_paths.back().filename(), "000001.pcd");
  for (std::size_t i = 0; i < 2; ++i) {
    std::vector<float> t;
    EXPECT_EQ(read_pcd(sequence.scan_paths[i], nullptr, &t), frames[i]);
    EXPECT_EQ(t, point_times[i]);
  }
  EXPECT_THROW(write_simulated_sequence(dir_ / "e", frames, poses, times, {}, {}, std::span(point_times).first(1)), Error);
  EXPECT_THROW(write_pcd_with_time(dir_ / "f.pcd", frames[0], std::span(point_times[0]).first(3)), Error);
  std::vector<float> bad = point_times[0];
  bad[7] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(write_pcd_with_time(dir_ / "g.pcd", frames[0], bad), Error);
  EXPECT_FALSE(std::filesystem::exists(dir_ / "g.pcd"));
}

}  // namespace
}  // namespace hmap::sim
