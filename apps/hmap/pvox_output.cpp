#include "pvox_output.hpp"

#include <cmath>
#include <string_view>

#include "hmap/io/atomic_file.hpp"
#include "hmap/pvox/serialize.hpp"

namespace hmap::cli {

PvoxFileSizes write_pvox_files(const std::filesystem::path& dir, const std::string& prefix, const pvox::VoxelMap& map,
                               const PointCloud* raw_points) {
  PvoxFileSizes sizes;
  const std::vector<std::uint8_t> binary = pvox::encode_binary(map);
  write_file_atomic(dir / (prefix + "map.pvox"),
                    std::string_view(reinterpret_cast<const char*>(binary.data()), binary.size()));
  sizes.binary = binary.size();
  const std::string voxels = pvox::voxels_csv(map);
  write_file_atomic(dir / (prefix + "voxels.csv"), voxels);
  sizes.voxel_csv = voxels.size();
  if (raw_points != nullptr) {
    const std::string raw = pvox::points_csv(*raw_points);
    write_file_atomic(dir / (prefix + "points.csv"), raw);
    sizes.raw_csv = raw.size();
  }
  return sizes;
}

void write_pvox_pictures(const std::filesystem::path& dir, const std::string& prefix, const pvox::VoxelMap& map,
                         const PvoxView& view, double gradient_z) {
  write_png(dir / (prefix + "top.png"), render_pvox_top(map, view));
  write_png(dir / (prefix + "iso.png"), render_pvox_iso(map, view));
  if (std::isfinite(gradient_z)) {
    PvoxView flat = view;
    flat.max_pixels = std::min(view.max_pixels, 900);
    write_png(dir / (prefix + "gradient.png"), render_pvox_gradient(map, flat, gradient_z));
  }
}

}  // namespace hmap::cli
