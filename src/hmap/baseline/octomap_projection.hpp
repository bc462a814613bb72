#pragma once
// OctoMap as the ROS user meets it: the 3D tree read as HVoxels (so the 3D scores treat every map
// alike) and the 2D map octomap_server projects from it (occupied leaves between a minimum and a
// maximum height projected down, free where only free leaves are seen in that band).

#include <octomap/OcTree.h>

#include "hmap/core/params.hpp"
#include "hmap/ground/ground_patches.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap {

/// Occupied OctoMap leaves as HVoxels of `params`' cell size: per column, vertically adjacent
/// leaves unite into one HVoxel.
[[nodiscard]] HMap octomap_as_hmap(const octomap::OcTree& tree, const Params& params);

/// The band of octomap_server's projection, as heights above the local ground [m].
struct OctomapProjectionParams {
  double min_height = 0.2;   ///< occupancy_min_z: leaves whose centre is lower are left out (the ground)
  double max_height = 2.0;   ///< occupancy_max_z: higher leaves pass over the robot
  double ground_reach = 3.0; ///< [m] cells farther than this from the nearest ground patch stay unknown
};

/// octomap_server's 2D map (projectCompleteMap): a cell is occupied when an occupied leaf's centre
/// over it lies in the band, else free when a free leaf's does, else unknown. The band is taken
/// above the local ground of `ground` (octomap_server takes it above z = 0 of its frame, which is
/// the same on flat ground; on a ramp or a second floor the user would need one band per level).
/// Occupied cells get the grid's clamp_max, free ones its clamp_min.
[[nodiscard]] OccupancyGrid project_octomap(const octomap::OcTree& tree, const GroundModel& ground, double cell_size,
                                            const OccupancyParams& occupancy, const OctomapProjectionParams& p);

}  // namespace hmap
