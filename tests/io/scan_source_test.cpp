// The scan sources of hmap::io (src/hmap/io/scan_source.hpp): files with a pose file, the checks
// of the inputs, the up axis, the budget of a read; every error one line naming its input.

#include "hmap/io/scan_source.hpp"

#include <gtest/gtest.h>

#include <string>

#include "io/io_test_util.hpp"

namespace hmap::test {
namespace {

/// The what() of the E that `f` throws, or a note that it threw something else or nothing.
template <typename E, typename F>
std::string message_of(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("<another exception: ") + e.what() + ">";
  }
  return "<no exception>";
}
#define EXPECT_THROW_MSG(expr, E, part) EXPECT_TRUE(contains(message_of<E>([&] { (void)(expr); }), part))

class ScanSourceTest : public IoTest {
 protected:
  /// Three one-point .xyz scans and a TUM pose file for them (stamps 5, 6, 7; x = 0, 1, 2).
  ScanSourceSpec three_scans() {
    ScanSourceSpec spec;
    for (int k = 0; k < 3; ++k) spec.files.push_back(write("s" + std::to_string(k) + ".xyz", std::to_string(k) + " 2 3\n").string());
    spec.poses = write("poses.txt", "5 0 0 0 0 0 0 1\n6 1 0 0 0 0 0 1\n7 2 0 0 0 0 0 1\n").string();
    return spec;
  }
};

TEST_F(ScanSourceTest, FilesWithATumPoseFileGivePointsPosesAndStamps) {
  const ScanSource src = open_scan_source_without_recordings(three_scans());
  ASSERT_EQ(src.scans.size(), 3u);
  ASSERT_TRUE(src.T_map_scan.has_value());
  EXPECT_EQ(src.stamps, (std::vector<double>{5.0, 6.0, 7.0}));
  EXPECT_EQ((*src.T_map_scan)[2].translation(), Eigen::Vector3d(2, 0, 0));
  EXPECT_TRUE(src.description.empty());
  EXPECT_EQ(src.frames, nullptr);
  CloudReadStats stats;
  const PointCloud cloud = src.read(1, stats);
  ASSERT_EQ(cloud.size(), 1u);
  EXPECT_EQ(cloud[0], Point3f(1, 2, 3));
}

TEST_F(ScanSourceTest, MaxScansCutsTheScansAndThePoses) {
  ScanSourceSpec spec = three_scans();
  spec.max_scans = 2;
  const ScanSource src = open_scan_files(spec);
  EXPECT_EQ(src.scans.size(), 2u);
  EXPECT_EQ(src.T_map_scan->size(), 2u);
  EXPECT_EQ(src.stamps.size(), 2u);
}

TEST_F(ScanSourceTest, UpAxisTurnsEveryPose) {
  ScanSourceSpec spec = three_scans();
  spec.up = "x";  // the world's x becomes the map's z: (2, 0, 0) goes to (0, 0, 2)
  const ScanSource src = open_scan_source_without_recordings(spec);
  EXPECT_TRUE((*src.T_map_scan)[2].translation().isApprox(Eigen::Vector3d(0, 0, 2), 1e-12));
  EXPECT_EQ(src.description, "world up axis x");
  spec.rotation = "1 0 0 0 1 0 0 0 1";
  EXPECT_THROW_MSG(open_scan_source_without_recordings(spec), Error, "give either --up or --rotation, not both");
}

TEST_F(ScanSourceTest, BadInputsAreOneLineEach) {
  ScanSourceSpec spec = three_scans();
  spec.files.pop_back();
  try {
    (void)open_scan_files(spec);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), spec.poses + ": holds 3 poses for 2 scans");
  }
  ScanSourceSpec none;
  EXPECT_THROW_MSG(open_scan_source_without_recordings(none), Error, "no scans: give --kitti DIR or scan files");
  none.poses_required = true;
  none.files = {spec.files[0]};
  EXPECT_THROW_MSG(open_scan_files(none), Error, "no poses: give --poses FILE");
  ScanSourceSpec two = three_scans();
  two.rgbd = dir_.string();
  EXPECT_THROW_MSG(check_one_input(two), Error, "give one input: --kitti DIR, scan files, --rgbd DIR, --tum DIR or --bag FILE");
  ScanSourceSpec rgbd_with_poses;
  rgbd_with_poses.rgbd = dir_.string();
  rgbd_with_poses.poses = "poses.txt";
  EXPECT_THROW_MSG(check_one_input(rgbd_with_poses), Error, "--poses applies to scan files and KITTI folders");
  ScanSourceSpec png;
  png.files = {write("depth.png", "x").string()};
  CloudReadStats stats;
  EXPECT_THROW_MSG((void)open_scan_files(png).read(0, stats), InputError, "a depth image needs its camera");
}

TEST_F(ScanSourceTest, ReadsAreCheckedAgainstTheBudget) {
  ScanSourceSpec spec = three_scans();
  const MemoryBudget tiny{4};  // bytes: less than twice a 6-byte file
  spec.budget = &tiny;
  const ScanSource src = open_scan_files(spec);
  CloudReadStats stats;
  EXPECT_THROW_MSG((void)src.read(0, stats), Error, "s0.xyz: reading the scan needs 1 MiB, more than the memory budget");
}

}  // namespace
}  // namespace hmap::test
