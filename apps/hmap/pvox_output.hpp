#pragma once
// What `hmap pvox` and `hmap experiment pvox-boxes` write for a PVOX map: the binary map, the
// voxel CSV, optionally the raw points CSV, and the pictures.

#include <cstdint>
#include <filesystem>
#include <string>

#include "hmap/core/types.hpp"
#include "hmap/pvox/voxel_map.hpp"
#include "hmap/render/pvox_render.hpp"

namespace hmap::cli {

struct PvoxFileSizes {
  std::uintmax_t raw_csv = 0;
  std::uintmax_t voxel_csv = 0;
  std::uintmax_t binary = 0;
};

/// Writes DIR/PREFIXmap.pvox and DIR/PREFIXvoxels.csv (and DIR/PREFIXpoints.csv when `raw_points`
/// is given), atomically; returns their sizes.
PvoxFileSizes write_pvox_files(const std::filesystem::path& dir, const std::string& prefix, const pvox::VoxelMap& map,
                               const PointCloud* raw_points);

/// True when `path` begins with the PVOX magic (the file `hmap pvox` writes as map.pvox); false for
/// any other file, including one that cannot be read (its loader then says why).
[[nodiscard]] bool is_pvox_file(const std::filesystem::path& path);
/// Reads a `.pvox` file written by write_pvox_files, checked as pvox::decode_binary checks it, within
/// the run's memory budget; hmap::InputError naming the file otherwise.
[[nodiscard]] pvox::VoxelMap load_pvox_file(const std::filesystem::path& path);

/// Writes DIR/PREFIXtop.png, DIR/PREFIXiso.png and, when `gradient_z` is finite, DIR/PREFIXgradient.png.
void write_pvox_pictures(const std::filesystem::path& dir, const std::string& prefix, const pvox::VoxelMap& map,
                         const render::PvoxView& view, double gradient_z);

}  // namespace hmap::cli
