#include "pvox_output.hpp"

#include <algorithm>
#include <cmath>
#include <string_view>

#include <fstream>

#include "cli_common.hpp"
#include "hmap/io/atomic_file.hpp"
#include "hmap/io/read_support.hpp"
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

bool is_pvox_file(const std::filesystem::path& path) {
  static constexpr char kMagic[8] = {'\x89', 'P', 'V', 'O', 'X', '\r', '\n', '\x1a'};
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  std::ifstream in(path, std::ios::binary);
  char head[8] = {};
  return in.read(head, 8) && std::equal(head, head + 8, kMagic);
}

pvox::VoxelMap load_pvox_file(const std::filesystem::path& path) {
  const std::string bytes = detail::read_file_bytes(path);
  return pvox::decode_binary(std::span(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()), path.string(),
                             memory_budget());
}

void write_pvox_pictures(const std::filesystem::path& dir, const std::string& prefix, const pvox::VoxelMap& map,
                         const render::PvoxView& view, double gradient_z) {
  write_png(dir / (prefix + "top.png"), render::render_pvox_top(map, view));
  write_png(dir / (prefix + "iso.png"), render::render_pvox_iso(map, view));
  if (std::isfinite(gradient_z)) {
    render::PvoxView flat = view;
    flat.max_pixels = std::min(view.max_pixels, 900);
    write_png(dir / (prefix + "gradient.png"), render::render_pvox_gradient(map, flat, gradient_z));
  }
}

}  // namespace hmap::cli
