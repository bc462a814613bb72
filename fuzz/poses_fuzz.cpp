// Fuzzes hmap::read_pose_file (src/hmap/io/poses.hpp): KITTI or TUM trajectories give finite
// rigid poses or one hmap::InputError.
#include "fuzz_target.hpp"
#include "hmap/io/poses.hpp"

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  hmap::fuzz::read_input(data, size, [](const std::filesystem::path& path) {
    const hmap::PoseFile file = hmap::read_pose_file(path);
    if (file.format == hmap::PoseFileFormat::kTum && file.times.size() != file.poses.size()) {
      hmap::fuzz::fail("TUM file with a time count unlike its pose count");
    }
    for (const auto& T : file.poses) {
      if (!T.matrix().allFinite()) hmap::fuzz::fail("non-finite pose returned");
      const Eigen::Matrix3d R = T.linear();
      if (!(R.transpose() * R).isIdentity(1e-6) || std::abs(R.determinant() - 1.0) > 1e-6) {
        hmap::fuzz::fail("pose whose rotation is not a rotation returned");
      }
    }
  });
  return 0;
}
