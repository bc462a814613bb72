#pragma once
// The 2.5D map seen through the HMAP's tools: as an HMap (one flat HVoxel per cell) for the RRT
// ground extraction and the renderers, and the 2D occupancy grid of pipeline [9] judged against
// a ground model.

#include "hmap/baseline/elevation_map.hpp"
#include "hmap/ground/ground_patches.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap {

/// The elevation map as an HMap with the map's parameters: one HVoxel [elevation, elevation] per
/// observed cell, its count the cell's points and its density eq. (1) of that count.
[[nodiscard]] HMap as_hmap(const ElevationMap& map);

/// How one elevation cell counts for the 2D grid. A 2.5D map has no z+ / z−: it cannot tell an
/// overhang from a wall, so anything not at ground level is in the way.
enum class ElevationRole : std::uint8_t {
  kGround,    ///< within d_pth of the local ground: free
  kObstacle,  ///< higher than d_pth above it, at any height (walls, but also table tops, crowns)
  kDrop,      ///< lower than d_pth below it (a step down, a pit, below z− or not)
};

/// The role of a cell of elevation `elevation` [m] over a local ground at `ground_z` [m].
[[nodiscard]] ElevationRole elevation_role(double elevation, double ground_z, const OccupancyParams& p);

/// The 2D grid of pipeline [9], as occupancy_from_map builds it for the HMAP: a cell whose
/// elevation is ground (elevation_role) is free (clamp_min), any other observed cell occupied
/// (clamp_max); cells never observed, or without a ground patch whose centre is within
/// `max_ground_distance` [m] of the cell centre, stay unknown. The grid's cell is the map's.
[[nodiscard]] OccupancyGrid occupancy_from_elevation(const ElevationMap& map, const GroundModel& ground,
                                                     const Params& params, double max_ground_distance);

}  // namespace hmap
