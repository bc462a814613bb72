// Fuzzes hmap::read_xyz (src/hmap/io/xyz.hpp): any bytes give points or one hmap::InputError.
#include "fuzz_target.hpp"
#include "hmap/io/xyz.hpp"

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  hmap::fuzz::read_input(data, size, [](const std::filesystem::path& path) {
    hmap::CloudReadStats stats;
    const hmap::PointCloud cloud = hmap::read_xyz(path, &stats);
    hmap::fuzz::check_cloud(cloud, stats);
  });
  return 0;
}
