// Fuzzes hmap::read_depth_png (src/hmap/io/depth_image.hpp) and the back-projection of what it
// reads: a 16-bit grayscale image of consistent size, or one hmap::InputError.
#include "fuzz_target.hpp"
#include "hmap/io/depth_image.hpp"

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  hmap::fuzz::read_input(data, size, [](const std::filesystem::path& path) {
    const hmap::DepthImage image = hmap::read_depth_png(path);
    if (image.width <= 0 || image.height <= 0 ||
        image.pixels.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height)) {
      hmap::fuzz::fail("depth image whose size disagrees with its pixels");
    }
    hmap::PointCloud points;
    hmap::CloudReadStats stats;
    hmap::depth_to_points(image, hmap::DepthCamera{}, points, &stats);
    hmap::fuzz::check_cloud(points, stats);
  });
  return 0;
}
