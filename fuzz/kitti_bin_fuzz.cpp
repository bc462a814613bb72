// Fuzzes hmap::read_kitti_bin (src/hmap/io/kitti.hpp): any bytes give points or one hmap::InputError.
#include "fuzz_target.hpp"
#include "hmap/io/kitti.hpp"

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  hmap::fuzz::read_input(data, size, [](const std::filesystem::path& path) {
    hmap::CloudReadStats stats;
    const hmap::PointCloud cloud = hmap::read_kitti_bin(path, &stats);
    hmap::fuzz::check_cloud(cloud, stats);
  });
  return 0;
}
