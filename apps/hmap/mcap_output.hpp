#pragma once
// --mcap OUT.mcap of hmap export, map and slam: the map as a recording Foxglove opens as it is
// (hmap/ros/foxglove_scene.hpp).

#include <span>
#include <string>

#include "hmap/core/types.hpp"
#include "hmap/ground/ground_patches.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap::cli {

/// Before any work: the name ends in .mcap and its folder can take it (hmap::Error otherwise).
void check_mcap_output(const std::string& path);

/// Before any work: the stamps [s] from `source` are times an MCAP can carry (hmap::Error otherwise).
void check_mcap_stamps(std::span<const double> stamps_s, const std::string& source);

/// Writes `map`, its 2D `grid` (null: no /map nor /grid) and the poses `trajectory` (may be empty)
/// with their stamps [s] `stamps_s` (one per pose, or empty: no time known, all at 0) to `path`
/// atomically and prints one line: size, time, messages per topic, the time span.
void write_map_mcap(const std::string& path, const HMap& map, const OccupancyGrid* grid, std::span<const Pose> trajectory,
                    std::span<const double> stamps_s);

/// hmap map/slam --mcap: the grid export would write (export_grid's default: the kept grid and
/// the judged columns, or one derived from the columns when `kept` is null), then write_map_mcap.
/// A derived grid that finds no ground leaves /map and /grid out, and says so.
void write_run_mcap(const std::string& path, const HMap& map, std::span<const GroundPatch> ground,
                    const OccupancyGrid* kept, std::span<const Pose> trajectory, std::span<const double> stamps_s);

}  // namespace hmap::cli
