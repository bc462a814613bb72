// Issue 17: the ground model is found at the default settings on every real recorded set, and
// the 2D grid the map keeps is not left alone. Runs the built tool on each set of ../shared/data
// (skipped with a message when the folder is absent), then reads the saved map back.

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <sys/wait.h>

#include "common/test_data.hpp"
#include "hmap/io/hmap_file.hpp"

namespace hmap {
namespace {

struct RealSet {
  const char* name;
  const char* folder;       // under the data folder, for HMAP_REQUIRE_DATA
  const char* args;         // input arguments; {D} is the data folder, {ID} an identity pose file
  std::size_t min_patches;  // a ground, not a stray plane: several patches
};

std::string expand(std::string s, const std::string& key, const std::string& value) {
  for (std::size_t at = s.find(key); at != std::string::npos; at = s.find(key, at + value.size())) {
    s.replace(at, key.size(), value);
  }
  return s;
}

class RealSetsGroundTest : public ::testing::TestWithParam<RealSet> {};

TEST_P(RealSetsGroundTest, GroundAndGridAtDefaults) {
  const RealSet& set = GetParam();
  HMAP_REQUIRE_DATA(set.folder);
  const auto dir = test::temp_dir(std::string("realground_") + set.name);
  const std::string poses = (dir / "identity.txt").string();
  std::ofstream(poses) << "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const std::string out = (dir / "m.hmap").string();
  std::string args = expand(expand(set.args, "{D}", test::data_dir().string()), "{ID}", poses);
  const std::string cmd = std::string(HMAP_BIN_PATH) + " map " + args + " --out " + out + " > /dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << cmd;
  const MapFile file = load_map_file(out);
  EXPECT_GE(file.ground.size(), set.min_patches) << set.name << ": ground patches";
  ASSERT_TRUE(file.grid.has_value());
  std::size_t occupied = 0, free_cells = 0;
  file.grid->for_each_cell([&](const CellKey&, float l) { (l > 0.0F ? occupied : free_cells) += 1; });
  EXPECT_GT(free_cells, 50U) << set.name << ": the grid has no free cells";
  EXPECT_GT(occupied, 0U) << set.name << ": the grid has no occupied cells";
  std::filesystem::remove_all(dir);
}

// Figures at the time of writing (docs/HMAP.md): 208, 1120, 9, 13, 12, 43, 90, 8, 92 patches. The Kinect
// files' VIEWPOINT (180° about x) is applied when they are read: their up axis is +y, not the camera's -y.
INSTANTIATE_TEST_SUITE_P(
    Sets, RealSetsGroundTest,
    ::testing::Values(
        RealSet{"kitti_hdl64", "kitti_hdl64_seq16", "{D}/kitti_hdl64_seq16/velodyne/000000.bin --poses {ID}", 50},
        RealSet{"balm_os0", "balm_os0", "--kitti {D}/balm_os0", 200},
        RealSet{"rgbd_7scenes", "rgbd_7scenes", "--rgbd {D}/rgbd_7scenes --preset indoor", 5},
        RealSet{"kinect_office", "kinect_pcd", "{D}/kinect_pcd/office1.pcd --poses {ID} --preset indoor --up y", 5},
        // A grabber frame of a Kinect pitched about 42 degrees down at the floor: no axis is up, the
        // floor plane gives it (and must face the camera above it).
        RealSet{"kinect_grabber_frame", "kinect_pcd",
                "{D}/kinect_pcd/frame_20121214T142255.814212.pcd --poses {ID} --preset indoor --up floor", 5},
        RealSet{"hdl32", "hdl32_pair", "{D}/hdl32_pair/251370668.pcd --poses {ID}", 20},
        RealSet{"eth_car_vtk", "sweeping_laser_eth", "{D}/sweeping_laser_eth/cloud.00000.vtk --poses {ID}", 20},
        RealSet{"eth_apartment_vtk", "sweeping_laser_eth", "{D}/sweeping_laser_eth/cloud_0.vtk --poses {ID}", 5},
        RealSet{"eth_car_csv", "sweeping_laser_eth", "{D}/sweeping_laser_eth/car_cloud400.csv --poses {ID}", 20}),
    [](const ::testing::TestParamInfo<RealSet>& p) { return std::string(p.param.name); });

}  // namespace
}  // namespace hmap
