#pragma once
// The HMAP as an OctoMap binary tree (.bt) for octovis and the octomap tools.

#include <filesystem>

#include "hmap/maps/hmap.hpp"

namespace hmap::cli {

/// Writes every HVoxel as occupied OctoMap leaves at the map's cell size (each cell's column
/// from z_min to z_max, one leaf per cell-size step), pruned, as a binary tree (.bt), atomically.
/// Returns the number of leaves set.
std::size_t write_octomap_bt(const std::filesystem::path& path, const HMap& map);

}  // namespace hmap::cli
