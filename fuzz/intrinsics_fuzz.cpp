// Fuzzes the small text files of RGB-D folders (src/hmap/io/depth_image.hpp, rgbd.hpp): the same
// bytes as camera intrinsics and as a 7-Scenes 4×4 pose.
#include "fuzz_target.hpp"
#include "hmap/io/depth_image.hpp"
#include "hmap/io/rgbd.hpp"

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  hmap::fuzz::read_input(data, size, [](const std::filesystem::path& path) {
    const hmap::DepthCamera camera = hmap::read_intrinsics(path);
    if (!(camera.fx > 0.0) || !(camera.fy > 0.0) || !std::isfinite(camera.fx) || !std::isfinite(camera.fy) ||
        !std::isfinite(camera.cx) || !std::isfinite(camera.cy)) {
      hmap::fuzz::fail("intrinsics with a focal length that is not positive and finite");
    }
  });
  hmap::fuzz::read_input(data, size, [](const std::filesystem::path& path) {
    const std::optional<hmap::Pose> T = hmap::read_matrix4_pose(path);
    if (T && !T->matrix().allFinite()) hmap::fuzz::fail("non-finite 7-Scenes pose returned");
  });
  return 0;
}
