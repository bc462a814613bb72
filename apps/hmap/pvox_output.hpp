#pragma once
// What `hmap pvox` and `hmap experiment pvox-boxes` write for a PVOX map: the binary map, the
// voxel CSV, optionally the raw points CSV, and the pictures.

#include <cstdint>
#include <filesystem>
#include <string>

#include "hmap/core/types.hpp"
#include "pvox_render.hpp"

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

/// Writes DIR/PREFIXtop.png, DIR/PREFIXiso.png and, when `gradient_z` is finite, DIR/PREFIXgradient.png.
void write_pvox_pictures(const std::filesystem::path& dir, const std::string& prefix, const pvox::VoxelMap& map,
                         const PvoxView& view, double gradient_z);

}  // namespace hmap::cli
