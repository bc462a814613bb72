#pragma once
// The HMAP as an OctoMap binary tree (.bt) for octovis and the octomap tools.

#include <filesystem>
#include <span>

#include "hmap/core/budget.hpp"
#include "hmap/ground/ground_patches.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap {

/// What an OctoMap export wrote, counted as liboctomap counts the file it reads back.
struct OctomapExportStats {
  std::size_t occupied_voxels = 0;  ///< distinct occupied voxels of the map's cell size
  std::size_t free_voxels = 0;      ///< distinct free voxels (not occupied) of the map's cell size
  std::size_t leaves = 0;           ///< leaf nodes of the pruned tree (OcTree::getNumLeafNodes)
};

/// Known free space of one grid cell: the vertical band (z_low, z_high] [m], e.g. from the ground
/// up to the robot's height where the 2D grid says free.
struct FreeBand {
  CellKey key;
  double z_low = 0.0;
  double z_high = 0.0;
};

/// The free space an OctoMap user can plan in: where `grid` is free by OctoMap's own rule (p < 0.5,
/// as OcTree::isNodeOccupied reads the leaves), the band from the local ground plane (of `ground`)
/// up to `z_plus` [m] above it (the robot's height, which eq. (4) judged free). Cells without a
/// ground patch within reach are left out; no patches give no bands.
[[nodiscard]] std::vector<FreeBand> free_bands(const OccupancyGrid& grid, std::span<const GroundPatch> ground, double z_plus);

/// Writes every HVoxel as occupied OctoMap leaves at the map's cell size (each cell's column
/// from z_min to z_max, one leaf per cell-size step), pruned, as a binary tree (.bt), atomically.
/// The `free` bands become free leaves (clamped free), except where an HVoxel is. Eight equal
/// siblings are pruned into their parent, so `leaves` is at most the voxels written. Throws hmap::Error, before anything is written, when an
/// HVoxel lies beyond OctoMap's key range (±32768 leaves from the origin on each axis: OctoMap
/// would drop it silently) or when the leaves would need more than `budget`.
OctomapExportStats write_octomap_bt(const std::filesystem::path& path, const HMap& map, std::span<const FreeBand> free,
                                    const MemoryBudget& budget);

}  // namespace hmap
