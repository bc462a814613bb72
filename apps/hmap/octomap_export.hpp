#pragma once
// The HMAP as an OctoMap binary tree (.bt) for octovis and the octomap tools.

#include <filesystem>

#include "hmap/maps/hmap.hpp"

namespace hmap::cli {

/// Writes every HVoxel as occupied OctoMap leaves at the map's cell size (each cell's column
/// from z_min to z_max, one leaf per cell-size step), pruned, as a binary tree (.bt), atomically.
/// Returns the number of leaves set. Throws hmap::Error, before anything is written, when an
/// HVoxel lies beyond OctoMap's key range (±32768 leaves from the origin on each axis: OctoMap
/// would drop it silently) or when the leaves would need more than `budget`.
std::size_t write_octomap_bt(const std::filesystem::path& path, const HMap& map, const MemoryBudget& budget);

}  // namespace hmap::cli
