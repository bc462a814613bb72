#pragma once
// The hybrid map's other layers made one across sessions: the 2D grid's evidence added, the
// ground trees joined; and both moved with their HMAP (maps/map_merge.hpp).

#include <span>
#include <vector>

#include "hmap/ground/ground_patches.hpp"
#include "hmap/maps/map_merge.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap {

/// eq. (3) across sessions: a cell both grids observed gets the sum of their log-odds (the prior is
/// 0.5, so independent evidence adds), clamped to `into`'s bounds; a cell only `from` observed
/// takes its value. Against one run over both sessions' scans, only where the running sum was
/// clamped on the way can the result differ. Throws hmap::Error when the cell sizes differ.
void add_evidence(OccupancyGrid& into, const OccupancyGrid& from);

/// `grid` moved by `shift` (its z unused), each cell taking the value under its centre moved back
/// (nearest cell), as shifted_map moves the HMAP.
[[nodiscard]] OccupancyGrid shifted_grid(const OccupancyGrid& grid, const PlanarShift& shift);

/// Appends the patches of `from` whose centre lies outside every patch of `into` (in x, y: within
/// its half size); a kept patch whose parent was dropped becomes a root. Returns how many were kept.
std::size_t join_ground(std::vector<GroundPatch>& into, std::span<const GroundPatch> from);

/// The patches moved by `shift`: centres and normals turned and shifted, tree unchanged.
[[nodiscard]] std::vector<GroundPatch> shifted_ground(std::span<const GroundPatch> patches, const PlanarShift& shift);

}  // namespace hmap
